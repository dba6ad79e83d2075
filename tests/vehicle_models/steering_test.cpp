#include "vehicle_models/steering.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "vehicle_models/kinematics.hpp"
#include "vehicle_models/vehicle_params.hpp"

namespace conesim::vehicle_models {
namespace {

constexpr double kL = 1.53;
constexpr double kT = 1.2;

TEST(Steering, FullAckermannMeetsTheCotangentRelation) {
  // ideal Ackermann: cot(outer) - cot(inner) = track / wheelbase
  const WheelAngles w = split_steering(0.3, kL, kT, 1.0);
  EXPECT_GT(w.left_rad, w.right_rad);  // left turn: the left wheel is inside
  EXPECT_NEAR(1.0 / std::tan(w.right_rad) - 1.0 / std::tan(w.left_rad), kT / kL, 1e-12);
}

TEST(Steering, ParallelSteerGivesEqualAngles) {
  const WheelAngles w = split_steering(-0.2, kL, kT, 0.0);
  EXPECT_DOUBLE_EQ(w.left_rad, -0.2);
  EXPECT_DOUBLE_EQ(w.right_rad, -0.2);
}

TEST(Steering, AntiAckermannSteersTheOuterWheelMore) {
  const WheelAngles left_turn = split_steering(0.3, kL, kT, -1.0);
  EXPECT_GT(left_turn.right_rad, left_turn.left_rad);
  // the mean stays near the single-track angle, and a right turn mirrors a left one
  EXPECT_NEAR(0.5 * (left_turn.left_rad + left_turn.right_rad), 0.3, 0.01);
  const WheelAngles right_turn = split_steering(-0.3, kL, kT, -1.0);
  EXPECT_DOUBLE_EQ(right_turn.left_rad, -left_turn.right_rad);
  EXPECT_DOUBLE_EQ(right_turn.right_rad, -left_turn.left_rad);
}

TEST(Steering, DefaultCarIsAntiAckermannAndValid) {
  const VehicleParams p;
  EXPECT_LT(p.ackermann_factor, 0.0);
  EXPECT_EQ(p.validate(), "");
  VehicleParams bad = p;
  bad.wheelbase_m = std::nan("");
  EXPECT_NE(bad.validate().find("wheelbase_m"), std::string::npos);
}

TEST(Steering, TurnRadiusOfTheBicycle) {
  EXPECT_NEAR(turn_radius_m(std::atan(kL / 10.0), kL), 10.0, 1e-9);
  EXPECT_TRUE(std::isinf(turn_radius_m(0.0, kL)));
}

TEST(Kinematics, BicycleDrivesAFullCircleBackToItsStart) {
  const double steer = std::atan(kL / 8.0);  // 8 m radius
  const double v = 5.0;
  const double period_s = 2.0 * std::numbers::pi * 8.0 / v;
  core::Pose2 pose;
  const int steps = 10000;
  for (int i = 0; i < steps; ++i) pose = bicycle_step(pose, v, steer, kL, period_s / steps);
  EXPECT_NEAR(pose.x, 0.0, 1e-6);
  EXPECT_NEAR(pose.y, 0.0, 1e-6);
  // the half-way point is the far side of the circle, 16 m to the left
  core::Pose2 half;
  half = bicycle_step(half, v, steer, kL, period_s / 2);
  EXPECT_NEAR(half.y, 16.0, 1e-9);
  EXPECT_NEAR(unicycle_step({}, 1.0, 0.0, 2.0).x, 2.0, 1e-12);
}

}  // namespace
}  // namespace conesim::vehicle_models
