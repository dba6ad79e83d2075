#pragma once
// Speed along a path from its curvature: the lateral limit caps the speed at each point, a
// forward pass limits acceleration and a backward pass plans braking before tight turns.

#include <optional>
#include <vector>

#include "control/path.hpp"
#include "vehicle_models/performance.hpp"

namespace conesim::control {

/// Limits the profile plans for.
struct SpeedLimits {
  /// Speed cap, m/s.
  double max_speed_mps = 10.0;
  /// Lateral acceleration allowed in turns, m/s^2.
  double max_lateral_accel_mps2 = 9.0;
  /// Longitudinal acceleration and deceleration allowed on a straight, m/s^2.
  double max_accel_mps2 = 6.0;
  double max_decel_mps2 = 8.0;
  /// The car's limits over speed (at the grip fraction planned for); when given, the lateral,
  /// drive and braking limits at each speed are the envelope's, each capped by the constant
  /// limit above.
  std::optional<vehicle_models::PerformanceEnvelope> envelope;
  /// Share of the envelope's lateral limit the profile turns with (1: all of it); braking and
  /// drive keep the envelope's.
  double lateral_share = 1.0;
  /// Tightest curvature the car's steering gives (full lock, with its yaw loss), 1/m; 0: none.
  /// Near it the car turns at tight_turn_speed_mps at most, where the turn-in into a minimum
  /// hairpin can be timed (measured on 100 generated hard-profile trackdrives: 24 with cones hit
  /// at 4 m/s, 6 at 3 m/s; later 28 at 5 m/s, 5 at 3 m/s). The tyres are not the limit: the car
  /// holds its full-lock radius up to about 5.4 m/s.
  double max_curvature = 0.0;
  double tight_turn_speed_mps = 3.0;
  /// How fast the car can change the curvature it drives, 1/m per second (its steering rate
  /// over the steering its full-lock curvature takes); 0: no limit. Where the path's curvature
  /// changes faster along its length, the speed is capped so that the steering keeps up: a
  /// chicane taken faster than that left the car at full lock the wrong way.
  double max_curvature_rate_per_s = 0.0;

  /// Lateral, forward and braking acceleration allowed at speed v, m/s^2.
  double lateral_mps2(double v) const;
  double accel_mps2(double v) const;
  double decel_mps2(double v) const;
  /// Braking allowed at speed v on a turn of curvature k: decel_mps2 less what the turn takes
  /// of the grip by the friction ellipse, never under a fifth of it, m/s^2.
  double braking_mps2(double v, double k) const;
  /// Highest speed on a turn of curvature k (lateral limit, capped by max_speed_mps), m/s.
  double corner_speed_mps(double k) const;
};

/// The planned speed at each point of a path.
struct SpeedProfile {
  /// Arc length of each point (closed paths: without the lap entry), metres.
  std::vector<double> s_m;
  /// Planned speed at each point, m/s.
  std::vector<double> speed_mps;

  /// The planned speed at arc length s, linear between points (wrapping on a closed path).
  double speed_at(double s, double lap_m = 0.0) const;
};

/// Plans the speed along a path. Open paths start at start_speed_mps (when given, it is only
/// an upper bound for the forward pass) and end at most at end_speed_mps (when given); closed
/// paths are periodic. Longitudinal acceleration shares the tyre with the lateral one (friction
/// ellipse), so the car brakes before a turn rather than in it.
/// `point_cap_mps`, when it has one entry per point, caps the speed at each point as well.
SpeedProfile plan_speed(const Path& path, const SpeedLimits& limits,
                        std::optional<double> start_speed_mps = std::nullopt,
                        std::optional<double> end_speed_mps = std::nullopt,
                        const std::vector<double>& point_cap_mps = {});

}  // namespace conesim::control
