#include "tracks/track_area.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace conesim::tracks {

namespace {

/// Cell size of the triangle grid, metres.
constexpr double kCellM = 2.0;
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
  area.left_ = std::move(left);
  area.right_ = std::move(right);

  // the grid: each triangle listed in every cell its bounding box touches
  Vec2 lo = area.triangles_.front()[0], hi = lo;
  for (const auto& t : area.triangles_)
    for (const Vec2& v : t) {
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
    }
  area.cell_m_ = kCellM;
  area.origin_ = lo - Vec2::Constant(kCellM);
  area.nx_ = static_cast<int>(std::ceil((hi.x() - area.origin_.x()) / kCellM)) + 2;
  area.ny_ = static_cast<int>(std::ceil((hi.y() - area.origin_.y()) / kCellM)) + 2;
  const size_t cells = static_cast<size_t>(area.nx_) * static_cast<size_t>(area.ny_);
  std::vector<int> counts(cells + 1, 0);
  auto for_cells = [&](const std::array<Vec2, 3>& t, auto&& visit) {
    Vec2 a = t[0], b = t[0];
    for (const Vec2& v : t) {
      a = a.cwiseMin(v);
      b = b.cwiseMax(v);
    }
    const int x0 = static_cast<int>((a.x() - area.origin_.x()) / kCellM);
    const int y0 = static_cast<int>((a.y() - area.origin_.y()) / kCellM);
    const int x1 = static_cast<int>((b.x() - area.origin_.x()) / kCellM);
    const int y1 = static_cast<int>((b.y() - area.origin_.y()) / kCellM);
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) visit(static_cast<size_t>(y) * area.nx_ + x);
  };
  for (const auto& t : area.triangles_) for_cells(t, [&](size_t c) { ++counts[c + 1]; });
  for (size_t c = 1; c < counts.size(); ++c) counts[c] += counts[c - 1];
  area.cell_starts_ = counts;
  area.cell_items_.resize(static_cast<size_t>(counts.back()));
  for (size_t k = 0; k < area.triangles_.size(); ++k)
    for_cells(area.triangles_[k],
              [&](size_t c) { area.cell_items_[static_cast<size_t>(counts[c]++)] = int(k); });
  return area;
}

bool TrackArea::contains(const Vec2& p) const {
  if (triangles_.empty()) return false;
  const Vec2 q = (p - origin_) / cell_m_;
  if (!(q.x() >= 0.0 && q.y() >= 0.0 && q.x() < nx_ && q.y() < ny_)) return false;
  const size_t c = static_cast<size_t>(static_cast<int>(q.y())) * nx_ + static_cast<int>(q.x());
  for (int k = cell_starts_[c]; k < cell_starts_[c + 1]; ++k)
    if (in_triangle(triangles_[static_cast<size_t>(cell_items_[static_cast<size_t>(k)])], p))
      return true;
  return false;
}

std::optional<BoundaryPoint> TrackArea::nearest_boundary(const Vec2& p) const {
  if (triangles_.empty()) return std::nullopt;
  BoundaryPoint best;
  best.distance_m = std::numeric_limits<double>::infinity();
  auto scan = [&](const std::vector<Vec2>& lane, bool is_left) {
    for (size_t s = 0; s + 1 < lane.size(); ++s) {
      const Vec2 &a = lane[s], &b = lane[s + 1];
      const Vec2 ab = b - a;
      const double len2 = ab.squaredNorm();
      const double u = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
      const Vec2 q = a + u * ab;
      const double d = (p - q).norm();
      if (d < best.distance_m) best = {is_left, q, d};
    }
  };
  scan(left_, true);
  scan(right_, false);
  return best;
}

}  // namespace conesim::tracks
