#include "control/skidpad_plan.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <numbers>

namespace conesim::control {

namespace {

using core::ConeClass;
using core::MapCone;

constexpr double kPi = std::numbers::pi;
// nominal half distance between the circle centres (FSG: 18.25 m apart), for the first guess
constexpr double kNominalRadiusM = 9.125;
// inner-ring cones lie between these distances from a centre guess (rule radius 7.475 m;
// the outer ring is at 10.775 m), metres
constexpr double kInnerRingMinM = 5.5;
constexpr double kInnerRingMaxM = 8.8;
// refinement rounds of the circle fits
constexpr int kFitRounds = 3;
// the entry path starts this far behind the start pose, metres
constexpr double kEntryBehindM = 2.0;

// algebraic (Kasa) circle fit of the points near `guess`; returns the guess when too few
Vec2 fit_ring_centre(const std::vector<MapCone>& cones, const Vec2& guess) {
  Vec2 centre = guess;
  for (int round = 0; round < kFitRounds; ++round) {
    // x^2 + y^2 + D x + E y + F = 0 in least squares, points relative to the guess
    Eigen::MatrixXd a(0, 3);
    Eigen::VectorXd b(0);
    std::vector<Vec2> ring;
    for (const MapCone& c : cones) {
      if (c.cls == ConeClass::kOrangeBig) continue;
      const double d = (c.position - centre).norm();
      if (d >= kInnerRingMinM && d <= kInnerRingMaxM) ring.push_back(c.position - centre);
    }
    if (ring.size() < 3) return centre;
    a.resize(static_cast<Eigen::Index>(ring.size()), 3);
    b.resize(static_cast<Eigen::Index>(ring.size()));
    for (size_t i = 0; i < ring.size(); ++i) {
      const auto r = static_cast<Eigen::Index>(i);
      a.row(r) << ring[i].x(), ring[i].y(), 1.0;
      b(r) = -ring[i].squaredNorm();
    }
    const Eigen::Vector3d sol = a.colPivHouseholderQr().solve(b);
    centre += Vec2(-0.5 * sol(0), -0.5 * sol(1));
  }
  return centre;
}

// appends an arc around centre from the angle of `from` through sweep (negative: clockwise)
void append_arc(std::vector<Vec2>& path, const Vec2& centre, const Vec2& from, double radius,
                double sweep, double spacing_m) {
  const Vec2 u = from - centre;
  const double phi0 = std::atan2(u.y(), u.x());
  const int n = std::max(1, static_cast<int>(std::ceil(std::abs(sweep) * radius / spacing_m)));
  for (int i = 1; i <= n; ++i) {
    const double phi = phi0 + sweep * static_cast<double>(i) / n;
    path.push_back(centre + radius * Vec2(std::cos(phi), std::sin(phi)));
  }
}

// appends the straight to b every spacing_m, without its first point
void append_straight(std::vector<Vec2>& path, const Vec2& b, double spacing_m) {
  const Vec2 a = path.back();
  const int n = std::max(1, static_cast<int>(std::ceil((b - a).norm() / spacing_m)));
  for (int i = 1; i <= n; ++i) path.push_back(a + (b - a) * (static_cast<double>(i) / n));
}

}  // namespace

std::optional<SkidpadGeometry> fit_skidpad(const std::vector<MapCone>& prior_map,
                                           const core::Pose2& start) {
  // timing point: centroid of the big orange cones, else of all the other cones
  Vec2 sum_big = Vec2::Zero(), sum_all = Vec2::Zero();
  int n_big = 0, n_all = 0;
  for (const MapCone& c : prior_map) {
    if (c.cls == ConeClass::kOrangeBig) {
      sum_big += c.position;
      ++n_big;
    } else if (c.cls == ConeClass::kBlue || c.cls == ConeClass::kYellow) {
      sum_all += c.position;
      ++n_all;
    }
  }
  if (n_all < 6) return std::nullopt;
  const Vec2 timing_guess = n_big >= 2 ? Vec2(sum_big / n_big) : Vec2(sum_all / n_all);

  // centres: first guesses either side of the driving direction, then ring fits
  const Vec2 h = start.heading();
  const Vec2 left_n(-h.y(), h.x());
  SkidpadGeometry g;
  g.right_centre = fit_ring_centre(prior_map, timing_guess - kNominalRadiusM * left_n);
  g.left_centre = fit_ring_centre(prior_map, timing_guess + kNominalRadiusM * left_n);

  // timing line between the centres, driving direction across it
  g.timing_point = 0.5 * (g.right_centre + g.left_centre);
  g.radius_m = 0.5 * (g.left_centre - g.right_centre).norm();
  const Vec2 across = (g.left_centre - g.right_centre).normalized();
  g.forward = Vec2(across.y(), -across.x());
  if (g.forward.dot(h) < 0.0) g.forward = -g.forward;
  return g;
}

SkidpadPlan plan_skidpad(const SkidpadGeometry& g, const core::Pose2& start, double stop_after_m,
                         double spacing_m) {
  SkidpadPlan plan;
  std::vector<Vec2>& pts = plan.path.points;

  // entry: along the driving direction from behind the start to the timing point
  const double entry_m = (g.timing_point - start.position()).dot(g.forward) + kEntryBehindM;
  pts.push_back(g.timing_point - entry_m * g.forward);
  append_straight(pts, g.timing_point, spacing_m);

  // two clockwise laps on the right, two counter-clockwise on the left, each lap ending at
  // the timing point; then the exit
  std::vector<size_t> lap_end_index;
  for (const auto& [centre, sweep] :
       {std::pair{g.right_centre, -2.0 * kPi}, std::pair{g.right_centre, -2.0 * kPi},
        std::pair{g.left_centre, 2.0 * kPi}, std::pair{g.left_centre, 2.0 * kPi}}) {
    append_arc(pts, centre, g.timing_point, g.radius_m, sweep, spacing_m);
    pts.back() = g.timing_point;
    lap_end_index.push_back(pts.size() - 1);
  }
  append_straight(pts, g.timing_point + stop_after_m * g.forward, spacing_m);

  // lap ends and the stop, by arc length
  const std::vector<double> s = plan.path.arc_lengths();
  for (const size_t i : lap_end_index) plan.lap_end_s.push_back(s[i]);
  plan.stop_s = s.back();
  return plan;
}

}  // namespace conesim::control
