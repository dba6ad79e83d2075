#pragma once
// Pure pursuit steering on the rear axle: aim at the path point one look-ahead distance away
// and steer the single-track angle whose arc passes through it.

#include "control/path.hpp"
#include "core/geometry.hpp"

namespace conesim::control {

/// Pure pursuit settings.
struct PurePursuitParams {
  /// Wheelbase of the single-track model, metres.
  double wheelbase_m = 1.53;
  /// Largest steering angle commanded, radians.
  double max_steer_rad = 0.4712;
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

/// Steers the rear-axle pose towards the look-ahead point of the path.
PurePursuitCommand pure_pursuit(const PurePursuitParams& params, const core::Pose2& pose,
                                double speed_mps, const Path& path, const PathProjection& from);

}  // namespace conesim::control
