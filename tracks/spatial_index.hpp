#pragma once
// Bounding-box trees over points and polyline segments: the neighbours of a place and the
// nearest point or segment cost what is near the query (O(log n) for a typical query), not the
// whole layout, so that track operations stay O(n log n) in the number of cones (a venue's
// cone map has thousands). Unlike a grid over the layout's box, the tree does not coarsen when
// one cone lies kilometres from the rest.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "core/geometry.hpp"

namespace conesim::tracks {

using core::Vec2;

/// A static tree of axis-aligned boxes, one per item: each node holds the box of its items,
/// split in half at the median centre along the longer side, down to leaves of a few items.
/// Depth is log2(n) whatever the layout's extent or clustering.
class BoxTree {
 public:
  struct Box {
    Vec2 lo = Vec2::Zero();
    Vec2 hi = Vec2::Zero();
  };

  BoxTree() = default;
  /// A tree over items 0..boxes.size()-1.
  explicit BoxTree(const std::vector<Box>& boxes);

  bool empty() const { return nodes_.empty(); }

  /// Calls f(item) for each item whose box overlaps [lo, hi] (touching counts), in no set order.
  template <typename F>
  void for_each_overlapping(const Vec2& lo, const Vec2& hi, F&& f) const {
    any_overlapping(lo, hi, [&f](size_t i) {
      f(i);
      return false;
    });
  }
  /// True as soon as pred(item) holds for an item whose box overlaps [lo, hi].
  template <typename Pred>
  bool any_overlapping(const Vec2& lo, const Vec2& hi, Pred&& pred) const;

  /// The item with the least distance2(item) (ties: the lowest index), visiting nearer boxes
  /// first and skipping those farther than the best so far: distance2(i) must be at least the
  /// squared distance from p to item i's box (+infinity rejects the item). {kNone, inf} when
  /// none is accepted.
  static constexpr size_t kNone = std::numeric_limits<size_t>::max();
  template <typename Distance2>
  std::pair<size_t, double> nearest(const Vec2& p, Distance2&& distance2) const;

 private:
  struct Node {
    Box box;
    uint32_t begin = 0, end = 0;  // items_[begin, end) below this node
    uint32_t first_child = 0;     // 0 for a leaf (the root is never a child)
  };
  static double distance2_to(const Box& b, const Vec2& p) {
    const double dx = std::max({b.lo.x() - p.x(), 0.0, p.x() - b.hi.x()});
    const double dy = std::max({b.lo.y() - p.y(), 0.0, p.y() - b.hi.y()});
    return dx * dx + dy * dy;
  }
  static bool overlaps(const Box& b, const Vec2& lo, const Vec2& hi) {
    return b.lo.x() <= hi.x() && lo.x() <= b.hi.x() && b.lo.y() <= hi.y() && lo.y() <= b.hi.y();
  }

  std::vector<Node> nodes_;
  std::vector<Box> boxes_;       // per item
  std::vector<uint32_t> items_;  // item indices in leaf order
};

/// Points, for radius and nearest queries.
class PointIndex {
 public:
  static constexpr size_t kNone = BoxTree::kNone;

  /// Indexes a copy of `points`.
  explicit PointIndex(const std::vector<Vec2>& points);

  /// Calls f(i) for each point within `radius_m` of p (distance <= radius), in no set order.
  template <typename F>
  void for_each_within(const Vec2& p, double radius_m, F&& f) const;

  /// The indices of the points within `radius_m` of p (distance <= radius), ascending.
  std::vector<size_t> within(const Vec2& p, double radius_m) const;

  /// The nearest point to p that `accept(i)` admits (ties: the lowest index), kNone when none.
  template <typename Accept>
  size_t nearest(const Vec2& p, Accept&& accept) const {
    return tree_
        .nearest(p,
                 [&](size_t i) {
                   return accept(i) ? (points_[i] - p).squaredNorm()
                                    : std::numeric_limits<double>::infinity();
                 })
        .first;
  }

 private:
  std::vector<Vec2> points_;
  BoxTree tree_;
};

/// The segments of a polyline (closed: the last point joins the first).
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

  PolylineIndex() = default;
  /// Indexes the segments of a copy of `points`.
  PolylineIndex(const std::vector<Vec2>& points, bool closed);

  /// The nearest place on the polyline to p (ties: the lowest segment); a single point is its
  /// own polyline; distance2 is infinite for an empty one. The same result as a scan of every
  /// segment.
  Nearest nearest(const Vec2& p) const;

  /// The segments whose bounding boxes overlap the box [lo, hi], ascending (a superset of
  /// those that come into the box).
  std::vector<size_t> segments_near(const Vec2& lo, const Vec2& hi) const;

  /// Number of segments.
  size_t segment_count() const { return segments_; }

 private:
  // the nearest place on segment i to p
  Nearest on_segment(size_t i, const Vec2& p) const;

  std::vector<Vec2> points_;
  size_t segments_ = 0;
  BoxTree tree_;
};

template <typename Pred>
bool BoxTree::any_overlapping(const Vec2& lo, const Vec2& hi, Pred&& pred) const {
  if (nodes_.empty()) return false;
  uint32_t stack[64];  // depth is at most log2 of 2^32 items
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& node = nodes_[stack[--top]];
    if (!overlaps(node.box, lo, hi)) continue;
    if (node.first_child == 0) {
      for (uint32_t k = node.begin; k < node.end; ++k)
        if (overlaps(boxes_[items_[k]], lo, hi) && pred(static_cast<size_t>(items_[k])))
          return true;
    } else {
      stack[top++] = node.first_child;
      stack[top++] = node.first_child + 1;
    }
  }
  return false;
}

template <typename Distance2>
std::pair<size_t, double> BoxTree::nearest(const Vec2& p, Distance2&& distance2) const {
  size_t best = kNone;
  double best_d2 = std::numeric_limits<double>::infinity();
  if (nodes_.empty()) return {best, best_d2};
  // depth first, the nearer child first; a node is skipped when its box is farther than the
  // best so far (equal is kept, for the tie rule)
  std::pair<uint32_t, double> stack[64];
  int top = 0;
  stack[top++] = {0, distance2_to(nodes_[0].box, p)};
  while (top > 0) {
    const auto [index, box_d2] = stack[--top];
    if (box_d2 > best_d2) continue;
    const Node& node = nodes_[index];
    if (node.first_child == 0) {
      for (uint32_t k = node.begin; k < node.end; ++k) {
        const size_t i = items_[k];
        if (distance2_to(boxes_[i], p) > best_d2) continue;
        const double d2 = distance2(i);
        const bool tie = d2 == best_d2 && best != kNone && i < best;
        if (d2 < best_d2 || tie) {
          best_d2 = d2;
          best = i;
        }
      }
      continue;
    }
    const uint32_t a = node.first_child, b = node.first_child + 1;
    const double da = distance2_to(nodes_[a].box, p), db = distance2_to(nodes_[b].box, p);
    // the nearer one on top
    if (da <= db) {
      stack[top++] = {b, db};
      stack[top++] = {a, da};
    } else {
      stack[top++] = {a, da};
      stack[top++] = {b, db};
    }
  }
  return {best, best_d2};
}

template <typename F>
void PointIndex::for_each_within(const Vec2& p, double radius_m, F&& f) const {
  if (!(radius_m >= 0.0)) return;
  const double r2 = radius_m * radius_m;
  const Vec2 reach = Vec2::Constant(radius_m);
  tree_.for_each_overlapping(p - reach, p + reach, [&](size_t i) {
    if ((points_[i] - p).squaredNorm() <= r2) f(i);
  });
}

}  // namespace conesim::tracks
