#pragma once
// A driving path as a polyline in the map frame, and the geometry the driver needs on it:
// arc length, resampling, smoothing, curvature and projection of the car onto it.

#include <cstddef>
#include <optional>
#include <vector>

#include "core/geometry.hpp"

namespace conesim::control {

using core::Vec2;

/// A polyline to drive along. A closed path joins its last point to its first one and does not
/// repeat the first point at the end.
struct Path {
  std::vector<Vec2> points;
  bool closed = false;

  /// Number of segments: n - 1 for an open path, n for a closed one (0 when n < 2).
  size_t segment_count() const;
  /// The end point of segment i (wraps on a closed path).
  const Vec2& segment_end(size_t i) const { return points[(i + 1) % points.size()]; }
  /// Arc length at each point from the first one; a closed path has one more entry, the lap.
  std::vector<double> arc_lengths() const;
  /// Total length (a closed path includes the closing segment), metres.
  double length() const;
};

/// Where a point projects onto a path.
struct PathProjection {
  /// Segment index and the fraction along it, in [0, 1].
  size_t segment = 0;
  double t = 0.0;
  /// The nearest point of the path and its distance to the query point, metres.
  Vec2 point = Vec2::Zero();
  double distance_m = 0.0;
};

/// Projects p onto the segments first .. first + count - 1 of the path (wrapping on a closed
/// path, clipped at the end of an open one). Pass count = segment_count() for a global search.
PathProjection project_onto(const Path& path, const Vec2& p, size_t first, size_t count);

/// A path that a car at `from` (projecting onto `path` at `at`) joins smoothly: the points within
/// `length_m` ahead of the projection are moved by the car's offset from the path, in full at the
/// projection and fading to none at length_m along a half cosine (no kink at either end); behind
/// the projection the offset fades in the same way over 8 m, so that the car is on the joined
/// path. Its curvature differs from the path's by about offset * (pi / length)^2 / 2.
/// With the car's `heading` the joined path also leaves the car along it (the heading's angle
/// to the path, up to 0.5 rad, as a sideways slope that fades out along the cubic Hermite
/// basis u (1 - u)^2, continued straight behind the car), and meets the path with the path's
/// own heading at length_m.
/// The points keep their indices, so that beyond length_m the two paths are the same and a
/// follower can switch back without a jump.
Path join_from(const Path& path, const Vec2& from, const PathProjection& at, double length_m,
               std::optional<double> heading = std::nullopt);

/// A driven lap's trace as a closed loop: the points at its end that have come back to its first
/// point and run on past it (up to `reach_m` ahead of it along the trace's heading over its first
/// metre, within `lateral_m` to either side) are dropped. A lap is counted as the car crosses the
/// line, so its trace runs on past where it began, and further when the line has moved on to the
/// time-keeping cones since the trace began (6 m on generated tracks); closed as it is, the loop
/// would double back on itself there.
std::vector<Vec2> closed_lap(std::vector<Vec2> trace, double reach_m = 15.0,
                             double lateral_m = 2.0);

/// The polyline resampled every spacing_m (the last step of an open path may be shorter).
std::vector<Vec2> resample(const std::vector<Vec2>& points, double spacing_m, bool closed);

/// Moving average over 2 * half_window + 1 points; an open path keeps its first point and
/// shrinks the window at its ends.
std::vector<Vec2> smooth(const std::vector<Vec2>& points, int half_window, bool closed);

/// Signed curvature (positive left) at each point from the circle through the points `stride`
/// before and after it; an open path copies the nearest computable value to its ends.
std::vector<double> curvatures(const std::vector<Vec2>& points, bool closed, int stride = 2);

/// The curvature `k` (one value per point of `path`, s: its arc lengths) at arc length `at`,
/// averaged over five samples spread over `span_m` (wrapping on a closed path, clamped on an
/// open one): what a tracker feeds forward.
double curvature_near(const Path& path, const std::vector<double>& s, const std::vector<double>& k,
                      double at, double span_m);

/// Signed curvature of the circle through three points (0 when they are collinear).
double three_point_curvature(const Vec2& a, const Vec2& b, const Vec2& c);

}  // namespace conesim::control
