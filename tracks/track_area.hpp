#pragma once
// The area inside a layout's boundaries, for judging off-course: the corridor between the left
// and the right lane, cut into triangles that each have one side on a lane and the other two
// across the track. A point is on the track when it lies in any triangle. A union of cells,
// unlike an even-odd polygon test, stays right where parts of the corridor overlap: the open
// ends of a layout extended past its first and last cones, a start/finish gap, a track that
// crosses itself.

#include <array>
#include <optional>
#include <vector>

#include "tracks/spatial_index.hpp"
#include "tracks/track.hpp"

namespace conesim::tracks {

/// Where the nearest boundary is, for messages.
struct BoundaryPoint {
  /// True for the left (blue) lane, false for the right (yellow) one.
  bool left = true;
  /// The nearest point of that lane's polyline.
  Vec2 point = Vec2::Zero();
  /// Distance from the query point to it, metres.
  double distance_m = 0.0;
};

/// The drivable area of a layout with lanes (circuits and open courses; skidpad is judged from
/// its circles instead).
class TrackArea {
 public:
  /// Open layouts are extended this far past both ends of their lanes, so that a car standing
  /// behind the first cone pair or stopping past the last one is on the track, metres.
  static constexpr double kDefaultOpenExtensionM = 10.0;

  TrackArea() = default;

  /// The area between the track's lanes (empty when a lane has fewer than two cones).
  static TrackArea of(const Track& track, double open_extension_m = kDefaultOpenExtensionM);

  /// True when the track has an area to judge.
  bool empty() const { return triangles_.empty(); }

  /// True when p lies inside the boundaries (on a boundary counts as inside).
  bool contains(const Vec2& p) const;

  /// The nearest point of either lane's polyline (nullopt when the area is empty).
  std::optional<BoundaryPoint> nearest_boundary(const Vec2& p) const;

  /// The triangles that make up the area, each (lane point, lane point, other lane's point).
  const std::vector<std::array<Vec2, 3>>& triangles() const { return triangles_; }

 private:
  std::vector<std::array<Vec2, 3>> triangles_;
  BoxTree triangle_tree_;  // the triangles' bounding boxes
  // the lane polylines as judged (closed ones repeat their first point)
  PolylineIndex left_, right_;
};

}  // namespace conesim::tracks
