#include "tracks/track_area.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace conesim::tracks {

namespace {

/// A diagonal is checked against the lane segments this many indices either side of its ends.
constexpr int kCrossingWindow = 12;
/// Points this close outside a triangle's edge count as inside (rounding), metres.
constexpr double kEdgeToleranceM = 1e-9;

// true when segments ab and cd cross at a point inside both (touching ends do not count)
bool crosses(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d) {
  const double d1 = core::cross(b - a, c - a), d2 = core::cross(b - a, d - a);
  const double d3 = core::cross(d - c, a - c), d4 = core::cross(d - c, b - c);
  return ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0)) &&
         ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0));
}

// true when the diagonal a-b crosses a segment of the lane near index k
bool crosses_lane(const Vec2& a, const Vec2& b, const std::vector<Vec2>& lane, size_t k) {
  const int n = static_cast<int>(lane.size());
  const int lo = std::max(0, static_cast<int>(k) - kCrossingWindow);
  const int hi = std::min(n - 1, static_cast<int>(k) + kCrossingWindow);
  for (int s = lo; s < hi; ++s)
    if (crosses(a, b, lane[static_cast<size_t>(s)], lane[static_cast<size_t>(s) + 1])) return true;
  return false;
}

// the lane with both ends pushed out along their end segments
std::vector<Vec2> extended(const std::vector<Vec2>& lane, double by_m) {
  std::vector<Vec2> out;
  auto beyond = [by_m](const Vec2& end, const Vec2& inner) {
    const Vec2 d = end - inner;
    return d.norm() > 0.0 ? Vec2(end + by_m * d.normalized()) : end;
  };
  out.push_back(beyond(lane.front(), lane[1]));
  out.insert(out.end(), lane.begin(), lane.end());
  out.push_back(beyond(lane.back(), lane[lane.size() - 2]));
  return out;
}

// true when p lies in the triangle (either orientation), edges included
bool in_triangle(const std::array<Vec2, 3>& t, const Vec2& p) {
  const double d1 = core::cross(t[1] - t[0], p - t[0]);
  const double d2 = core::cross(t[2] - t[1], p - t[1]);
  const double d3 = core::cross(t[0] - t[2], p - t[2]);
  // edge tolerance scaled to the edge lengths, so that shared edges leave no crack
  const double e1 = kEdgeToleranceM * (t[1] - t[0]).norm();
  const double e2 = kEdgeToleranceM * (t[2] - t[1]).norm();
  const double e3 = kEdgeToleranceM * (t[0] - t[2]).norm();
  const bool has_neg = d1 < -e1 || d2 < -e2 || d3 < -e3;
  const bool has_pos = d1 > e1 || d2 > e2 || d3 > e3;
  return !(has_neg && has_pos);
}

}  // namespace

TrackArea TrackArea::of(const Track& track, double open_extension_m) {
  TrackArea area;
  std::vector<Vec2> left = track.lane_points(track.left_lane);
  std::vector<Vec2> right = track.lane_points(track.right_lane);
  if (left.size() < 2 || right.size() < 2) return area;

  // closed lanes end where they began; open ones run on past their ends
  if (track.closed) {
    left.push_back(left.front());
    right.push_back(right.front());
  } else {
    left = extended(left, open_extension_m);
    right = extended(right, open_extension_m);
  }

  // ladder: step along whichever lane gives the shorter diagonal across the track, unless that
  // diagonal would cut through a boundary (the inside of a hairpin) and the other would not
  size_t i = 0, j = 0;
  const size_t nl = left.size(), nr = right.size();
  while (i + 1 < nl || j + 1 < nr) {
    bool step_left;
    if (i + 1 >= nl) {
      step_left = false;
    } else if (j + 1 >= nr) {
      step_left = true;
    } else {
      const Vec2 &l1 = left[i + 1], &r1 = right[j + 1];
      const bool left_cuts =
          crosses_lane(l1, right[j], left, i + 1) || crosses_lane(l1, right[j], right, j);
      const bool right_cuts =
          crosses_lane(left[i], r1, left, i) || crosses_lane(left[i], r1, right, j + 1);
      if (left_cuts != right_cuts) {
        step_left = right_cuts;
      } else {
        step_left = (l1 - right[j]).squaredNorm() <= (left[i] - r1).squaredNorm();
      }
    }
    if (step_left) {
      area.triangles_.push_back({left[i], left[i + 1], right[j]});
      ++i;
    } else {
      area.triangles_.push_back({right[j], right[j + 1], left[i]});
      ++j;
    }
  }
  area.left_ = PolylineIndex(left, false);
  area.right_ = PolylineIndex(right, false);
  // the triangles' boxes, grown by what in_triangle lets pass outside an edge
  std::vector<BoxTree::Box> boxes;
  boxes.reserve(area.triangles_.size());
  for (const auto& t : area.triangles_) {
    const Vec2 lo = t[0].cwiseMin(t[1]).cwiseMin(t[2]), hi = t[0].cwiseMax(t[1]).cwiseMax(t[2]);
    boxes.push_back({lo - Vec2::Constant(kEdgeToleranceM), hi + Vec2::Constant(kEdgeToleranceM)});
  }
  area.triangle_tree_ = BoxTree(boxes);
  return area;
}

bool TrackArea::contains(const Vec2& p) const {
  return triangle_tree_.any_overlapping(p, p,
                                        [&](size_t k) { return in_triangle(triangles_[k], p); });
}

std::optional<BoundaryPoint> TrackArea::nearest_boundary(const Vec2& p) const {
  if (triangles_.empty()) return std::nullopt;
  const PolylineIndex::Nearest l = left_.nearest(p), r = right_.nearest(p);
  // the left lane on a tie, as a scan of left then right would give
  const bool left = !(r.distance2 < l.distance2);
  const Vec2 point = left ? l.point : r.point;
  return BoundaryPoint{left, point, (p - point).norm()};
}

}  // namespace conesim::tracks
