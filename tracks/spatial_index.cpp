#include "tracks/spatial_index.hpp"

#include <algorithm>
#include <stdexcept>

namespace conesim::tracks {

namespace {

// items in a leaf at most: a few distance checks cost less than another level of boxes
constexpr uint32_t kLeafItems = 8;

}  // namespace

// ---------------------------------------------------------------------------------------------
// the tree

BoxTree::BoxTree(const std::vector<Box>& boxes) : boxes_(boxes) {
  if (boxes_.empty()) return;
  if (boxes_.size() >= std::numeric_limits<uint32_t>::max())
    throw std::length_error("BoxTree: too many items");
  const uint32_t n = static_cast<uint32_t>(boxes_.size());
  items_.resize(n);
  for (uint32_t i = 0; i < n; ++i) items_[i] = i;
  nodes_.reserve(2 * (n / kLeafItems + 1));
  nodes_.push_back({{}, 0, n, 0});
  // breadth first: each node's two children are pushed next to each other
  for (size_t k = 0; k < nodes_.size(); ++k) {
    const uint32_t begin = nodes_[k].begin, end = nodes_[k].end;
    Box box = boxes_[items_[begin]];
    Vec2 centre_lo = 0.5 * (box.lo + box.hi), centre_hi = centre_lo;
    for (uint32_t j = begin; j < end; ++j) {
      const Box& b = boxes_[items_[j]];
      box.lo = box.lo.cwiseMin(b.lo);
      box.hi = box.hi.cwiseMax(b.hi);
      const Vec2 c = 0.5 * (b.lo + b.hi);
      centre_lo = centre_lo.cwiseMin(c);
      centre_hi = centre_hi.cwiseMax(c);
    }
    nodes_[k].box = box;
    if (end - begin <= kLeafItems) continue;
    // halve at the median centre along the longer side of the centres' box (ties by index,
    // so that the tree is the same on every platform)
    const int axis = (centre_hi - centre_lo).x() >= (centre_hi - centre_lo).y() ? 0 : 1;
    const uint32_t mid = begin + (end - begin) / 2;
    std::nth_element(items_.begin() + begin, items_.begin() + mid, items_.begin() + end,
                     [&](uint32_t a, uint32_t b) {
                       const double ca = boxes_[a].lo[axis] + boxes_[a].hi[axis];
                       const double cb = boxes_[b].lo[axis] + boxes_[b].hi[axis];
                       return ca < cb || (ca == cb && a < b);
                     });
    nodes_[k].first_child = static_cast<uint32_t>(nodes_.size());
    nodes_.push_back({{}, begin, mid, 0});
    nodes_.push_back({{}, mid, end, 0});
  }
}

// ---------------------------------------------------------------------------------------------
// points

namespace {

std::vector<BoxTree::Box> point_boxes(const std::vector<Vec2>& points) {
  std::vector<BoxTree::Box> boxes;
  boxes.reserve(points.size());
  for (const Vec2& p : points) boxes.push_back({p, p});
  return boxes;
}

}  // namespace

PointIndex::PointIndex(const std::vector<Vec2>& points)
    : points_(points), tree_(point_boxes(points)) {}

std::vector<size_t> PointIndex::within(const Vec2& p, double radius_m) const {
  std::vector<size_t> out;
  for_each_within(p, radius_m, [&out](size_t i) { out.push_back(i); });
  std::sort(out.begin(), out.end());
  return out;
}

// ---------------------------------------------------------------------------------------------
// polyline segments

PolylineIndex::PolylineIndex(const std::vector<Vec2>& points, bool closed) : points_(points) {
  const size_t n = points_.size();
  segments_ = n < 2 ? 0 : (closed ? n : n - 1);
  std::vector<BoxTree::Box> boxes;
  boxes.reserve(segments_);
  for (size_t i = 0; i < segments_; ++i) {
    const Vec2& a = points_[i];
    const Vec2& b = points_[(i + 1) % n];
    boxes.push_back({a.cwiseMin(b), a.cwiseMax(b)});
  }
  tree_ = BoxTree(boxes);
}

PolylineIndex::Nearest PolylineIndex::on_segment(size_t i, const Vec2& p) const {
  const Vec2& a = points_[i];
  const Vec2 ab = points_[(i + 1) % points_.size()] - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  const Vec2 q = a + t * ab;
  return {q, (p - q).squaredNorm(), i, t};
}

PolylineIndex::Nearest PolylineIndex::nearest(const Vec2& p) const {
  if (points_.empty()) return {};
  if (points_.size() == 1) return {points_.front(), (p - points_.front()).squaredNorm(), 0, 0.0};
  const size_t best = tree_.nearest(p, [&](size_t i) { return on_segment(i, p).distance2; }).first;
  return best == BoxTree::kNone ? Nearest{} : on_segment(best, p);  // kNone: p is not a number
}

std::vector<size_t> PolylineIndex::segments_near(const Vec2& lo, const Vec2& hi) const {
  std::vector<size_t> out;
  tree_.for_each_overlapping(lo, hi, [&out](size_t i) { out.push_back(i); });
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace conesim::tracks
