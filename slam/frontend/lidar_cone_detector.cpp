// The LiDAR cone detector. One pass per sweep:
//   de-skew  -> every point moved to the vehicle frame at the sweep's end,
//   ground   -> a plane fitted to the low points, heights measured from it,
//   clusters -> a grid over the ground-projected points, neighbours linked by distance; a
//               cluster that may be a row of cones whose bases touch is cut into cones,
//   cones    -> size and point-count checks, the centre fitted to the visible surface with the
//               known radius at each point's height, the class from the intensities along the
//               height, and a covariance from the range noise and the number of points.

#include "slam/frontend/lidar_cone_detector.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <numeric>
#include <span>
#include <sstream>
#include <stdexcept>
#include <unordered_map>

#include "core/cone_geometry.hpp"

namespace conesim::slam::frontend {
namespace {

using core::ConeClass;
using Eigen::Vector2d;
using Eigen::Vector3d;

constexpr double kDeg = std::numbers::pi / 180.0;

// a non-ground point, ready for clustering
struct RaisedPoint {
  int index = 0;          // into PointCloud::points
  Vector2d foot;          // foot on the ground plane, vehicle x y
  double height_m = 0.0;  // above the ground plane
  double range_m = 0.0;   // from the sensor
  double intensity = 0.0;
  int ring = 0;
};

// the ground plane z = a x + b y + c in the vehicle frame at the sweep end
struct GroundPlane {
  double a = 0.0, b = 0.0, c = 0.0;
  // unit normal pointing up
  Vector3d normal() const { return Vector3d(-a, -b, 1.0).normalized(); }
  // signed height of a point above the plane, along the normal
  double height(const Vector3d& p) const {
    return (p.z() - (a * p.x() + b * p.y() + c)) / std::sqrt(a * a + b * b + 1.0);
  }
};

// Which of many points lie at heights within [lo, hi] of a plane, and at what height: the same
// heights as GroundPlane::height with its square root taken once, and the points far outside
// turned away by a multiplication (the exact quotient decides near the limits).
class HeightBand {
 public:
  HeightBand(const GroundPlane& plane, double lo, double hi)
      : plane_(plane),
        length_(std::sqrt(plane.a * plane.a + plane.b * plane.b + 1.0)),
        inverse_(1.0 / length_),
        lo_(lo),
        hi_(hi) {}

  // true when the point's height is within the band; its height in h then
  bool contains(const Vector3d& p, double& h) const {
    // the product is within 1e-15 relative of the quotient: a margin of 1e-9 m is safe
    constexpr double kMarginM = 1e-9;
    const double rise = p.z() - (plane_.a * p.x() + plane_.b * p.y() + plane_.c);
    const double approx = rise * inverse_;
    if (approx < lo_ - kMarginM || approx > hi_ + kMarginM) return false;
    h = rise / length_;
    return h >= lo_ && h <= hi_;
  }

 private:
  GroundPlane plane_;
  double length_, inverse_, lo_, hi_;
};

// the pose of the vehicle at the sweep end seen from the vehicle at dt earlier, for constant
// speed and yaw rate (a circular arc; a straight line for a negligible yaw rate)
core::Pose2 arc_motion(const SweepMotion& motion, double dt_s) {
  const double dyaw = motion.yaw_rate_rps * dt_s;
  const double distance = motion.speed_mps * dt_s;
  if (std::abs(dyaw) < 1e-9) return {distance, 0.0, 0.0};
  const double radius = distance / dyaw;
  return {radius * std::sin(dyaw), radius * (1.0 - std::cos(dyaw)), dyaw};
}

// a point's horizontal range from the sensor, as std::hypot of its two floats gives it (glibc
// computes it in double and rounds it to float), inline
double horizontal_range(const core::LidarPoint& p) {
  return static_cast<float>(
      std::sqrt(static_cast<double>(p.x) * p.x + static_cast<double>(p.y) * p.y));
}

// Which points lie within [lo, hi] of horizontal range, as horizontal_range gives it: the
// squared range decides away from the limits (the float rounding is within 1e-7 relative, the
// margin 1e-6), the square root only near them.
class RangeWindow {
 public:
  RangeWindow(double lo, double hi)
      : lo_(lo),
        hi_(hi),
        inner_lo_squared_(lo * (1.0 + kMargin) * lo * (1.0 + kMargin)),
        inner_hi_squared_(hi * (1.0 - kMargin) * hi * (1.0 - kMargin)) {}

  bool contains(const core::LidarPoint& p) const {
    const double squared = static_cast<double>(p.x) * p.x + static_cast<double>(p.y) * p.y;
    if (squared > inner_lo_squared_ && squared < inner_hi_squared_) return true;
    const double horizontal = horizontal_range(p);
    return !(horizontal < lo_ || horizontal > hi_);
  }

 private:
  static constexpr double kMargin = 1e-6;
  double lo_, hi_, inner_lo_squared_, inner_hi_squared_;
};

// The de-skew of the points fired at one time (a column): the vehicle at the sweep end seen from
// the vehicle at the firing, and the cosine and sine of its yaw.
struct ColumnMotion {
  int first_index = 0;  // the column's first point within the range window
  core::Pose2 back;
  double cos_yaw = 1.0, sin_yaw = 0.0;
};

// The columns of a sweep in firing order: the caller adds one at each change of the firing time
// among the points within the range window, as it meets them in firing order.
class SweepColumns {
 public:
  // room for a 0.2-degree sweep (1800 columns; more grow the buffer), under malloc's 128 KiB
  // threshold for handing memory back to the kernel
  static constexpr int kTypicalColumns = 2048;

  // frame_s: the frame's time after the sweep's start, to which the points are moved
  SweepColumns(const SweepMotion& motion, double frame_s, int points)
      : motion_(motion), frame_s_(frame_s) {
    columns_.reserve(static_cast<size_t>(std::min(points, kTypicalColumns)));
  }

  // a column starting at point i (within the range window), fired at tau_s
  void add(int i, float tau_s) {
    ColumnMotion m;
    m.first_index = i;
    m.back = arc_motion(motion_, frame_s_ - tau_s);
    m.cos_yaw = std::cos(m.back.yaw);
    m.sin_yaw = std::sin(m.back.yaw);
    columns_.push_back(m);
  }
  // the column of point i (within the range window) given that of an earlier point, from 0 on
  int column_of(int i, int earlier) const {
    while (earlier + 1 < size() && columns_[earlier + 1].first_index <= i) ++earlier;
    return earlier;
  }
  // the points of a column: indices from its first to the next column's first (or `points`)
  int end_of(int column, int points) const {
    return column + 1 < size() ? columns_[column + 1].first_index : points;
  }
  const ColumnMotion& operator[](int column) const { return columns_[column]; }
  int size() const { return static_cast<int>(columns_.size()); }

 private:
  SweepMotion motion_;
  double frame_s_;
  std::vector<ColumnMotion> columns_;
};

// A point in the vehicle frame at the sweep end: the mount's transform, then (with de-skew) the
// column's motion undone, back.inverse_transform(v.head<2>()) with the column's cosine and sine.
Vector3d to_vehicle(const core::Pose3& mount, const core::LidarPoint& p,
                    const ColumnMotion* column) {
  const Vector3d v = mount.transform(Vector3d(p.x, p.y, p.z));
  if (column == nullptr) return v;
  const double dx = v.x() - column->back.x, dy = v.y() - column->back.y;
  return Vector3d(column->cos_yaw * dx + column->sin_yaw * dy,
                  -column->sin_yaw * dx + column->cos_yaw * dy, v.z());
}

// Sorting of the points in the sensor frame, without moving them: a linear function of a
// point's sensor coordinates, n . p + d, equal up to rounding (relative 1e-15 of the terms,
// for |x|, |y| within the range window and |z| up to kMaxZM) to a value that to_vehicle() and
// the plane give more slowly. Values farther than a margin (1e6 times the rounding) from the
// limits decide; the others are left to the exact value.
struct SensorFrameTest {
  static constexpr double kMaxZM = 1000.0;

  SensorFrameTest(const Vector3d& normal, double offset, double lo_limit, double hi_limit,
                  double margin)
      : nx(normal.x()),
        ny(normal.y()),
        nz(normal.z()),
        d(offset),
        lo(lo_limit - margin),
        hi(hi_limit + margin),
        inner_lo(lo_limit + margin),
        inner_hi(hi_limit - margin) {}

  double value(double x, double y, double z) const { return nx * x + ny * y + nz * z + d; }

  double nx, ny, nz, d;
  double lo, hi;              // values outside are surely outside the limits
  double inner_lo, inner_hi;  // values inside are surely inside
};

// least-squares plane z = a x + b y + c through the points within `tolerance` of `plane`: the
// normal equations summed term by term (the products each entry of sum (x, y, 1)^T (x, y, 1)
// and sum (x, y, 1)^T z takes, in the points' order)
bool fit_plane(const std::vector<Vector3d>& points, double tolerance, GroundPlane& plane) {
  double xx = 0.0, xy = 0.0, yy = 0.0, sx = 0.0, sy = 0.0, count = 0.0;
  double xz = 0.0, yz = 0.0, sz = 0.0;
  const HeightBand band(plane, -tolerance, tolerance);
  double h = 0.0;
  for (const Vector3d& p : points) {
    if (!band.contains(p, h)) continue;
    const double x = p.x(), y = p.y(), z = p.z();
    xx += x * x, xy += x * y, yy += y * y;
    sx += x, sy += y, count += 1.0;
    xz += x * z, yz += y * z, sz += z;
  }
  if (count < 20.0) return false;
  Eigen::Matrix3d ata;
  ata << xx, xy, sx, xy, yy, sy, sx, sy, count;
  const Vector3d x = ata.ldlt().solve(Vector3d(xz, yz, sz));
  if (!x.allFinite()) return false;
  plane = {x(0), x(1), x(2)};
  return true;
}

// union-find over point indices, with path halving
int find_root(std::vector<int>& parent, int i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];
    i = parent[i];
  }
  return i;
}

// Clusters as one array of point indices, cluster after cluster.
struct Clusters {
  std::vector<int> members;
  std::vector<int> offsets{0};  // cluster k is members[offsets[k], offsets[k + 1])

  int size() const { return static_cast<int>(offsets.size()) - 1; }
  std::span<const int> operator[](int k) const {
    return {members.data() + offsets[k], members.data() + offsets[k + 1]};
  }
};

// a stable sort of items by a small integer key in [0, range): counting sort
void counting_sort(std::vector<std::pair<int64_t, int>>& items, const std::vector<int>& key,
                   int range, std::vector<std::pair<int64_t, int>>& out) {
  std::vector<int> start(static_cast<size_t>(range) + 1, 0);
  for (const auto& item : items) ++start[key[item.second] + 1];
  for (int k = 0; k < range; ++k) start[k + 1] += start[k];
  out.resize(items.size());
  for (const auto& item : items) out[start[key[item.second]]++] = item;
  items.swap(out);
}

// clusters of the raised points: points whose feet are within `distance` are linked; clusters
// come out ordered by their first point (the firing order), points in firing order
Clusters euclidean_clusters(const std::vector<RaisedPoint>& points, double distance) {
  // a grid of cells small enough that any two points of one cell are within `distance` (side
  // distance / sqrt 2): a cell's points belong together, and two points within `distance` lie
  // at most two cells apart on each axis
  const int n = static_cast<int>(points.size());
  const double side = distance / std::sqrt(2.0);
  auto cell_of = [side](const Vector2d& p) {
    return std::array<int64_t, 2>{static_cast<int64_t>(std::floor(p.x() / side)),
                                  static_cast<int64_t>(std::floor(p.y() / side))};
  };
  constexpr int64_t kRow = int64_t{1} << 32;
  auto key_of = [](int64_t cx, int64_t cy) { return cx * kRow + cy; };
  // the points by cell key (cx, then cy), then index: two stable counting sorts, on cy then on
  // cx, when the cells span a small grid (else a comparison sort)
  std::vector<std::pair<int64_t, int>> sorted(static_cast<size_t>(n));
  std::vector<int> cx(static_cast<size_t>(n)), cy(static_cast<size_t>(n));
  int64_t lo_x = std::numeric_limits<int64_t>::max(), hi_x = std::numeric_limits<int64_t>::min();
  int64_t lo_y = lo_x, hi_y = hi_x;
  for (int i = 0; i < n; ++i) {
    const auto c = cell_of(points[i].foot);
    sorted[static_cast<size_t>(i)] = {key_of(c[0], c[1]), i};
    lo_x = std::min(lo_x, c[0]), hi_x = std::max(hi_x, c[0]);
    lo_y = std::min(lo_y, c[1]), hi_y = std::max(hi_y, c[1]);
  }
  constexpr int64_t kMaxGridCells = 1 << 16;
  if (n > 0 && hi_x - lo_x < kMaxGridCells && hi_y - lo_y < kMaxGridCells && lo_x > -kRow / 4 &&
      hi_x < kRow / 4 && lo_y > -kRow / 4 && hi_y < kRow / 4) {
    for (int i = 0; i < n; ++i) {
      const auto c = cell_of(points[i].foot);
      cx[static_cast<size_t>(i)] = static_cast<int>(c[0] - lo_x);
      cy[static_cast<size_t>(i)] = static_cast<int>(c[1] - lo_y);
    }
    std::vector<std::pair<int64_t, int>> buffer;
    counting_sort(sorted, cy, static_cast<int>(hi_y - lo_y + 1), buffer);
    counting_sort(sorted, cx, static_cast<int>(hi_x - lo_x + 1), buffer);
  } else {
    std::sort(sorted.begin(), sorted.end());
  }

  // the occupied cells: runs of the sorted points
  struct Cell {
    int64_t key, cx, cy;
    size_t begin, end;
  };
  std::vector<Cell> cells;
  cells.reserve(sorted.size());
  for (size_t k = 0; k < sorted.size(); ++k) {
    if (cells.empty() || cells.back().key != sorted[k].first) {
      const auto c = cell_of(points[sorted[k].second].foot);
      cells.push_back({sorted[k].first, c[0], c[1], k, k});
    }
    cells.back().end = k + 1;
  }

  // union-find: each cell's points joined, then each pair of nearby cells joined by their first
  // pair of points within `distance` (once joined, a pair of cells needs no more checks)
  std::vector<int> parent(static_cast<size_t>(n));
  std::iota(parent.begin(), parent.end(), 0);
  auto join = [&parent](int a, int b) {
    const int ra = find_root(parent, a), rb = find_root(parent, b);
    if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
  };
  for (const Cell& cell : cells)
    for (size_t k = cell.begin + 1; k < cell.end; ++k)
      join(sorted[cell.begin].second, sorted[k].second);
  const double distance2 = distance * distance;
  // the cells (cx + dx, cy - 2 .. cy + 2) for dx = 0, 1, 2 are runs of the sorted cells whose
  // starts only move forward as the cells are visited in order: one cursor per dx
  std::array<size_t, 3> cursor{0, 0, 0};
  for (const Cell& cell : cells) {
    for (int64_t dx = 0; dx <= 2; ++dx) {
      const int64_t first = key_of(cell.cx + dx, cell.cy - 2),
                    last = key_of(cell.cx + dx, cell.cy + 2);
      size_t& k = cursor[static_cast<size_t>(dx)];
      while (k < cells.size() && cells[k].key < first) ++k;
      for (size_t o = k; o < cells.size() && cells[o].key <= last; ++o) {
        const Cell& other = cells[o];
        if (dx == 0 && other.cy <= cell.cy) continue;  // each pair of cells once
        const int a0 = sorted[cell.begin].second, b0 = sorted[other.begin].second;
        if (find_root(parent, a0) == find_root(parent, b0)) continue;
        bool joined = false;
        for (size_t i = cell.begin; i < cell.end && !joined; ++i)
          for (size_t j = other.begin; j < other.end && !joined; ++j)
            if ((points[sorted[i].second].foot - points[sorted[j].second].foot).squaredNorm() <=
                distance2) {
              join(a0, b0);
              joined = true;
            }
      }
    }
  }

  // gather: roots are the smallest index of their cluster, so this order is deterministic
  Clusters clusters;
  std::vector<int>& cluster_of = cx;  // reused: the cluster of each root, or -1
  std::fill(cluster_of.begin(), cluster_of.end(), -1);
  std::vector<int>& count = cy;  // reused: points per cluster
  int cluster_count = 0;
  for (int i = 0; i < n; ++i) {
    const int root = find_root(parent, i);
    if (cluster_of[root] < 0) count[static_cast<size_t>(cluster_of[root] = cluster_count++)] = 0;
    ++count[static_cast<size_t>(cluster_of[root])];
  }
  clusters.offsets.resize(static_cast<size_t>(cluster_count) + 1);
  for (int k = 0; k < cluster_count; ++k) clusters.offsets[k + 1] = clusters.offsets[k] + count[k];
  clusters.members.resize(static_cast<size_t>(n));
  std::vector<int>& next = count;  // reused: the next free slot of each cluster
  for (int k = 0; k < cluster_count; ++k) next[k] = clusters.offsets[k];
  for (int i = 0; i < n; ++i) clusters.members[next[cluster_of[find_root(parent, i)]]++] = i;
  return clusters;
}

// body radius of a cone shape at a height above the ground (clamped to the body)
double body_radius(const core::ConeGeometry& g, double height_m) {
  const double z = std::clamp(height_m, g.bands.front().z_bottom_m, g.bands.back().z_top_m);
  for (const core::ConeBand& band : g.bands)
    if (z <= band.z_top_m) {
      const double s = (z - band.z_bottom_m) / (band.z_top_m - band.z_bottom_m);
      return band.radius_bottom_m + s * (band.radius_top_m - band.radius_bottom_m);
    }
  return g.bands.back().radius_top_m;
}

// The paint a point at a measured height may be on: its own band's and, with probability
// p_other, the band across the nearest inner edge (the measured height is uncertain by
// sigma_m: the ground fit and the beam's footprint)
struct BandChance {
  bool stripe_here = false;
  bool stripe_other = false;
  double p_other = 0.0;
};
bool in_stripe(const core::ConeGeometry& g, double height_m);
BandChance band_chance(const core::ConeGeometry& g, double height_m, double sigma_m) {
  BandChance c;
  c.stripe_here = in_stripe(g, height_m);
  double nearest = std::numeric_limits<double>::infinity();
  for (size_t k = 0; k + 1 < g.bands.size(); ++k) {
    const double d = std::abs(height_m - g.bands[k].z_top_m);
    if (d < nearest)
      nearest = d,
      c.stripe_other = height_m < g.bands[k].z_top_m ? g.bands[k + 1].stripe : g.bands[k].stripe;
  }
  c.p_other = c.stripe_other == c.stripe_here
                  ? 0.0
                  : 0.5 * std::erfc(nearest / (sigma_m * std::numbers::sqrt2));
  return c;
}

// true when the height falls in a stripe of the shape
bool in_stripe(const core::ConeGeometry& g, double height_m) {
  for (const core::ConeBand& band : g.bands)
    if (height_m < band.z_top_m) return band.stripe;
  return g.bands.back().stripe;
}

// the centre of a cone (ground-projected) whose visible surface the points are on: least
// squares of |q - c| - r(h) by Gauss-Newton, started one mean radius behind the centroid
// along the line of sight; returns the start when the fit runs away
Vector2d fit_centre(const std::vector<RaisedPoint>& points, std::span<const int> cluster,
                    const core::ConeGeometry& shape, const Vector2d& sensor_xy,
                    std::vector<double>& radius) {
  // the body radius at each point's height, once
  radius.clear();
  for (const int i : cluster) radius.push_back(body_radius(shape, points[i].height_m));
  Vector2d centroid = Vector2d::Zero();
  double mean_radius = 0.0;
  for (size_t k = 0; k < cluster.size(); ++k) {
    centroid += points[cluster[k]].foot;
    mean_radius += radius[k];
  }
  centroid /= static_cast<double>(cluster.size());
  mean_radius /= static_cast<double>(cluster.size());
  const Vector2d ray = (centroid - sensor_xy).normalized();
  const Vector2d start = centroid + ray * mean_radius;

  // Gauss-Newton with a small damping (a prior on the start) for clusters on one short arc
  Vector2d c = start;
  for (int iteration = 0; iteration < 8; ++iteration) {
    Eigen::Matrix2d jtj = Eigen::Matrix2d::Identity() * 1e-3;
    Vector2d jtr = 1e-3 * (c - start);
    for (size_t k = 0; k < cluster.size(); ++k) {
      const Vector2d d = points[cluster[k]].foot - c;
      const double norm = d.norm();
      if (norm < 1e-6) continue;
      const Vector2d j = -d / norm;
      const double r = norm - radius[k];
      jtj += j * j.transpose();
      jtr += j * r;
    }
    const Vector2d step = -jtj.ldlt().solve(jtr);
    if (!step.allFinite()) return start;
    c += step;
    if (step.norm() < 1e-5) break;
  }
  return (c - start).norm() > 1.5 * mean_radius ? start : c;
}

// A cluster cut into k cones: each point's cone and what the cut costs.
struct RowCut {
  std::vector<int> cone_of;  // per point of the cluster
  double cost = std::numeric_limits<double>::infinity();
  double chi2 = 0.0;        // the residuals' part of the cost
  double lowest_top = 0.0;  // the lowest of the cones' tops above the ground, metres
};

// The pieces of a cut, each in the cluster's order.
void gather_pieces(std::span<const int> cluster, const std::vector<int>& cone_of, int k,
                   Clusters& pieces) {
  pieces.members.resize(cluster.size());
  pieces.offsets.assign(static_cast<size_t>(k) + 1, 0);
  for (const int j : cone_of) ++pieces.offsets[static_cast<size_t>(j) + 1];
  for (int j = 0; j < k; ++j) pieces.offsets[j + 1] += pieces.offsets[j];
  std::vector<int> next(pieces.offsets.begin(), pieces.offsets.end() - 1);
  for (size_t m = 0; m < cluster.size(); ++m) pieces.members[next[cone_of[m]]++] = cluster[m];
}

// The best cut of a cluster into k cones: started from 1-D k-means of the points' positions
// `along` its long axis, then on the cones' shapes: each cone's centre fitted to its points
// (big when their top is above a small cone), each point given to the cone whose surface it
// lies nearest, until no point moves (the nearer cone hides part of the farther one, so the cut
// is not where the axis halves the points). Its cost: the squared surface residuals over
// sigma^2 (each at most 9, so that a stray return does not ask for a cone of its own), plus
// BIC's 2 ln n per cone (two unknowns each); infinite when a cone has too few points or two
// cones overlap.
RowCut cut_row(const std::vector<RaisedPoint>& points, std::span<const int> cluster,
               const std::vector<double>& along, int k, const LidarDetectorConfig& config,
               const core::ConeGeometry& small, const core::ConeGeometry& big,
               const Vector2d& sensor_xy, std::vector<double>& radius, Clusters& pieces) {
  const size_t n = cluster.size();
  RowCut cut;
  cut.cone_of.assign(n, 0);
  // 1-D k-means from evenly spaced centres (nearest centre, ties to the lower one)
  const auto [s_lo, s_hi] = std::minmax_element(along.begin(), along.end());
  std::vector<double> centre(static_cast<size_t>(k)), sum(centre.size());
  std::vector<int> count(centre.size());
  for (int j = 0; j < k; ++j) centre[j] = *s_lo + (j + 0.5) * (*s_hi - *s_lo) / k;
  for (int iteration = 0; iteration < 20; ++iteration) {
    std::fill(sum.begin(), sum.end(), 0.0);
    std::fill(count.begin(), count.end(), 0);
    for (size_t m = 0; m < n; ++m) {
      int best = 0;
      for (int j = 1; j < k; ++j)
        if (std::abs(along[m] - centre[j]) < std::abs(along[m] - centre[best])) best = j;
      cut.cone_of[m] = best, sum[best] += along[m], ++count[best];
    }
    bool moved = false;
    for (int j = 0; j < k; ++j) {
      const double next = count[j] ? sum[j] / count[j] : centre[j];
      moved = moved || next != centre[j];
      centre[j] = next;
    }
    if (!moved) break;
  }
  // then on the shapes
  const double sigma =
      std::hypot(config.range_noise_sigma_m, config.model_sigma_m, config.height_sigma_m);
  std::vector<Vector2d> centres(static_cast<size_t>(k));
  std::vector<const core::ConeGeometry*> shapes(static_cast<size_t>(k));
  for (int round = 0; round < 6; ++round) {
    gather_pieces(cluster, cut.cone_of, k, pieces);
    cut.lowest_top = std::numeric_limits<double>::infinity();
    for (int j = 0; j < k; ++j) {
      const std::span<const int> members = pieces[j];
      if (static_cast<int>(members.size()) < config.min_cluster_points) {
        cut.cost = std::numeric_limits<double>::infinity();
        return cut;
      }
      double top = 0.0;
      for (const int i : members) top = std::max(top, points[i].height_m);
      cut.lowest_top = std::min(cut.lowest_top, top);
      shapes[j] = top >= config.big_cone_min_height_m ? &big : &small;
      centres[j] = fit_centre(points, members, *shapes[j], sensor_xy, radius);
    }
    // cones stand on their plates: two centres are at least a small plate's width apart (less
    // the fits' errors), else the cut has made two cones of one
    for (int j = 0; j < k; ++j)
      for (int l = j + 1; l < k; ++l)
        if ((centres[j] - centres[l]).norm() < 0.8 * small.base_width_m) {
          cut.cost = std::numeric_limits<double>::infinity();
          return cut;
        }
    bool moved = false;
    double chi2 = 0.0;
    for (size_t m = 0; m < n; ++m) {
      const RaisedPoint& p = points[cluster[m]];
      int best = cut.cone_of[m];
      double best_residual = std::numeric_limits<double>::infinity();
      for (int j = 0; j < k; ++j) {
        const double residual =
            std::abs((p.foot - centres[j]).norm() - body_radius(*shapes[j], p.height_m));
        if (residual < best_residual) best = j, best_residual = residual;
      }
      chi2 += std::min(9.0, best_residual * best_residual / (sigma * sigma));
      moved = moved || best != cut.cone_of[m];
      cut.cone_of[m] = best;
    }
    cut.chi2 = chi2;
    cut.cost = chi2 + 2.0 * k * std::log(static_cast<double>(n));
    if (!moved) break;
  }
  return cut;
}

// A cluster that may be a row of cones whose bases touch (a start gate's big orange cones stand
// 0.26-0.30 m apart, centre to centre), which link into one cluster: one wider than a cone, or
// deeper along the line of sight than a cone's visible half, and narrower than
// config.max_row_cones cones. Cut into the number of cones (one to max_row_cones) whose cut
// costs least; true with the pieces (each in the cluster's order) when that is more than one.
bool split_row(const std::vector<RaisedPoint>& points, std::span<const int> cluster,
               const LidarDetectorConfig& config, const core::ConeGeometry& small,
               const core::ConeGeometry& big, const Vector2d& sensor_xy,
               std::vector<double>& radius, Clusters& pieces) {
  if (config.max_row_cones < 2 || static_cast<int>(cluster.size()) < 2 * config.min_cluster_points)
    return false;
  Vector2d lo = Vector2d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  Vector2d mean = Vector2d::Zero();
  for (const int i : cluster) {
    lo = lo.cwiseMin(points[i].foot);
    hi = hi.cwiseMax(points[i].foot);
    mean += points[i].foot;
  }
  mean /= static_cast<double>(cluster.size());
  const double extent = (hi - lo).norm();
  if (extent > config.max_cluster_extent_m + (config.max_row_cones - 1) * big.base_width_m)
    return false;
  // a cone's visible points lie within its body's bottom radius of its front, along the line of
  // sight (plus the range noise's spread)
  const Vector2d ray = (mean - sensor_xy).normalized();
  double near = std::numeric_limits<double>::infinity(), far = -near;
  for (const int i : cluster) {
    const double depth = ray.dot(points[i].foot - mean);
    near = std::min(near, depth), far = std::max(far, depth);
  }
  const double deepest_cone = body_radius(big, 0.0) + 6.0 * config.range_noise_sigma_m;
  if (extent <= config.max_cluster_extent_m && far - near <= deepest_cone) return false;
  // the long axis: the principal direction of the feet
  double sxx = 0.0, sxy = 0.0, syy = 0.0;
  for (const int i : cluster) {
    const Vector2d d = points[i].foot - mean;
    sxx += d.x() * d.x(), sxy += d.x() * d.y(), syy += d.y() * d.y();
  }
  const double angle = 0.5 * std::atan2(2.0 * sxy, sxx - syy);
  const Vector2d axis(std::cos(angle), std::sin(angle));
  std::vector<double> along(cluster.size());
  for (size_t m = 0; m < cluster.size(); ++m) along[m] = axis.dot(points[cluster[m]].foot - mean);
  int best_k = 1;
  RowCut best;
  for (int k = 1; k <= config.max_row_cones; ++k) {
    RowCut cut = cut_row(points, cluster, along, k, config, small, big, sensor_xy, radius, pieces);
    if (cut.cost < best.cost) best = std::move(cut), best_k = k;
  }
  // a row of cones shows each cone's body (feet of fences and tents, kerbs do not), and its
  // points lie on the cones' surfaces within the noise: the residuals' mean (each squared
  // residual over sigma^2 about 1 on a cone, with the standard error sqrt(2 / n) of the mean)
  // within 0.5 for the model's error and four standard errors (tyre stacks, barriers and
  // people fit no row of cones that well)
  const double n = static_cast<double>(cluster.size());
  if (best_k == 1 || best.lowest_top < 0.5 * small.height_m ||
      best.chi2 / n > 1.5 + 4.0 * std::sqrt(2.0 / n))
    return false;
  gather_pieces(cluster, best.cone_of, best_k, pieces);
  return true;
}

// Log-likelihood of a shape from the width of each ring's points across the line of sight:
// a ring crossing the body at height h spans its full width 2 r(h), less on average one
// column step (the edge columns fall anywhere within a step of the silhouette), with a
// spread of about half a step plus the model error. Rings with one point say nothing.
double width_log_likelihood(const LidarDetectorConfig& config,
                            const std::vector<RaisedPoint>& points, std::span<const int> cluster,
                            const core::ConeGeometry& shape, const Vector2d& sensor_xy) {
  Vector2d centroid = Vector2d::Zero();
  for (const int i : cluster) centroid += points[i].foot;
  centroid /= static_cast<double>(cluster.size());
  const Vector2d ray = (centroid - sensor_xy).normalized();
  const Vector2d across(-ray.y(), ray.x());

  // per ring: lateral extent, mean height and range
  struct RingSpan {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    double height_sum = 0.0, range_sum = 0.0;
    int n = 0;
  };
  std::unordered_map<int, RingSpan> rings;
  for (const int i : cluster) {
    RingSpan& r = rings[points[i].ring];
    const double lateral = (points[i].foot - centroid).dot(across);
    r.lo = std::min(r.lo, lateral);
    r.hi = std::max(r.hi, lateral);
    r.height_sum += points[i].height_m;
    r.range_sum += points[i].range_m;
    ++r.n;
  }
  double log_likelihood = 0.0;
  for (const auto& [ring, r] : rings) {
    if (r.n < 2) continue;
    const double step = r.range_sum / r.n * config.azimuth_step_deg * kDeg;
    const double expected = 2.0 * body_radius(shape, r.height_sum / r.n) - step;
    const double sigma = 0.5 * step + config.model_sigma_m;
    const double z = (r.hi - r.lo - expected) / sigma;
    log_likelihood += -0.5 * z * z;
  }
  return log_likelihood;
}

// one paint hypothesis: a shape and the reflectivity of its body and stripe
struct PaintHypothesis {
  ConeClass cls;
  core::ConeGeometry shape;
  double body;
  double stripe;
};

// the classes a cluster may be, by its size: small, big or undecided
struct PaintHypotheses {
  std::array<PaintHypothesis, 4> h;
  size_t size = 0;
};
PaintHypotheses hypotheses_for(const LidarDetectorConfig& c, bool may_be_small, bool may_be_big) {
  PaintHypotheses h;
  const core::ConeGeometry small = core::cone_geometry(ConeClass::kBlue);
  if (may_be_small) {
    h.h[h.size++] = {ConeClass::kBlue, small, c.reflectivity_blue, c.reflectivity_white};
    h.h[h.size++] = {ConeClass::kYellow, small, c.reflectivity_yellow, c.reflectivity_black};
    h.h[h.size++] = {ConeClass::kOrangeSmall, small, c.reflectivity_orange, c.reflectivity_white};
  }
  if (may_be_big)
    h.h[h.size++] = {ConeClass::kOrangeBig, core::cone_geometry(ConeClass::kOrangeBig),
                     c.reflectivity_orange, c.reflectivity_white};
  return h;
}

// buffers of classify_paint, kept over the clusters of a sweep
struct PaintScratch {
  struct Seen {
    double measured, scale, p_other;
    bool stripe_here, stripe_other;
  };
  struct Expected {
    double measured, here, other, p_other;
  };
  std::vector<Seen> seen;
  std::vector<Expected> used;
};

// The class whose paint pattern explains the intensities best. Each point's expected intensity
// is 255 x reflectivity of the band at its height x cos(incidence) x range fall-off, with the
// incidence from where the point sits on the visible half-circle (the silhouette is grazing)
// and the taper of the body; one free gain per hypothesis absorbs what the model misses. The
// hypotheses are scored by their Gaussian log-likelihood; kUnknown when the best does not lead
// the runner-up by colour_min_log_likelihood_ratio, or too few points are usable.
ConeClass classify_paint(const LidarDetectorConfig& config, const std::vector<RaisedPoint>& points,
                         std::span<const int> cluster, const Vector2d& centre,
                         const Vector2d& sensor_xy, const PaintHypotheses& hypotheses,
                         PaintScratch& scratch) {
  if (hypotheses.size == 0) return ConeClass::kUnknown;
  if (hypotheses.size == 1) return hypotheses.h[0].cls;
  const Vector2d ray = (centre - sensor_xy).normalized();
  const Vector2d across(-ray.y(), ray.x());
  const double half_spot = std::tan(0.5e-3 * config.beam_divergence_mrad);

  // mean log-likelihood per usable point of each hypothesis (shapes differ in the points they
  // can use), scaled below by the fewest usable points
  std::array<double, 4> mean_log_likelihood{};
  size_t fewest_used = cluster.size();
  // the usable points of a shape, with the band each may be on and its expected intensity per
  // unit reflectivity; hypotheses of one shape (the small ones) share them
  using Seen = PaintScratch::Seen;
  using Expected = PaintScratch::Expected;
  std::vector<Seen>& seen = scratch.seen;
  const core::ConeBand* seen_shape = nullptr;
  std::vector<Expected>& used = scratch.used;
  for (size_t k = 0; k < hypotheses.size; ++k) {
    const PaintHypothesis& h = hypotheses.h[k];
    if (h.shape.bands.data() != seen_shape) {
      seen_shape = h.shape.bands.data();
      seen.clear();
      const double taper =
          std::atan2(h.shape.bands.front().radius_bottom_m - h.shape.bands.back().radius_top_m,
                     h.shape.height_m - h.shape.plate_height_m);
      const double cos_taper = std::cos(taper);
      for (const int i : cluster) {
        const RaisedPoint& p = points[i];
        if (p.height_m > h.shape.height_m + 0.02) continue;
        const double radius = body_radius(h.shape, p.height_m);
        const double u = (p.foot - centre).dot(across) / radius;
        // (the half spot at the point's range, as a share of the radius, off the usable width)
        if (std::abs(u) > 0.85 - half_spot * p.range_m / radius) continue;
        const BandChance band = band_chance(h.shape, p.height_m, config.height_sigma_m);
        const double falloff = 1.0 / (1.0 + std::pow(p.range_m / config.intensity_falloff_m, 2));
        const double scale = 255.0 * std::sqrt(1.0 - u * u) * cos_taper * falloff;
        seen.push_back({p.intensity, scale, band.p_other, band.stripe_here, band.stripe_other});
      }
    }
    // expected intensities of the usable points (gain 1), in their band and across the edge
    used.clear();
    for (const Seen& s : seen)
      used.push_back({s.measured, s.scale * (s.stripe_here ? h.stripe : h.body),
                      s.scale * (s.stripe_other ? h.stripe : h.body), s.p_other});
    if (static_cast<int>(used.size()) < config.colour_min_points) return ConeClass::kUnknown;

    // the gain by least squares on the points sure of their band, kept near 1; then the
    // log-likelihood of the intensities, a mixture of the two bands near an edge
    double num = 0.0, den = 0.0;
    for (const Expected& e : used) {
      const double w = (1.0 - 2.0 * e.p_other) * (1.0 - 2.0 * e.p_other);
      num += w * e.measured * e.here, den += w * e.here * e.here;
    }
    const double gain =
        std::clamp(den > 0.0 ? num / den : 1.0, 1.0 - config.intensity_gain_tolerance,
                   1.0 + config.intensity_gain_tolerance);
    auto density = [&config, gain](double measured, double expected) {
      const double sigma = config.intensity_sigma + config.intensity_model_error * gain * expected;
      const double r = (measured - gain * expected) / sigma;
      return std::exp(-0.5 * r * r) / sigma;
    };
    double log_likelihood = 0.0;
    // (a point sure of its band adds nothing across the edge: the density there is finite)
    for (const Expected& e : used) {
      const double across_edge = e.p_other > 0.0 ? e.p_other * density(e.measured, e.other) : 0.0;
      log_likelihood +=
          std::log((1.0 - e.p_other) * density(e.measured, e.here) + across_edge + 1e-300);
    }
    mean_log_likelihood[k] = log_likelihood / static_cast<double>(used.size());
    fewest_used = std::min(fewest_used, used.size());
  }
  double best = -std::numeric_limits<double>::infinity(), second = best;
  ConeClass best_cls = ConeClass::kUnknown;
  for (size_t k = 0; k < hypotheses.size; ++k) {
    const double log_likelihood = mean_log_likelihood[k] * static_cast<double>(fewest_used);
    if (log_likelihood > best) {
      second = best;
      best = log_likelihood;
      best_cls = hypotheses.h[k].cls;
    } else if (log_likelihood > second) {
      second = log_likelihood;
    }
  }
  return best - second >= config.colour_min_log_likelihood_ratio ? best_cls : ConeClass::kUnknown;
}

// Covariance of a fitted centre, in the vehicle frame. The centre inherits the range noise of
// the n points, sigma_r^2 / n, along and (through the circle fit over the visible half) across
// the line of sight; both get the model error (radius at a height, facets, ground fit:
// sigma_m^2) and the de-skew error deskew_sigma_m: a speed off by speed_relative_sigma x speed
// displaces the cluster by that times the time from its mean firing to the sweep end (without
// de-skew, the whole motion over that time is the error). Across the line of
// sight the bearing error adds (range x sigma_bearing)^2: this and the 1/n term (n falls with the
// square of the range) make the covariance grow with range.
Eigen::Matrix2d covariance_of(const LidarDetectorConfig& c, const Vector2d& centre_vehicle,
                              const Vector2d& sensor_xy, int n, double deskew_sigma_m) {
  const Vector2d line = centre_vehicle - sensor_xy;
  const double range = line.norm();
  const Vector2d ray = line / std::max(range, 1e-6);
  const double common = c.range_noise_sigma_m * c.range_noise_sigma_m / std::max(n, 1) +
                        c.model_sigma_m * c.model_sigma_m + deskew_sigma_m * deskew_sigma_m;
  const double along = common;
  const double across = common + std::pow(range * c.bearing_sigma_rad, 2);
  Eigen::Matrix2d rotation;
  rotation << ray.x(), -ray.y(), ray.y(), ray.x();
  return rotation * Eigen::Vector2d(along, across).asDiagonal() * rotation.transpose();
}

}  // namespace

std::string LidarDetectorConfig::validate() const {
  std::ostringstream e;
  auto positive = [&e](const char* key, double v) {
    if (!(v > 0.0) && e.tellp() == 0) e << key << ": expected > 0, got " << v;
  };
  auto non_negative = [&e](const char* key, double v) {
    if (!(v >= 0.0) && e.tellp() == 0) e << key << ": expected >= 0, got " << v;
  };
  auto fraction = [&e](const char* key, double v) {
    if (!(v >= 0.0 && v <= 1.0) && e.tellp() == 0) e << key << ": expected 0-1, got " << v;
  };
  positive("sweep_period_s", sweep_period_s);
  positive("max_range_m", max_range_m);
  non_negative("min_range_m", min_range_m);
  if (e.tellp() == 0 && min_range_m >= max_range_m)
    e << "min_range_m: expected < max_range_m (" << max_range_m << "), got " << min_range_m;
  positive("ground_candidate_band_m", ground_candidate_band_m);
  positive("ground_inlier_m", ground_inlier_m);
  non_negative("min_point_height_m", min_point_height_m);
  if (e.tellp() == 0 && max_point_height_m <= min_point_height_m)
    e << "max_point_height_m: expected > min_point_height_m, got " << max_point_height_m;
  positive("cluster_distance_m", cluster_distance_m);
  if (e.tellp() == 0 && min_cluster_points < 1)
    e << "min_cluster_points: expected >= 1, got " << min_cluster_points;
  positive("max_cluster_extent_m", max_cluster_extent_m);
  if (e.tellp() == 0 && (max_row_cones < 1 || max_row_cones > 8))
    e << "max_row_cones: expected 1 to 8, got " << max_row_cones;
  non_negative("min_cone_height_m", min_cone_height_m);
  if (e.tellp() == 0 && max_cone_height_m <= min_cone_height_m)
    e << "max_cone_height_m: expected > min_cone_height_m, got " << max_cone_height_m;
  positive("big_cone_min_height_m", big_cone_min_height_m);
  positive("ring_spacing_deg", ring_spacing_deg);
  non_negative("ring_above_margin_m", ring_above_margin_m);
  for (size_t i = 1; e.tellp() == 0 && i < ring_elevations_deg.size(); ++i)
    if (!(ring_elevations_deg[i] > ring_elevations_deg[i - 1]))
      e << "ring_elevations_deg: expected strictly increasing elevations, ring 0 lowest";
  positive("azimuth_step_deg", azimuth_step_deg);
  non_negative("size_min_log_likelihood_ratio", size_min_log_likelihood_ratio);
  fraction("reflectivity_blue", reflectivity_blue);
  fraction("reflectivity_yellow", reflectivity_yellow);
  fraction("reflectivity_orange", reflectivity_orange);
  fraction("reflectivity_white", reflectivity_white);
  fraction("reflectivity_black", reflectivity_black);
  positive("intensity_falloff_m", intensity_falloff_m);
  positive("intensity_sigma", intensity_sigma);
  non_negative("intensity_model_error", intensity_model_error);
  if (e.tellp() == 0 && !(beam_divergence_mrad >= 0.0 && beam_divergence_mrad <= 50.0))
    e << "beam_divergence_mrad: expected 0-50, got " << beam_divergence_mrad;
  if (e.tellp() == 0 && !(intensity_gain_tolerance >= 0.0 && intensity_gain_tolerance < 1.0))
    e << "intensity_gain_tolerance: expected 0-1, got " << intensity_gain_tolerance;
  positive("height_sigma_m", height_sigma_m);
  if (e.tellp() == 0 && colour_min_points < 1)
    e << "colour_min_points: expected >= 1, got " << colour_min_points;
  non_negative("colour_min_log_likelihood_ratio", colour_min_log_likelihood_ratio);
  positive("range_noise_sigma_m", range_noise_sigma_m);
  positive("model_sigma_m", model_sigma_m);
  non_negative("bearing_sigma_rad", bearing_sigma_rad);
  non_negative("speed_relative_sigma", speed_relative_sigma);
  return e.str();
}

core::ConeObservations LidarDetections::observations() const {
  core::ConeObservations out;
  out.stamp = stamp;
  out.cones.reserve(cones.size());
  for (const LidarCone& cone : cones) out.cones.push_back(cone.observation);
  return out;
}

LidarConeDetector::LidarConeDetector(const LidarDetectorConfig& config,
                                     const core::Pose3& sensor_in_vehicle)
    : config_(config), sensor_in_vehicle_(sensor_in_vehicle) {
  const std::string error = config_.validate();
  if (!error.empty()) throw std::invalid_argument("lidar cone detector: " + error);
}

LidarDetections LidarConeDetector::detect(const core::PointCloud& cloud,
                                          const SweepMotion& motion) const {
  return detect(cloud, motion, cloud.stamp + core::from_seconds(config_.sweep_period_s));
}

LidarDetections LidarConeDetector::detect(const core::PointCloud& cloud, const SweepMotion& motion,
                                          core::TimeUs frame_stamp) const {
  const LidarDetectorConfig& c = config_;
  LidarDetections out;
  out.stamp = frame_stamp;
  // the frame's time after the sweep's start: the points are moved to the vehicle frame then
  const double frame_s = std::max(0.0, core::to_seconds(frame_stamp - cloud.stamp));
  const int n = static_cast<int>(cloud.points.size());

  // de-skew: a point fired at tau is in the vehicle frame of tau; the vehicle at the sweep end
  // is arc_motion(T - tau) ahead of it, so the point moves by that motion's inverse (columns
  // share tau, so the motion is computed once per column). Only the points within the sensor's
  // horizontal range window count. Moving every point would cost more than the rest of the
  // detector: the points are sorted in the sensor frame instead (SensorFrameTest), and only
  // those the fits use and those near a limit are moved (to_vehicle)
  const RangeWindow window(c.min_range_m, c.max_range_m);
  const core::Pose3& mount = sensor_in_vehicle_;
  const Eigen::Matrix3d rotation = mount.orientation.toRotationMatrix();
  const Vector3d& t = mount.position;
  // bound of the terms' magnitudes, for the margins of the sensor-frame tests; the rotation
  // matrix and the quaternion agree only for a unit quaternion (else every point is moved)
  const double magnitude_m = t.cwiseAbs().sum() + 2.0 * c.max_range_m + SensorFrameTest::kMaxZM +
                             std::abs(motion.speed_mps) * frame_s + 1.0;
  const double relative_margin = std::abs(mount.orientation.squaredNorm() - 1.0) < 1e-12
                                     ? 1e-9
                                     : std::numeric_limits<double>::infinity();
  SweepColumns columns(motion, frame_s, n);
  auto column_motion = [&columns, &c](int column) -> const ColumnMotion* {
    return c.deskew ? &columns[column] : nullptr;
  };

  // the points within the range window: `tame` ones (|z| up to kMaxZM) are sorted in the sensor
  // frame, `wild` ones always moved; ground candidates are those with |z| < band in the vehicle
  // frame (the de-skew keeps z)
  enum PointFlag : uint8_t { kTame = 1, kWild = 2, kCandidate = 4 };
  std::vector<uint8_t> flags(static_cast<size_t>(n), 0);
  size_t candidate_count = 0;
  {
    // |z| within the band's margin of its limit: the exact z decides
    const SensorFrameTest band(rotation.row(2).transpose(), t.z(), -c.ground_candidate_band_m,
                               c.ground_candidate_band_m, relative_margin * magnitude_m);
    const double sure_in = band.inner_hi, sure_out = band.hi;
    const double band_m = c.ground_candidate_band_m;
    const bool deskew = c.deskew;
    float last_tau = std::numeric_limits<float>::quiet_NaN();
    for (int i = 0; i < n; ++i) {
      const core::LidarPoint& p = cloud.points[i];
      if (!window.contains(p)) continue;
      if (deskew && p.time_offset_s != last_tau) {
        last_tau = p.time_offset_s;
        columns.add(i, p.time_offset_s);
      }
      const double z = std::abs(band.value(p.x, p.y, p.z));
      uint8_t flag = kTame | kCandidate;
      if (!(z < sure_in && std::abs(p.z) <= SensorFrameTest::kMaxZM)) {
        flag = std::abs(p.z) <= SensorFrameTest::kMaxZM ? kTame : kWild;
        if ((flag == kWild || !(z > sure_out)) &&
            std::abs(mount.transform(Vector3d(p.x, p.y, p.z)).z()) < band_m)
          flag |= kCandidate;
      }
      if (flag & kCandidate) ++candidate_count;
      flags[static_cast<size_t>(i)] = flag;
    }
  }

  // ground: the candidates, then two refits on the inliers. Three parameters need no more than
  // a few thousand points: every k-th candidate is used
  constexpr size_t kGroundFitPoints = 4000;
  const size_t stride =
      candidate_count > 2 * kGroundFitPoints ? candidate_count / kGroundFitPoints : 1;
  std::vector<Vector3d> candidates;
  candidates.reserve(candidate_count / stride + 1);
  {
    size_t skip = 0;  // candidates to pass over before the next one used
    int column = 0;
    for (int i = 0; i < n; ++i) {
      if (!(flags[static_cast<size_t>(i)] & kCandidate)) continue;
      if (skip > 0) {
        --skip;
        continue;
      }
      skip = stride - 1;
      if (c.deskew) column = columns.column_of(i, column);
      candidates.push_back(to_vehicle(mount, cloud.points[i], column_motion(column)));
    }
  }
  GroundPlane ground;
  if (fit_plane(candidates, c.ground_candidate_band_m, ground)) {
    GroundPlane refit = ground;
    if (fit_plane(candidates, 2.0 * c.ground_inlier_m, refit)) ground = refit;
    refit = ground;
    if (fit_plane(candidates, c.ground_inlier_m, refit)) ground = refit;
  }
  const Vector3d up = ground.normal();

  // the height band of the raised points as a sensor-frame test per column: the height of the
  // moved point is (z - A x - B y + A bx + B by - c) / |(a, b, -1)| with A = a cos - b sin and
  // B = a sin + b cos of the column's yaw, (x, y, z) = R p + t and (bx, by) its back motion
  const double inverse_length = 1.0 / std::sqrt(ground.a * ground.a + ground.b * ground.b + 1.0);
  auto height_test = [&](const ColumnMotion* m) {
    const double cos_yaw = m ? m->cos_yaw : 1.0, sin_yaw = m ? m->sin_yaw : 0.0;
    const double bx = m ? m->back.x : 0.0, by = m ? m->back.y : 0.0;
    const double a = ground.a * cos_yaw - ground.b * sin_yaw;
    const double b = ground.a * sin_yaw + ground.b * cos_yaw;
    const Vector3d normal =
        (rotation.row(2) - a * rotation.row(0) - b * rotation.row(1)).transpose() * inverse_length;
    const double offset =
        (t.z() - a * t.x() - b * t.y() + a * bx + b * by - ground.c) * inverse_length;
    const double slopes = std::abs(ground.a) + std::abs(ground.b) + std::abs(a) + std::abs(b);
    const double margin = relative_margin * (1.0 + slopes) *
                          (magnitude_m + std::abs(bx) + std::abs(by) + std::abs(ground.c));
    return SensorFrameTest(normal, offset, c.min_point_height_m, c.max_point_height_m, margin);
  };

  // raised points: heights along the plane's normal, feet on the plane, in firing order
  const Vector3d sensor = sensor_in_vehicle_.position;
  const Vector2d sensor_xy = (sensor - ground.height(sensor) * up).head<2>();
  std::vector<RaisedPoint> raised;
  raised.reserve(static_cast<size_t>(n / 32));
  const HeightBand raised_band(ground, c.min_point_height_m, c.max_point_height_m);
  const int column_count = c.deskew ? columns.size() : 1;
  for (int column = 0; column < column_count; ++column) {
    const SensorFrameTest band = height_test(column_motion(column));
    const double nx = band.nx, ny = band.ny, nz = band.nz, d = band.d;
    const double lo = band.lo, hi = band.hi;
    const int end = c.deskew ? columns.end_of(column, n) : n;
    for (int i = c.deskew ? columns[column].first_index : 0; i < end; ++i) {
      const uint8_t flag = flags[static_cast<size_t>(i)];
      if (flag == 0) continue;
      const core::LidarPoint& p = cloud.points[i];
      if (flag & kTame) {
        const double v = nx * p.x + ny * p.y + nz * p.z + d;
        if (v < lo || v > hi) continue;
      }
      const Vector3d vehicle = to_vehicle(mount, p, column_motion(column));
      double h = 0.0;
      if (!raised_band.contains(vehicle, h)) continue;
      // the range from the sensor, only for the points kept
      const double horizontal = horizontal_range(p);
      const double z = p.z;
      const double range = std::sqrt(horizontal * horizontal + z * z);
      raised.push_back(
          {i, (vehicle - h * up).head<2>(), h, range, static_cast<double>(p.intensity), p.ring});
    }
  }
  out.non_ground_points = static_cast<int>(raised.size());

  // clusters, then each one validated, fitted and classified
  const core::ConeGeometry small = core::cone_geometry(ConeClass::kBlue);
  const core::ConeGeometry big = core::cone_geometry(ConeClass::kOrangeBig);
  const double ring_step = std::tan(c.ring_spacing_deg * kDeg);
  const Clusters clusters = euclidean_clusters(raised, c.cluster_distance_m);
  out.cones.reserve(static_cast<size_t>(clusters.size()));
  // buffers kept over the clusters
  std::vector<double> radius;
  PaintScratch paint;
  Clusters pieces;
  // one cluster validated, fitted and classified: a cone in out.cones, or one more rejected
  auto detect_cone = [&](std::span<const int> cluster) {
    // size: point count, extent on the ground, top above the ground
    Vector2d lo = Vector2d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    double top = 0.0, top_range = 0.0;
    int top_ring = 0;
    for (const int i : cluster) {
      lo = lo.cwiseMin(raised[i].foot);
      hi = hi.cwiseMax(raised[i].foot);
      if (raised[i].height_m > top)
        top = raised[i].height_m, top_range = raised[i].range_m, top_ring = raised[i].ring;
    }
    if (static_cast<int>(cluster.size()) < c.min_cluster_points ||
        (hi - lo).norm() > c.max_cluster_extent_m || top < c.min_cone_height_m ||
        top > c.max_cone_height_m) {
      ++out.rejected_clusters;
      return;
    }

    // small or big: a top above a small cone's height is big; a top below it is small when the
    // next ring up would have hit a big cone below its top (else undecided)
    const bool big_by_height = top >= c.big_cone_min_height_m;
    double rise = ring_step;
    const auto& rings = c.ring_elevations_deg;
    if (top_ring >= 0 && static_cast<size_t>(top_ring) + 1 < rings.size())
      rise = std::tan(rings[top_ring + 1] * kDeg) - std::tan(rings[top_ring] * kDeg);
    else if (!rings.empty())
      rise = std::numeric_limits<double>::infinity();  // the top ring: nothing above it
    const double next_ring_height = top + top_range * rise;
    // the ring above would have met any cone standing here, and left nothing: not a cone
    if (next_ring_height < small.height_m - c.ring_above_margin_m) {
      ++out.rejected_clusters;
      return;
    }
    const bool small_by_rings = !big_by_height && next_ring_height < big.height_m - 0.02;
    bool may_be_small = !big_by_height;
    bool may_be_big = !small_by_rings;
    if (may_be_small && may_be_big) {
      // undecided by height: the widths of the rings decide when they are clear enough
      const double lead = width_log_likelihood(c, raised, cluster, small, sensor_xy) -
                          width_log_likelihood(c, raised, cluster, big, sensor_xy);
      if (lead >= c.size_min_log_likelihood_ratio) may_be_big = false;
      if (lead <= -c.size_min_log_likelihood_ratio) may_be_small = false;
    }

    // centre on the small shape unless surely big; class from the paint; refit if it is big
    const bool fitted_big = !may_be_small;
    Vector2d centre = fit_centre(raised, cluster, fitted_big ? big : small, sensor_xy, radius);
    const ConeClass cls = classify_paint(c, raised, cluster, centre, sensor_xy,
                                         hypotheses_for(c, may_be_small, may_be_big), paint);
    if (cls == ConeClass::kOrangeBig && !fitted_big)
      centre = fit_centre(raised, cluster, big, sensor_xy, radius);

    // the cone: its base centre on the plane, in the vehicle and sensor frames
    const Vector3d base(centre.x(), centre.y(),
                        ground.a * centre.x() + ground.b * centre.y() + ground.c);
    LidarCone cone;
    cone.observation.position = base.head<2>();
    cone.observation.cls = cls;
    double mean_tau = 0.0;
    for (const int i : cluster) mean_tau += cloud.points[raised[i].index].time_offset_s;
    mean_tau /= static_cast<double>(cluster.size());
    // de-skew error: a fraction of the motion since the cluster fired, or all of it when off
    const double moved_m = std::abs(motion.speed_mps) * std::max(0.0, frame_s - mean_tau);
    const double deskew_sigma_m = c.deskew ? c.speed_relative_sigma * moved_m : moved_m;
    cone.observation.covariance = covariance_of(c, base.head<2>(), sensor_xy,
                                                static_cast<int>(cluster.size()), deskew_sigma_m);
    cone.centre_sensor = sensor_in_vehicle_.inverse().transform(base);
    cone.height_m = top;
    cone.points = static_cast<int>(cluster.size());
    cone.point_indices.reserve(cluster.size());
    for (const int i : cluster) cone.point_indices.push_back(raised[i].index);
    out.cones.push_back(std::move(cone));
  };
  for (int k = 0; k < clusters.size(); ++k) {
    // cones whose bases touch (a gate's cones in a row) link into one cluster: a cluster too
    // wide for one cone is tried as a row of them, each piece validated as a cone on its own
    if (split_row(raised, clusters[k], c, small, big, sensor_xy, radius, pieces))
      for (int j = 0; j < pieces.size(); ++j) detect_cone(pieces[j]);
    else
      detect_cone(clusters[k]);
  }
  return out;
}

}  // namespace conesim::slam::frontend
