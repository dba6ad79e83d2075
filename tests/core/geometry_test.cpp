#include "core/geometry.hpp"

#include <gtest/gtest.h>

#include <numbers>

namespace conesim::core {
namespace {

TEST(Geometry, NormalizeAngleWrapsIntoHalfOpenInterval) {
  EXPECT_NEAR(normalize_angle(3.0 * std::numbers::pi), std::numbers::pi, 1e-12);
  EXPECT_NEAR(normalize_angle(-std::numbers::pi), std::numbers::pi, 1e-12);
  EXPECT_NEAR(normalize_angle(0.5 - 4.0 * std::numbers::pi), 0.5, 1e-12);
}

TEST(Geometry, PoseComposeThenInverseIsIdentity) {
  const Pose2 a{1.0, -2.0, 0.7};
  const Pose2 b{-0.3, 4.0, -2.9};
  const Pose2 ab = a.compose(b);
  const Pose2 back = a.inverse().compose(ab);
  EXPECT_NEAR(back.x, b.x, 1e-12);
  EXPECT_NEAR(back.y, b.y, 1e-12);
  EXPECT_NEAR(back.yaw, b.yaw, 1e-12);
  const Vec2 p{3.0, 1.0};
  EXPECT_TRUE(a.inverse_transform(a.transform(p)).isApprox(p, 1e-12));
}

TEST(Geometry, SegmentsIntersectOnlyWhenTheyCross) {
  EXPECT_TRUE(segments_intersect({0, 0}, {2, 2}, {0, 2}, {2, 0}));
  EXPECT_FALSE(segments_intersect({0, 0}, {1, 1}, {2, 0}, {3, 1}));
  EXPECT_NEAR(distance_to_segment({1, 1}, {0, 0}, {2, 0}), 1.0, 1e-12);
  EXPECT_NEAR(distance_to_segment({3, 0}, {0, 0}, {2, 0}), 1.0, 1e-12);
}

}  // namespace
}  // namespace conesim::core
