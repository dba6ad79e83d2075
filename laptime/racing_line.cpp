#include "laptime/racing_line.hpp"

#include <Eigen/Sparse>
#include <algorithm>
#include <cmath>
#include <limits>

namespace conesim::laptime {

namespace {

// how far from the line the room to a boundary is searched, metres
constexpr double kMaxRayM = 12.0;
// ADMM penalty, in units of the second-difference Hessian (whose diagonal is 6): small, so that
// the long, gentle modes of the line (eigenvalues ~ (2 pi step / wavelength)^4) converge in a
// few hundred iterations (1: thousands); measured on the shared circuits at 0.5 m steps
constexpr double kAdmmRho = 0.01;

// signed curvature of the circle through three points (0 for collinear ones)
double three_point_curvature(const Vec2& a, const Vec2& b, const Vec2& c) {
  const double ab = (b - a).norm(), bc = (c - b).norm(), ca = (a - c).norm();
  const double denom = ab * bc * ca;
  if (denom < 1e-12) return 0.0;
  return 2.0 * core::cross(b - a, c - b) / denom;
}

// step of the search for the room each side of the line, metres
constexpr double kRoomStepM = 0.02;

// what the line keeps clear of near one point: segments of a boundary, and every cone
struct Obstacles {
  std::vector<std::pair<Vec2, Vec2>> segments;
  std::vector<Vec2> cones;

  double distance(const Vec2& p) const {
    double best = std::numeric_limits<double>::infinity();
    for (const auto& [a, b] : segments) best = std::min(best, core::distance_to_segment(p, a, b));
    for (const Vec2& c : cones) best = std::min(best, (c - p).norm());
    return best;
  }
};

// the boundary's segments and the cones on its side (ahead of p along d) within kMaxRayM of p
Obstacles obstacles_near(const Vec2& p, const Vec2& d, const std::vector<Vec2>& boundary,
                         const std::vector<Vec2>& cones) {
  Obstacles o;
  for (size_t i = 0; i < boundary.size(); ++i) {
    const Vec2& a = boundary[i];
    const Vec2& b = boundary[(i + 1) % boundary.size()];
    if (core::distance_to_segment(p, a, b) < kMaxRayM) o.segments.emplace_back(a, b);
  }
  for (const Vec2& c : cones)
    if ((c - p).squaredNorm() < kMaxRayM * kMaxRayM && (c - p).dot(d) > 0.0) o.cones.push_back(c);
  return o;
}

// how far p may move along d (negative: against it) and stay clearance_m from the closed
// boundary polyline and from every cone: the last step out from p before the clearance would
// break, searched within kMaxRayM
double room_along(const Vec2& p, const Vec2& d, const std::vector<Vec2>& boundary,
                  const std::vector<Vec2>& cones, double clearance_m) {
  const Obstacles o = obstacles_near(p, d, boundary, cones);
  double t = 0.0;
  if (o.distance(p) >= clearance_m) {
    // out towards the boundary until the next step would come too close
    while (t + kRoomStepM < kMaxRayM && o.distance(p + (t + kRoomStepM) * d) >= clearance_m)
      t += kRoomStepM;
  } else {
    // already too close: back away until clear
    while (t > -kMaxRayM && o.distance(p + t * d) < clearance_m) t -= kRoomStepM;
  }
  return t;
}

// left unit normals of a closed line from its central differences
std::vector<Vec2> left_normals(const std::vector<Vec2>& pts) {
  const size_t n = pts.size();
  std::vector<Vec2> normals(n);
  for (size_t i = 0; i < n; ++i) {
    const Vec2 t = (pts[(i + 1) % n] - pts[(i + n - 1) % n]).normalized();
    normals[i] = Vec2(-t.y(), t.x());
  }
  return normals;
}

// one pass: offsets along the normals within [lo, hi] that minimise the sum of squared second
// differences of the closed line (a box-constrained QP; ADMM with the banded factor of
// H + rho I, which carries the long wavelengths that coordinate descent cannot)
std::vector<double> minimum_curvature_offsets(const std::vector<Vec2>& p,
                                              const std::vector<Vec2>& normal,
                                              const std::vector<double>& lo,
                                              const std::vector<double>& hi, int iterations) {
  const int n = static_cast<int>(p.size());
  // second difference k: b_k + n_{k-1} a_{k-1} - 2 n_k a_k + n_{k+1} a_{k+1}
  std::vector<Eigen::Triplet<double>> triplets;
  Eigen::VectorXd g = Eigen::VectorXd::Zero(n);
  for (int k = 0; k < n; ++k) {
    const int idx[3] = {(k + n - 1) % n, k, (k + 1) % n};
    const double w[3] = {1.0, -2.0, 1.0};
    const Vec2 b = p[idx[0]] - 2.0 * p[idx[1]] + p[idx[2]];
    for (int a = 0; a < 3; ++a) {
      g[idx[a]] += w[a] * normal[idx[a]].dot(b);
      for (int c = 0; c < 3; ++c)
        triplets.emplace_back(idx[a], idx[c], w[a] * w[c] * normal[idx[a]].dot(normal[idx[c]]));
    }
  }
  for (int i = 0; i < n; ++i) triplets.emplace_back(i, i, kAdmmRho);
  Eigen::SparseMatrix<double> m(n, n);
  m.setFromTriplets(triplets.begin(), triplets.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(m);
  if (solver.info() != Eigen::Success) return std::vector<double>(n, 0.0);

  // x: the unconstrained step, z: its projection on the box, u: the scaled dual
  Eigen::VectorXd z = Eigen::VectorXd::Zero(n), u = Eigen::VectorXd::Zero(n);
  for (int i = 0; i < n; ++i) z[i] = std::clamp(0.0, lo[i], hi[i]);
  for (int it = 0; it < iterations; ++it) {
    const Eigen::VectorXd x = solver.solve(kAdmmRho * (z - u) - g);
    for (int i = 0; i < n; ++i) z[i] = std::clamp(x[i] + u[i], lo[i], hi[i]);
    u += x - z;
  }
  return {z.data(), z.data() + n};
}

}  // namespace

bool RacingLineParams::is_valid(std::string* error) const {
  std::string e;
  if (!(step_m > 0.05 && step_m <= 5.0)) e = "step_m must be in (0.05, 5] m";
  if (!(clearance_m >= 0.0)) e = "clearance_m must be >= 0";
  if (passes < 1 || iterations < 1) e = "passes and iterations must be at least 1";
  if (error) *error = e;
  return e.empty();
}

RacingLine make_line(const std::vector<Vec2>& points, bool closed, double step_m) {
  RacingLine line;
  line.closed = closed;
  if (points.size() < 2) return line;

  // cumulative length of the polyline (closing segment included for a loop)
  std::vector<Vec2> pts = points;
  if (closed) pts.push_back(points.front());
  std::vector<double> s(pts.size(), 0.0);
  for (size_t i = 1; i < pts.size(); ++i) s[i] = s[i - 1] + (pts[i] - pts[i - 1]).norm();
  const double length = s.back();
  if (length <= 0.0) return line;

  // resampled every ~step_m
  const int segments = std::max(2, static_cast<int>(std::round(length / step_m)));
  const int count = closed ? segments : segments + 1;
  size_t j = 0;
  for (int i = 0; i < count; ++i) {
    const double si = length * i / segments;
    while (j + 2 < s.size() && s[j + 1] < si) ++j;
    const double span = s[j + 1] - s[j];
    const double f = span > 0.0 ? std::clamp((si - s[j]) / span, 0.0, 1.0) : 0.0;
    line.points.push_back(pts[j] + f * (pts[j + 1] - pts[j]));
    line.s_m.push_back(si);
  }
  line.length_m = length;

  // curvature from each point's neighbours (open ends: their neighbour's)
  const size_t n = line.points.size();
  line.curvature.assign(n, 0.0);
  for (size_t i = 0; i < n; ++i) {
    if (!closed && (i == 0 || i + 1 == n)) continue;
    line.curvature[i] = three_point_curvature(line.points[(i + n - 1) % n], line.points[i],
                                              line.points[(i + 1) % n]);
  }
  if (!closed && n >= 3) {
    line.curvature.front() = line.curvature[1];
    line.curvature.back() = line.curvature[n - 2];
  }
  return line;
}

RacingLine minimum_curvature_line(const tracks::Track& track, const RacingLineParams& params) {
  RacingLine line = make_line(track.centre_line, track.closed, params.step_m);
  if (!track.closed || line.points.size() < 10 || track.left_lane.size() < 3 ||
      track.right_lane.size() < 3)
    return line;
  const std::vector<Vec2> left = track.lane_points(track.left_lane);
  const std::vector<Vec2> right = track.lane_points(track.right_lane);
  std::vector<Vec2> cones;
  for (const tracks::Cone& c : track.cones) cones.push_back(c.position);
  // the line runs straight between its points: a cone abreast of the middle of a step is
  // clearance_m away when both ends keep this much
  const double clearance =
      std::sqrt(params.clearance_m * params.clearance_m + 0.25 * params.step_m * params.step_m);

  for (int pass = 0; pass < params.passes; ++pass) {
    // the room each side of the current line, less the clearance
    const std::vector<Vec2> normal = left_normals(line.points);
    const size_t n = line.points.size();
    std::vector<double> lo(n), hi(n);
    for (size_t i = 0; i < n; ++i) {
      hi[i] = room_along(line.points[i], normal[i], left, cones, clearance);
      lo[i] = -room_along(line.points[i], -normal[i], right, cones, clearance);
      if (lo[i] > hi[i]) lo[i] = hi[i] = 0.5 * (lo[i] + hi[i]);
    }

    // move the points and resample
    const std::vector<double> offset =
        minimum_curvature_offsets(line.points, normal, lo, hi, params.iterations);
    std::vector<Vec2> moved(n);
    for (size_t i = 0; i < n; ++i) moved[i] = line.points[i] + offset[i] * normal[i];
    line = make_line(moved, true, params.step_m);
  }
  return line;
}

}  // namespace conesim::laptime
