// The LiDAR cone detector. One pass per sweep:
//   de-skew  -> every point moved to the vehicle frame at the sweep's end,
//   ground   -> a plane fitted to the low points, heights measured from it,
//   clusters -> a grid over the ground-projected points, neighbours linked by distance,
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

// least-squares plane z = a x + b y + c through the points within `tolerance` of `plane`
bool fit_plane(const std::vector<Vector3d>& points, double tolerance, GroundPlane& plane) {
  Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
  Vector3d atb = Vector3d::Zero();
  int used = 0;
  const HeightBand band(plane, -tolerance, tolerance);
  double h = 0.0;
  for (const Vector3d& p : points) {
    if (!band.contains(p, h)) continue;
    const Vector3d row(p.x(), p.y(), 1.0);
    ata += row * row.transpose();
    atb += row * p.z();
    ++used;
  }
  if (used < 20) return false;
  const Vector3d x = ata.ldlt().solve(atb);
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

// clusters of the raised points: points whose feet are within `distance` are linked; clusters
// come out ordered by their first point (the firing order), points in firing order
std::vector<std::vector<int>> euclidean_clusters(const std::vector<RaisedPoint>& points,
                                                 double distance) {
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
  std::vector<std::pair<int64_t, int>> sorted(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    const auto c = cell_of(points[i].foot);
    sorted[static_cast<size_t>(i)] = {key_of(c[0], c[1]), i};
  }
  std::sort(sorted.begin(), sorted.end());

  // the occupied cells: runs of the sorted points
  struct Cell {
    int64_t key, cx, cy;
    size_t begin, end;
  };
  std::vector<Cell> cells;
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
  for (const Cell& cell : cells) {
    for (int64_t dx = 0; dx <= 2; ++dx)
      for (int64_t dy = -2; dy <= 2; ++dy) {
        if (dx == 0 && dy <= 0) continue;  // each pair of cells once
        const int64_t key = key_of(cell.cx + dx, cell.cy + dy);
        const auto other = std::lower_bound(
            cells.begin(), cells.end(), key,
            [](const Cell& c, int64_t k) { return c.key < k; });
        if (other == cells.end() || other->key != key) continue;
        const int a0 = sorted[cell.begin].second, b0 = sorted[other->begin].second;
        if (find_root(parent, a0) == find_root(parent, b0)) continue;
        bool joined = false;
        for (size_t i = cell.begin; i < cell.end && !joined; ++i)
          for (size_t j = other->begin; j < other->end && !joined; ++j)
            if ((points[sorted[i].second].foot - points[sorted[j].second].foot).squaredNorm() <=
                distance2) {
              join(a0, b0);
              joined = true;
            }
      }
  }

  // gather: roots are the smallest index of their cluster, so this order is deterministic
  std::vector<int> cluster_of(static_cast<size_t>(n), -1);
  std::vector<std::vector<int>> clusters;
  for (int i = 0; i < n; ++i) {
    const int root = find_root(parent, i);
    if (cluster_of[root] < 0) {
      cluster_of[root] = static_cast<int>(clusters.size());
      clusters.emplace_back();
    }
    clusters[cluster_of[root]].push_back(i);
  }
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
Vector2d fit_centre(const std::vector<RaisedPoint>& points, const std::vector<int>& cluster,
                    const core::ConeGeometry& shape, const Vector2d& sensor_xy) {
  Vector2d centroid = Vector2d::Zero();
  double mean_radius = 0.0;
  for (const int i : cluster) {
    centroid += points[i].foot;
    mean_radius += body_radius(shape, points[i].height_m);
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
    for (const int i : cluster) {
      const Vector2d d = points[i].foot - c;
      const double norm = d.norm();
      if (norm < 1e-6) continue;
      const Vector2d j = -d / norm;
      const double r = norm - body_radius(shape, points[i].height_m);
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

// Log-likelihood of a shape from the width of each ring's points across the line of sight:
// a ring crossing the body at height h spans its full width 2 r(h), less on average one
// column step (the edge columns fall anywhere within a step of the silhouette), with a
// spread of about half a step plus the model error. Rings with one point say nothing.
double width_log_likelihood(const LidarDetectorConfig& config,
                            const std::vector<RaisedPoint>& points, const std::vector<int>& cluster,
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
std::vector<PaintHypothesis> hypotheses_for(const LidarDetectorConfig& c, bool may_be_small,
                                            bool may_be_big) {
  std::vector<PaintHypothesis> h;
  const core::ConeGeometry small = core::cone_geometry(ConeClass::kBlue);
  if (may_be_small) {
    h.push_back({ConeClass::kBlue, small, c.reflectivity_blue, c.reflectivity_white});
    h.push_back({ConeClass::kYellow, small, c.reflectivity_yellow, c.reflectivity_black});
    h.push_back({ConeClass::kOrangeSmall, small, c.reflectivity_orange, c.reflectivity_white});
  }
  if (may_be_big)
    h.push_back({ConeClass::kOrangeBig, core::cone_geometry(ConeClass::kOrangeBig),
                 c.reflectivity_orange, c.reflectivity_white});
  return h;
}

// The class whose paint pattern explains the intensities best. Each point's expected intensity
// is 255 x reflectivity of the band at its height x cos(incidence) x range fall-off, with the
// incidence from where the point sits on the visible half-circle (the silhouette is grazing)
// and the taper of the body; one free gain per hypothesis absorbs what the model misses. The
// hypotheses are scored by their Gaussian log-likelihood; kUnknown when the best does not lead
// the runner-up by colour_min_log_likelihood_ratio, or too few points are usable.
ConeClass classify_paint(const LidarDetectorConfig& config, const std::vector<RaisedPoint>& points,
                         const std::vector<int>& cluster, const Vector2d& centre,
                         const Vector2d& sensor_xy,
                         const std::vector<PaintHypothesis>& hypotheses) {
  if (hypotheses.empty()) return ConeClass::kUnknown;
  if (hypotheses.size() == 1) return hypotheses.front().cls;
  const Vector2d ray = (centre - sensor_xy).normalized();
  const Vector2d across(-ray.y(), ray.x());

  // mean log-likelihood per usable point of each hypothesis (shapes differ in the points they
  // can use), scaled below by the fewest usable points
  std::vector<double> mean_log_likelihood;
  size_t fewest_used = cluster.size();
  // the usable points of a shape, with the band each may be on and its expected intensity per
  // unit reflectivity; hypotheses of one shape (the small ones) share them
  struct Seen {
    double measured, scale, p_other;
    bool stripe_here, stripe_other;
  };
  std::vector<Seen> seen;
  const core::ConeBand* seen_shape = nullptr;
  struct Expected {
    double measured, here, other, p_other;
  };
  std::vector<Expected> used;
  for (const PaintHypothesis& h : hypotheses) {
    if (h.shape.bands.data() != seen_shape) {
      seen_shape = h.shape.bands.data();
      seen.clear();
      const double taper =
          std::atan2(h.shape.bands.front().radius_bottom_m - h.shape.bands.back().radius_top_m,
                     h.shape.height_m - h.shape.plate_height_m);
      for (const int i : cluster) {
        const RaisedPoint& p = points[i];
        if (p.height_m > h.shape.height_m + 0.02) continue;
        const double radius = body_radius(h.shape, p.height_m);
        const double u = (p.foot - centre).dot(across) / radius;
        if (std::abs(u) > 0.85) continue;
        const BandChance band = band_chance(h.shape, p.height_m, config.height_sigma_m);
        const double falloff = 1.0 / (1.0 + std::pow(p.range_m / config.intensity_falloff_m, 2));
        const double scale = 255.0 * std::sqrt(1.0 - u * u) * std::cos(taper) * falloff;
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
    mean_log_likelihood.push_back(log_likelihood / static_cast<double>(used.size()));
    fewest_used = std::min(fewest_used, used.size());
  }
  double best = -std::numeric_limits<double>::infinity(), second = best;
  ConeClass best_cls = ConeClass::kUnknown;
  for (size_t k = 0; k < hypotheses.size(); ++k) {
    const double log_likelihood = mean_log_likelihood[k] * static_cast<double>(fewest_used);
    if (log_likelihood > best) {
      second = best;
      best = log_likelihood;
      best_cls = hypotheses[k].cls;
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
  non_negative("min_cone_height_m", min_cone_height_m);
  if (e.tellp() == 0 && max_cone_height_m <= min_cone_height_m)
    e << "max_cone_height_m: expected > min_cone_height_m, got " << max_cone_height_m;
  positive("big_cone_min_height_m", big_cone_min_height_m);
  positive("ring_spacing_deg", ring_spacing_deg);
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
  const LidarDetectorConfig& c = config_;
  LidarDetections out;
  out.stamp = cloud.stamp + core::from_seconds(c.sweep_period_s);
  const int n = static_cast<int>(cloud.points.size());

  // de-skew: a point fired at tau is in the vehicle frame of tau; the vehicle at the sweep end
  // is arc_motion(T - tau) ahead of it, so the point moves by that motion's inverse (columns
  // share tau, so the motion is computed once per column)
  std::vector<Vector3d> vehicle(static_cast<size_t>(n));
  // within the sensor's horizontal range window (the others are skipped)
  std::vector<uint8_t> in_range(static_cast<size_t>(n), 0);
  const RangeWindow window(c.min_range_m, c.max_range_m);
  float last_tau = std::numeric_limits<float>::quiet_NaN();
  core::Pose2 back;
  double back_cos = 1.0, back_sin = 0.0;
  for (int i = 0; i < n; ++i) {
    const core::LidarPoint& p = cloud.points[i];
    if (!window.contains(p)) continue;
    in_range[i] = 1;
    const Vector3d v = sensor_in_vehicle_.transform(Vector3d(p.x, p.y, p.z));
    if (!c.deskew) {
      vehicle[i] = v;
      continue;
    }
    if (p.time_offset_s != last_tau) {
      last_tau = p.time_offset_s;
      back = arc_motion(motion, c.sweep_period_s - p.time_offset_s);
      back_cos = std::cos(back.yaw);
      back_sin = std::sin(back.yaw);
    }
    // back.inverse_transform(v.head<2>()), with the column's cosine and sine
    const double dx = v.x() - back.x, dy = v.y() - back.y;
    vehicle[i] = Vector3d(back_cos * dx + back_sin * dy, -back_sin * dx + back_cos * dy, v.z());
  }

  // ground: candidates near z = 0 of the vehicle frame, then two refits on the inliers. Three
  // parameters need no more than a few thousand points: every k-th candidate is kept
  std::vector<Vector3d> candidates;
  candidates.reserve(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i)
    if (in_range[i] && std::abs(vehicle[i].z()) < c.ground_candidate_band_m)
      candidates.push_back(vehicle[i]);
  constexpr size_t kGroundFitPoints = 4000;
  if (candidates.size() > 2 * kGroundFitPoints) {
    const size_t stride = candidates.size() / kGroundFitPoints;
    size_t kept = 0;
    for (size_t i = 0; i < candidates.size(); i += stride) candidates[kept++] = candidates[i];
    candidates.resize(kept);
  }
  GroundPlane ground;
  if (fit_plane(candidates, c.ground_candidate_band_m, ground)) {
    GroundPlane refit = ground;
    if (fit_plane(candidates, 2.0 * c.ground_inlier_m, refit)) ground = refit;
    refit = ground;
    if (fit_plane(candidates, c.ground_inlier_m, refit)) ground = refit;
  }
  const Vector3d up = ground.normal();

  // raised points: heights along the plane's normal, feet on the plane
  const Vector3d sensor = sensor_in_vehicle_.position;
  const Vector2d sensor_xy = (sensor - ground.height(sensor) * up).head<2>();
  std::vector<RaisedPoint> raised;
  const HeightBand raised_band(ground, c.min_point_height_m, c.max_point_height_m);
  for (int i = 0; i < n; ++i) {
    if (!in_range[i]) continue;
    double h = 0.0;
    if (!raised_band.contains(vehicle[i], h)) continue;
    // the range from the sensor, only for the points kept
    const double horizontal = horizontal_range(cloud.points[i]);
    const double z = cloud.points[i].z;
    const double range = std::sqrt(horizontal * horizontal + z * z);
    raised.push_back({i, (vehicle[i] - h * up).head<2>(), h, range,
                      static_cast<double>(cloud.points[i].intensity), cloud.points[i].ring});
  }
  out.non_ground_points = static_cast<int>(raised.size());

  // clusters, then each one validated, fitted and classified
  const core::ConeGeometry small = core::cone_geometry(ConeClass::kBlue);
  const core::ConeGeometry big = core::cone_geometry(ConeClass::kOrangeBig);
  const double ring_step = std::tan(c.ring_spacing_deg * kDeg);
  for (const std::vector<int>& cluster : euclidean_clusters(raised, c.cluster_distance_m)) {
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
      continue;
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
    Vector2d centre = fit_centre(raised, cluster, fitted_big ? big : small, sensor_xy);
    const ConeClass cls = classify_paint(c, raised, cluster, centre, sensor_xy,
                                         hypotheses_for(c, may_be_small, may_be_big));
    if (cls == ConeClass::kOrangeBig && !fitted_big)
      centre = fit_centre(raised, cluster, big, sensor_xy);

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
    const double moved_m = std::abs(motion.speed_mps) * std::max(0.0, c.sweep_period_s - mean_tau);
    const double deskew_sigma_m = c.deskew ? c.speed_relative_sigma * moved_m : moved_m;
    cone.observation.covariance = covariance_of(c, base.head<2>(), sensor_xy,
                                                static_cast<int>(cluster.size()), deskew_sigma_m);
    cone.centre_sensor = sensor_in_vehicle_.inverse().transform(base);
    cone.height_m = top;
    cone.points = static_cast<int>(cluster.size());
    cone.point_indices.reserve(cluster.size());
    for (const int i : cluster) cone.point_indices.push_back(raised[i].index);
    out.cones.push_back(std::move(cone));
  }
  return out;
}

}  // namespace conesim::slam::frontend
