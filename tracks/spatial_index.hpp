#pragma once
// Uniform grids over points and polyline segments: the neighbours of a place and the nearest
// point or segment cost what is near the query, not the whole layout, so that track
// operations stay O(n log n) in the number of cones (a venue's cone map has thousands).

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "core/geometry.hpp"

namespace conesim::tracks {

using core::Vec2;

/// A dense grid of cells over a box, each listing item indices (compressed rows). The cells
/// grow beyond the asked size when the box would need more than a few per item, so that the
/// memory stays linear in the items whatever the layout's extent.
class CellGrid {
 public:
  /// Cells of about `cell_m` over [lo, hi], at most max(4 * items, 4096) of them.
  void shape(const Vec2& lo, const Vec2& hi, double cell_m, size_t items);
  /// Fills the cells: `cells_of(i, visit)` calls visit(cx, cy) for each cell item i is in.
  template <typename CellsOf>
  void fill(size_t items, CellsOf&& cells_of);
  /// The cell coordinate of a value along x or y (not clamped).
  int64_t cx(double x) const {
    return static_cast<int64_t>(std::floor((x - origin_.x()) / cell_m_));
  }
  int64_t cy(double y) const {
    return static_cast<int64_t>(std::floor((y - origin_.y()) / cell_m_));
  }
  /// Calls f(item) for each item listed in cell (x, y) (nothing outside the grid).
  template <typename F>
  void for_each_in(int64_t x, int64_t y, F&& f) const {
    if (x < 0 || y < 0 || x >= nx_ || y >= ny_) return;
    const size_t c = static_cast<size_t>(y) * static_cast<size_t>(nx_) + static_cast<size_t>(x);
    for (uint32_t k = starts_[c]; k < starts_[c + 1]; ++k) f(static_cast<size_t>(items_[k]));
  }
  double cell_m() const { return cell_m_; }
  int64_t nx() const { return nx_; }
  int64_t ny() const { return ny_; }
  bool empty() const { return nx_ == 0; }

 private:
  Vec2 origin_ = Vec2::Zero();
  double cell_m_ = 1.0;
  int64_t nx_ = 0, ny_ = 0;
  std::vector<uint32_t> starts_;
  std::vector<uint32_t> items_;
};

/// Points in a grid of square cells.
class PointIndex {
 public:
  static constexpr size_t kNone = std::numeric_limits<size_t>::max();

  /// Indexes a copy of `points` in cells about `cell_m` wide.
  PointIndex(const std::vector<Vec2>& points, double cell_m);

  /// Calls f(i) for each point within `radius_m` of p (distance <= radius), in no set order.
  template <typename F>
  void for_each_within(const Vec2& p, double radius_m, F&& f) const;

  /// The indices of the points within `radius_m` of p (distance <= radius), ascending.
  std::vector<size_t> within(const Vec2& p, double radius_m) const;

  /// The nearest point to p that `accept(i)` admits (ties: the lowest index), kNone when none.
  template <typename Accept>
  size_t nearest(const Vec2& p, Accept&& accept) const;

 private:
  std::vector<Vec2> points_;
  CellGrid grid_;
};

/// The segments of a polyline (closed: the last point joins the first) in a grid.
class PolylineIndex {
 public:
  /// The nearest place on the polyline: the point, its squared distance, the segment (from
  /// point `segment` to the next) and the position along it, 0..1.
  struct Nearest {
    Vec2 point = Vec2::Zero();
    double distance2 = std::numeric_limits<double>::infinity();
    size_t segment = 0;
    double t = 0.0;
  };

  /// Indexes the segments of a copy of `points`. cell_m <= 0: a cell about as wide as the
  /// median segment is long.
  PolylineIndex(const std::vector<Vec2>& points, bool closed, double cell_m = 0.0);

  /// The nearest place on the polyline to p (ties: the lowest segment); a single point is its
  /// own polyline; distance2 is infinite for an empty one. The same result as a scan of every
  /// segment.
  Nearest nearest(const Vec2& p) const;

  /// The segments whose cells overlap the box [lo, hi], ascending (a superset of those that
  /// come into the box).
  std::vector<size_t> segments_near(const Vec2& lo, const Vec2& hi) const;

  /// Number of segments.
  size_t segment_count() const { return segments_; }

 private:
  void consider(size_t i, const Vec2& p, Nearest& best) const;

  std::vector<Vec2> points_;
  size_t segments_ = 0;
  CellGrid grid_;
  // segments spanning too many cells to list in each: always considered
  std::vector<size_t> long_segments_;
};

/// Calls f(x, y) for each cell of the Chebyshev ring k around (cx, cy) within [0, nx) x [0, ny).
template <typename F>
void for_each_ring_cell(int64_t cx, int64_t cy, int64_t k, int64_t nx, int64_t ny, F&& f) {
  const int64_t x0 = std::max<int64_t>(cx - k, 0), x1 = std::min(cx + k, nx - 1);
  const int64_t y0 = std::max<int64_t>(cy - k, 0), y1 = std::min(cy + k, ny - 1);
  if (x0 > x1 || y0 > y1) return;
  // the top and bottom rows, then the columns between them
  for (int64_t y : {cy - k, cy + k}) {
    if (y >= 0 && y < ny)
      for (int64_t x = x0; x <= x1; ++x) f(x, y);
    if (k == 0) return;
  }
  for (int64_t x : {cx - k, cx + k})
    if (x >= 0 && x < nx)
      for (int64_t y = std::max<int64_t>(cy - k + 1, 0); y <= std::min(cy + k - 1, ny - 1); ++y)
        f(x, y);
}

/// The first and last ring around (cx, cy) that can hold a cell of the grid.
inline std::pair<int64_t, int64_t> ring_range(int64_t cx, int64_t cy, int64_t nx, int64_t ny) {
  const int64_t first = std::max({int64_t{0}, -cx, cx - (nx - 1), -cy, cy - (ny - 1)});
  const int64_t last = std::max({cx, nx - 1 - cx, cy, ny - 1 - cy});
  return {first, last};
}

template <typename CellsOf>
void CellGrid::fill(size_t items, CellsOf&& cells_of) {
  // two passes over the cells each item is in: count, then fill
  std::vector<uint32_t> counts(static_cast<size_t>(nx_ * ny_) + 1, 0);
  for (size_t i = 0; i < items; ++i)
    cells_of(i, [&](int64_t x, int64_t y) { ++counts[static_cast<size_t>(y * nx_ + x) + 1]; });
  for (size_t c = 1; c < counts.size(); ++c) counts[c] += counts[c - 1];
  starts_ = counts;
  items_.resize(counts.back());
  for (size_t i = 0; i < items; ++i)
    cells_of(i, [&](int64_t x, int64_t y) {
      items_[counts[static_cast<size_t>(y * nx_ + x)]++] = static_cast<uint32_t>(i);
    });
}

template <typename F>
void PointIndex::for_each_within(const Vec2& p, double radius_m, F&& f) const {
  if (grid_.empty() || !(radius_m >= 0.0)) return;
  const double r2 = radius_m * radius_m;
  const int64_t x0 = std::max<int64_t>(grid_.cx(p.x() - radius_m), 0);
  const int64_t x1 = std::min(grid_.cx(p.x() + radius_m), grid_.nx() - 1);
  const int64_t y0 = std::max<int64_t>(grid_.cy(p.y() - radius_m), 0);
  const int64_t y1 = std::min(grid_.cy(p.y() + radius_m), grid_.ny() - 1);
  for (int64_t y = y0; y <= y1; ++y)
    for (int64_t x = x0; x <= x1; ++x)
      grid_.for_each_in(x, y, [&](size_t i) {
        if ((points_[i] - p).squaredNorm() <= r2) f(i);
      });
}

template <typename Accept>
size_t PointIndex::nearest(const Vec2& p, Accept&& accept) const {
  size_t best = kNone;
  double best_d2 = std::numeric_limits<double>::infinity();
  if (grid_.empty()) return best;
  const auto consider = [&](size_t i) {
    if (!accept(i)) return;
    const double d2 = (points_[i] - p).squaredNorm();
    if (d2 < best_d2 || (d2 == best_d2 && i < best)) {
      best_d2 = d2;
      best = i;
    }
  };
  // rings of cells outwards from p's cell until no unvisited cell can hold a nearer point
  const int64_t cx = grid_.cx(p.x()), cy = grid_.cy(p.y());
  const auto [first, last] = ring_range(cx, cy, grid_.nx(), grid_.ny());
  for (int64_t k = first; k <= last; ++k) {
    if (best != kNone && static_cast<double>(k - 1) * grid_.cell_m() > std::sqrt(best_d2)) break;
    for_each_ring_cell(cx, cy, k, grid_.nx(), grid_.ny(),
                       [&](int64_t x, int64_t y) { grid_.for_each_in(x, y, consider); });
  }
  return best;
}

}  // namespace conesim::tracks
