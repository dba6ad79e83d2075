#pragma once
// Pure pursuit steering on the rear axle: aim at the path point one look-ahead distance away
// and steer the single-track angle whose arc passes through it.

#include <utility>
#include <vector>

#include "control/path.hpp"
#include "core/geometry.hpp"

namespace conesim::control {

/// Pure pursuit settings.
struct PurePursuitParams {
  /// Wheelbase of the single-track model, metres.
  double wheelbase_m = 1.53;
  /// Largest steering angle commanded, radians.
  double max_steer_rad = 0.6283;
  /// Look-ahead distance = max(lookahead_min_m, lookahead_gain_s * speed).
  double lookahead_min_m = 3.0;
  double lookahead_gain_s = 0.35;
};

/// The steering command and what it aimed at.
struct PurePursuitCommand {
  /// Single-track steering angle, radians, positive left.
  double steer_rad = 0.0;
  /// Curvature of the arc to the target, 1/m.
  double curvature = 0.0;
  /// The target point on the path (map frame) and the look-ahead used.
  Vec2 target = Vec2::Zero();
  double lookahead_m = 0.0;
};

/// The point of the path ahead of `from` (a projection of the car onto the path) at distance
/// `lookahead_m` from `position`: the first crossing of the look-ahead circle further along the
/// path. An open path too short for it is extended along its last segment.
Vec2 lookahead_point(const Path& path, const PathProjection& from, const Vec2& position,
                     double lookahead_m);

/// Path tracking with feed-forward curvature: the steering that holds the path's curvature
/// (read a little ahead for the steering lag) plus feedback on the rear axle's lateral and
/// heading error, with the error dynamics of a damped second-order system over distance.
struct TrackerParams {
  double wheelbase_m = 1.53;
  double max_steer_rad = 0.6283;
  /// Natural frequency of the error dynamics per metre driven, capped in time, rad/m and rad/s.
  double frequency_per_m = 0.5;
  double max_frequency_rps = 3.0;
  double damping = 0.8;
  /// The yaw rate the car gets at steering angle d is v tan(d) / L times this gain, linear
  /// between the angles (radians, rising) given; empty: the kinematic yaw rate.
  std::vector<std::pair<double, double>> yaw_gain;
};

/// The steering angle that tracks the path: `curvature_ahead` is the path's curvature a
/// steering lag ahead of the projection `from`, 1/m.
double track_path(const TrackerParams& params, const core::Pose2& pose, double speed_mps,
                  const Path& path, const PathProjection& from, double curvature_ahead);

/// The steering angle whose yaw rate (with the anti-Ackermann loss) gives curvature k.
double steer_for_curvature(const TrackerParams& params, double k);

/// The curvature the car turns on at steering angle d (with the anti-Ackermann loss), 1/m:
/// steer_for_curvature's inverse within the steering's range.
double curvature_for_steer(const TrackerParams& params, double d);

/// The gain of the yaw rate over the kinematic one at steering angle d (1 without a table).
double yaw_gain_at(const std::vector<std::pair<double, double>>& table, double d);

/// Steers the rear-axle pose towards the look-ahead point of the path.
PurePursuitCommand pure_pursuit(const PurePursuitParams& params, const core::Pose2& pose,
                                double speed_mps, const Path& path, const PathProjection& from);

}  // namespace conesim::control
