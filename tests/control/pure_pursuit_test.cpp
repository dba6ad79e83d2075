#include "control/pure_pursuit.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

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

TEST(TrackPath, OnTheArcThroughCoarsePointsSteersSteadily) {
  // a hairpin's racing line: points 1 m apart on a 4 m circle (0.25 rad between chords). A car
  // driving the circle exactly, at every place along a few chords, is on the path and heading
  // along it: the steering is the circle's own, with no saw-tooth as it passes each point
  // (measured against the chords, the heading error swung by the turn between two points and
  // the steering by about 0.25 rad)
  constexpr double kRadiusM = 4.0;
  const Path path = circle(kRadiusM, 1.0);
  const TrackerParams params;
  const double expected = steer_for_curvature(params, 1.0 / kRadiusM);
  double lowest = 1e9, highest = -1e9;
  for (int i = 0; i <= 60; ++i) {
    const double phi = -0.5 * std::numbers::pi + 0.05 * i;  // about 3 chords
    const Pose2 pose{kRadiusM * std::cos(phi), kRadiusM * std::sin(phi),
                     phi + 0.5 * std::numbers::pi};
    const PathProjection here = project_onto(path, pose.position(), 0, path.segment_count());
    const double steer = track_path(params, pose, 6.6, path, here, 1.0 / kRadiusM);
    lowest = std::min(lowest, steer);
    highest = std::max(highest, steer);
  }
  EXPECT_NEAR(lowest, expected, 0.01);
  EXPECT_NEAR(highest, expected, 0.01);
}

TEST(TrackPath, EndsAndCuspsOfAPathFallBackOnTheChord) {
  // an open path's last chord and a chord that turns back have no smooth tangent at one end:
  // the car beside them is steered by the chord, without NaN
  const Path path{{Vec2(0.0, 0.0), Vec2(5.0, 0.0), Vec2(0.0, 0.1)}, false};
  for (size_t segment : {0u, 1u}) {
    const Pose2 pose{segment == 0 ? 2.0 : 3.0, 0.3, segment == 0 ? 0.0 : std::numbers::pi};
    const PathProjection here = project_onto(path, pose.position(), segment, 1);
    const double steer = track_path({}, pose, 3.0, path, here, 0.0);
    EXPECT_TRUE(std::isfinite(steer));
  }
  // on a straight path beside it to the left: steer right
  const Path straight{{Vec2(0.0, 0.0), Vec2(5.0, 0.0), Vec2(10.0, 0.0)}, false};
  const Pose2 left_of_it{7.0, 0.5, 0.0};
  const PathProjection on = project_onto(straight, left_of_it.position(), 0, 2);
  EXPECT_LT(track_path({}, left_of_it, 3.0, straight, on, 0.0), 0.0);
}

}  // namespace
}  // namespace conesim::control
