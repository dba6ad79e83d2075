#pragma once
// The quasi-steady-state speed profile: at every point of a line the car goes as fast as its
// lateral limit allows at that curvature, accelerates out of turns and brakes into them within
// the friction ellipse, with the envelope's speed-dependent grip, drive and braking limits.

#include <vector>

#include "vehicle_models/performance.hpp"

namespace conesim::laptime {

using vehicle_models::PerformanceEnvelope;

/// Speed over distance along a line, and the time it takes.
struct SpeedTrace {
  /// Arc length of each point, metres (closed lines: the lap's end is not repeated).
  std::vector<double> s_m;
  /// Speed at each point, m/s.
  std::vector<double> speed_mps;
  /// Time at each point from the first one, seconds.
  std::vector<double> time_s;
  /// Time over the whole line (closed: the lap, closing segment included), seconds.
  double total_time_s = 0.0;

  /// The time at arc length s (linear between points; clamped to the line).
  double time_at(double s) const;
};

/// Fastest steady speed on a circle of this curvature: v^2 |curvature| = lateral limit at v,
/// capped at the top speed, m/s.
double cornering_speed_mps(const PerformanceEnvelope& envelope, double curvature);

/// Largest forward acceleration at speed v while the tyres also give v^2 |curvature| sideways
/// (friction ellipse on the tyre force; motor and power caps; drag and rolling), m/s^2.
double drive_accel_mps2(const PerformanceEnvelope& envelope, double v_mps, double curvature);

/// Largest deceleration at speed v while cornering at that curvature (brakes or the ellipse's
/// share of grip, plus drag and rolling), m/s^2 (> 0).
double brake_decel_mps2(const PerformanceEnvelope& envelope, double v_mps, double curvature);

/// The flying lap of a closed line: points every ds (s_m, curvature of equal size, the lap
/// length closing it); the profile is periodic (forward and backward passes run twice round
/// from the slowest corner).
SpeedTrace flying_lap(const std::vector<double>& s_m, const std::vector<double>& curvature,
                      double lap_m, const PerformanceEnvelope& envelope);

/// An open line from standstill at its first point; the last point has no speed limit beyond
/// the corner ahead of it.
SpeedTrace standing_start(const std::vector<double>& s_m, const std::vector<double>& curvature,
                          const PerformanceEnvelope& envelope);

}  // namespace conesim::laptime
