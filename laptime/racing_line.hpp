#pragma once
// A line the car can drive through a layout: the minimum-curvature line between the lanes,
// shrunk by half the car and a cone's radius, as the lap-time bound drives it.

#include <string>
#include <vector>

#include "core/geometry.hpp"
#include "tracks/track.hpp"

namespace conesim::laptime {

using core::Vec2;

/// A polyline with its arc length and signed curvature (left positive) at each point.
struct RacingLine {
  std::vector<Vec2> points;
  /// Arc length at each point from the first one, metres.
  std::vector<double> s_m;
  /// Signed curvature at each point (circle through it and its neighbours), 1/m.
  std::vector<double> curvature;
  /// True when the line is a loop (the last point joins the first; it is not repeated).
  bool closed = false;
  /// Length of the line (closing segment included for a loop), metres.
  double length_m = 0.0;
};

/// Options of the minimum-curvature line.
struct RacingLineParams {
  /// Spacing of the line's points, metres.
  double step_m = 0.5;
  /// Distance the line keeps from the cone centres of either boundary: half the car's width plus
  /// a cone's base radius, metres.
  double clearance_m = 0.8;
  /// Re-linearisations of the problem about the previous solution.
  int passes = 3;
  /// ADMM iterations per pass.
  int iterations = 1000;

  /// True when usable; otherwise false and a reason in `error` (when given).
  bool is_valid(std::string* error = nullptr) const;
};

/// The line through `points` resampled every step_m, with arc length and curvature.
RacingLine make_line(const std::vector<Vec2>& points, bool closed, double step_m);

/// The minimum-curvature line of a closed circuit: points of the centre line moved along its
/// normals, within the lanes less clearance_m, so that the sum of squared curvature is least
/// (a box-constrained quadratic programme on the second differences, solved by ADMM). For an
/// open layout, and where the lanes leave no room, the centre line itself.
RacingLine minimum_curvature_line(const tracks::Track& track, const RacingLineParams& params = {});

}  // namespace conesim::laptime
