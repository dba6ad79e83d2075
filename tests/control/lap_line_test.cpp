#include "control/lap_line.hpp"

#include <gtest/gtest.h>

namespace conesim::control {
namespace {

using core::ConeClass;
using core::MapCone;
using core::Pose2;

TEST(LapLine, ComesFromTheBigOrangeConesEitherSide) {
  const Eigen::Matrix2d cov = Eigen::Matrix2d::Identity();
  const std::vector<MapCone> map{
      {0, ConeClass::kOrangeBig, {7.3, 2.5}, cov},  {1, ConeClass::kOrangeBig, {4.7, 2.5}, cov},
      {2, ConeClass::kOrangeBig, {7.3, -2.5}, cov}, {3, ConeClass::kOrangeBig, {4.7, -2.5}, cov},
      {4, ConeClass::kBlue, {6.0, 1.8}, cov},       {5, ConeClass::kOrangeBig, {60.0, 2.5}, cov}};
  const std::optional<LapLine> line = lap_line_from_cones(map, Pose2{});
  ASSERT_TRUE(line);
  EXPECT_NEAR(line->left.x(), 6.0, 1e-9);
  EXPECT_NEAR(line->right.x(), 6.0, 1e-9);
  EXPECT_GT(line->left.y(), 2.5);
  EXPECT_LT(line->right.y(), -2.5);
  // one side only is no line
  EXPECT_FALSE(lap_line_from_cones({map[0], map[1]}, Pose2{}));
}

TEST(LapLine, CountsOnlyForwardCrossings) {
  const LapLine line = lap_line_at({6.0, 0.0}, Pose2{}, 3.0);
  EXPECT_TRUE(crosses_forward(line, {5.9, 0.5}, {6.1, 0.6}));
  EXPECT_FALSE(crosses_forward(line, {6.1, 0.5}, {5.9, 0.6}));  // backwards
  EXPECT_FALSE(crosses_forward(line, {5.0, 0.0}, {5.9, 0.0}));  // short of it
  EXPECT_FALSE(crosses_forward(line, {5.9, 4.0}, {6.1, 4.0}));  // beside it
}

}  // namespace
}  // namespace conesim::control
