#include "tracks/spatial_index.hpp"

#include <algorithm>
#include <cmath>

namespace conesim::tracks {

namespace {

// a segment listed in more cells than this is kept apart and considered for every query
constexpr int64_t kMaxCellsPerSegment = 64;

// the box of some points
std::pair<Vec2, Vec2> box_of(const std::vector<Vec2>& pts) {
  Vec2 lo = pts.front(), hi = pts.front();
  for (const Vec2& p : pts) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  return {lo, hi};
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// the grid

void CellGrid::shape(const Vec2& lo, const Vec2& hi, double cell_m, size_t items) {
  // at most a few cells per item: larger cells over a large box
  const double max_cells = std::max(4.0 * static_cast<double>(items), 4096.0);
  const Vec2 size = hi - lo;
  cell_m = std::max(cell_m > 0.0 ? cell_m : 1.0, 1e-3);
  while ((std::floor(size.x() / cell_m) + 1.0) * (std::floor(size.y() / cell_m) + 1.0) > max_cells)
    cell_m *= 2.0;
  cell_m_ = cell_m;
  origin_ = lo;
  nx_ = static_cast<int64_t>(std::floor(size.x() / cell_m)) + 1;
  ny_ = static_cast<int64_t>(std::floor(size.y() / cell_m)) + 1;
}

// ---------------------------------------------------------------------------------------------
// points

PointIndex::PointIndex(const std::vector<Vec2>& points, double cell_m) : points_(points) {
  if (points_.empty()) return;
  const auto [lo, hi] = box_of(points_);
  grid_.shape(lo, hi, cell_m, points_.size());
  grid_.fill(points_.size(), [this](size_t i, auto&& visit) {
    visit(std::clamp<int64_t>(grid_.cx(points_[i].x()), 0, grid_.nx() - 1),
          std::clamp<int64_t>(grid_.cy(points_[i].y()), 0, grid_.ny() - 1));
  });
}

std::vector<size_t> PointIndex::within(const Vec2& p, double radius_m) const {
  std::vector<size_t> out;
  for_each_within(p, radius_m, [&out](size_t i) { out.push_back(i); });
  std::sort(out.begin(), out.end());
  return out;
}

// ---------------------------------------------------------------------------------------------
// polyline segments

PolylineIndex::PolylineIndex(const std::vector<Vec2>& points, bool closed, double cell_m)
    : points_(points) {
  const size_t n = points_.size();
  segments_ = n < 2 ? 0 : (closed ? n : n - 1);
  if (segments_ == 0) return;

  // cells about a median segment wide (at least 0.5 m)
  if (cell_m <= 0.0) {
    std::vector<double> lengths;
    lengths.reserve(segments_);
    for (size_t i = 0; i < segments_; ++i)
      lengths.push_back((points_[(i + 1) % n] - points_[i]).norm());
    std::nth_element(lengths.begin(), lengths.begin() + lengths.size() / 2, lengths.end());
    cell_m = std::max(0.5, lengths[lengths.size() / 2]);
  }
  const auto [lo, hi] = box_of(points_);
  grid_.shape(lo, hi, cell_m, segments_);

  // each segment in every cell its bounding box covers, a long one apart
  std::vector<bool> is_long(segments_, false);
  const auto cells_of = [&](size_t i, auto&& visit) {
    if (is_long[i]) return;
    const Vec2& a = points_[i];
    const Vec2& b = points_[(i + 1) % n];
    const int64_t x0 = grid_.cx(std::min(a.x(), b.x())), x1 = grid_.cx(std::max(a.x(), b.x()));
    const int64_t y0 = grid_.cy(std::min(a.y(), b.y())), y1 = grid_.cy(std::max(a.y(), b.y()));
    for (int64_t x = std::max<int64_t>(x0, 0); x <= std::min(x1, grid_.nx() - 1); ++x)
      for (int64_t y = std::max<int64_t>(y0, 0); y <= std::min(y1, grid_.ny() - 1); ++y)
        visit(x, y);
  };
  for (size_t i = 0; i < segments_; ++i) {
    const Vec2& a = points_[i];
    const Vec2& b = points_[(i + 1) % n];
    const int64_t cells = (std::abs(grid_.cx(a.x()) - grid_.cx(b.x())) + 1) *
                          (std::abs(grid_.cy(a.y()) - grid_.cy(b.y())) + 1);
    if (cells > kMaxCellsPerSegment) {
      is_long[i] = true;
      long_segments_.push_back(i);
    }
  }
  grid_.fill(segments_, cells_of);
}

void PolylineIndex::consider(size_t i, const Vec2& p, Nearest& best) const {
  const Vec2& a = points_[i];
  const Vec2 ab = points_[(i + 1) % points_.size()] - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  const Vec2 q = a + t * ab;
  const double d2 = (p - q).squaredNorm();
  if (d2 < best.distance2 || (d2 == best.distance2 && i < best.segment)) best = {q, d2, i, t};
}

PolylineIndex::Nearest PolylineIndex::nearest(const Vec2& p) const {
  Nearest best;
  if (points_.empty()) return best;
  if (points_.size() == 1) return {points_.front(), (p - points_.front()).squaredNorm(), 0, 0.0};
  best.segment = std::numeric_limits<size_t>::max();
  for (size_t i : long_segments_) consider(i, p, best);

  // rings of cells outwards from p's cell until no unvisited cell can hold a nearer place: a
  // segment is listed in the cell of each of its points
  const int64_t cx = grid_.cx(p.x()), cy = grid_.cy(p.y());
  const auto [first, last] = ring_range(cx, cy, grid_.nx(), grid_.ny());
  for (int64_t k = first; k <= last; ++k) {
    if (std::isfinite(best.distance2) &&
        static_cast<double>(k - 1) * grid_.cell_m() > std::sqrt(best.distance2))
      break;
    for_each_ring_cell(cx, cy, k, grid_.nx(), grid_.ny(), [&](int64_t x, int64_t y) {
      grid_.for_each_in(x, y, [&](size_t i) { consider(i, p, best); });
    });
  }
  return best;
}

std::vector<size_t> PolylineIndex::segments_near(const Vec2& lo, const Vec2& hi) const {
  std::vector<size_t> out(long_segments_);
  if (segments_ > 0) {
    const int64_t x0 = std::max<int64_t>(grid_.cx(lo.x()), 0);
    const int64_t x1 = std::min(grid_.cx(hi.x()), grid_.nx() - 1);
    const int64_t y0 = std::max<int64_t>(grid_.cy(lo.y()), 0);
    const int64_t y1 = std::min(grid_.cy(hi.y()), grid_.ny() - 1);
    for (int64_t x = x0; x <= x1; ++x)
      for (int64_t y = y0; y <= y1; ++y)
        grid_.for_each_in(x, y, [&](size_t i) { out.push_back(i); });
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

}  // namespace conesim::tracks
