#include "control/pure_pursuit.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "test_tracks.hpp"
#include "vehicle_models/kinematics.hpp"

namespace conesim::control {
namespace {

using core::Pose2;

constexpr double kWheelbaseM = 1.53;

Path circle(double radius, double spacing_m) {
  return testing::circle_path(radius, spacing_m);
}

TEST(PurePursuit, OnTheCircleSteersItsCurvature) {
  // on the circle, tangent to it: the arc to a point of the circle is the circle itself
  constexpr double kRadiusM = 12.0;
  const Path path = circle(kRadiusM, 0.5);
  const Pose2 pose{0.0, -kRadiusM, 0.0};
  const PathProjection here = project_onto(path, pose.position(), 0, path.segment_count());
  const PurePursuitCommand cmd = pure_pursuit({}, pose, 8.0, path, here);
  // the polyline's chords put the target a hair inside the circle
  EXPECT_NEAR(cmd.curvature, 1.0 / kRadiusM, 0.01 / kRadiusM);
  EXPECT_NEAR(cmd.steer_rad, std::atan(kWheelbaseM / kRadiusM), 1e-3);
}

TEST(PurePursuit, ClosedLoopConvergesToTheCircle) {
  // start 1 m outside the circle and drive the kinematic bicycle with the command
  constexpr double kRadiusM = 9.0;
  constexpr double kSpeedMps = 6.0, kDtS = 0.01;
  const Path path = circle(kRadiusM, 0.5);
  Pose2 pose{0.0, -kRadiusM - 1.0, 0.0};
  double steer = 0.0;
  size_t segment = 0;
  for (int i = 0; i < 3000; ++i) {
    const PathProjection here = project_onto(path, pose.position(), segment, 20);
    segment = here.segment;
    steer = pure_pursuit({}, pose, kSpeedMps, path, here).steer_rad;
    pose = vehicle_models::bicycle_step(pose, kSpeedMps, steer, kWheelbaseM, kDtS);
  }
  EXPECT_NEAR(pose.position().norm(), kRadiusM, 0.05);
  EXPECT_NEAR(std::tan(steer) / kWheelbaseM, 1.0 / kRadiusM, 0.02 / kRadiusM);
}

TEST(PurePursuit, SteersTowardsAPathBesideTheCar) {
  const Path path{{Vec2(0.0, 1.0), Vec2(50.0, 1.0)}, false};
  const Pose2 pose{0.0, 0.0, 0.0};
  const PathProjection here = project_onto(path, pose.position(), 0, 1);
  EXPECT_GT(pure_pursuit({}, pose, 5.0, path, here).steer_rad, 0.0);
  const Pose2 left_of_it{0.0, 2.0, 0.0};
  const PathProjection there = project_onto(path, left_of_it.position(), 0, 1);
  EXPECT_LT(pure_pursuit({}, left_of_it, 5.0, path, there).steer_rad, 0.0);
}

TEST(PurePursuit, LookaheadGrowsWithSpeedAndExtendsAShortPath) {
  const Path path{{Vec2(0.0, 0.0), Vec2(2.0, 0.0)}, false};
  const PurePursuitParams params;
  const PathProjection here = project_onto(path, Vec2::Zero(), 0, 1);
  const PurePursuitCommand slow = pure_pursuit(params, Pose2{}, 1.0, path, here);
  const PurePursuitCommand fast = pure_pursuit(params, Pose2{}, 20.0, path, here);
  EXPECT_DOUBLE_EQ(slow.lookahead_m, params.lookahead_min_m);
  EXPECT_DOUBLE_EQ(fast.lookahead_m, params.lookahead_gain_s * 20.0);
  // the 2 m path is extended straight on to the look-ahead distance
  EXPECT_TRUE(fast.target.isApprox(Vec2(fast.lookahead_m, 0.0), 1e-9));
  EXPECT_NEAR(fast.steer_rad, 0.0, 1e-12);
}

TEST(PurePursuit, SteeringIsClampedToTheLimit) {
  // a target straight to the left asks for more than the car can steer
  const Path path{{Vec2(0.0, 3.0), Vec2(0.0, 10.0)}, false};
  const PathProjection here = project_onto(path, Vec2::Zero(), 0, 1);
  const PurePursuitParams params;
  EXPECT_DOUBLE_EQ(pure_pursuit(params, Pose2{}, 3.0, path, here).steer_rad, params.max_steer_rad);
}

}  // namespace
}  // namespace conesim::control
