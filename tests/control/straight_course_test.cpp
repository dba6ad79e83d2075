#include "control/straight_course.hpp"

#include <gtest/gtest.h>

#include "tracks/fsg_layouts.hpp"

namespace conesim::control {
namespace {

using core::MapCone;
using core::Pose2;

// the acceleration layout's cones
std::vector<MapCone> acceleration_cones() {
  std::vector<MapCone> map;
  for (const tracks::Cone& c : tracks::make_acceleration().cones)
    map.push_back({c.id, c.cls, c.position, Eigen::Matrix2d::Identity()});
  return map;
}

TEST(StraightCourse, FindsTheMiddleOfTheLaneFromAnOffsetStart) {
  // the car starts 0.4 m left of the middle and 1 degree off: the course is the lane's middle
  const Pose2 start{-2.55, 0.4, 0.0175};
  const StraightCourse course = fit_straight_course(acceleration_cones(), start, 1.6);
  const Path path = straight_course_path(course, start, 0.0, 100.0);
  for (const Vec2& p : path.points) EXPECT_NEAR(p.y(), 0.0, 1e-6);
  EXPECT_GT(course.left_cones, 10);
  EXPECT_GT(course.right_cones, 10);
}

TEST(StraightCourse, OneSideIsOffsetAndAnOutlierIsDropped) {
  // only the left cones, one of them 1.2 m out of line: the middle is 1.6 m right of the row
  std::vector<MapCone> cones;
  for (const MapCone& c : acceleration_cones())
    if (c.position.y() > 0.5) cones.push_back(c);
  cones[5].position.y() += 1.2;
  const StraightCourse course = fit_straight_course(cones, Pose2{}, 1.6);
  EXPECT_NEAR(course.offset_m, tracks::kAccelerationHalfWidthM - 1.6, 1e-6);
  EXPECT_NEAR(course.slope, 0.0, 1e-9);
}

TEST(StraightCourse, NoConesFollowsTheStartHeading) {
  const StraightCourse course = fit_straight_course({}, Pose2{}, 1.6);
  EXPECT_EQ(course.offset_m, 0.0);
  EXPECT_EQ(course.slope, 0.0);
}

}  // namespace
}  // namespace conesim::control
