#include "tracks/ground.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

#include "core/rng.hpp"
#include "core/validate.hpp"

namespace conesim::tracks {

namespace {

// the ground's own random stream (sim/sensor_rig.cpp's are 101, 102; faults 301; scenery 401)
constexpr uint64_t kGroundStream = 501;
// the grid reaches this far beyond the cones, the driving line and the start: past the scenery
// (margin plus spread) and as far as the LiDAR's ground returns matter, metres
constexpr double kGridMarginM = 40.0;
// the grid's cell without bumps, and the most vertices it may hold
constexpr double kCoarseCellM = 0.5;
constexpr double kMaxVertices = 4.0e6;
// the crown: rounded over this half width about the driving line, falling out to this distance
constexpr double kCrownRoundM = 1.5;
constexpr double kCrownEndM = 8.0;
constexpr int kUndulationWaves = 3;

// the crown's drop per unit cross fall at a distance from the driving line
double crown_drop(double d) {
  if (d < kCrownRoundM) return d * d / (2.0 * kCrownRoundM);
  return std::min(d, kCrownEndM) - 0.5 * kCrownRoundM;
}

// distance from p to the segment ab
double segment_distance(const Vec2& p, const Vec2& a, const Vec2& b) {
  const Vec2 ab = b - a;
  const double squared = ab.squaredNorm();
  const double t = squared > 0.0 ? std::clamp((p - a).dot(ab) / squared, 0.0, 1.0) : 0.0;
  return (p - a - t * ab).norm();
}

}  // namespace

bool GroundConfig::flat() const {
  return grade_percent == 0.0 && crown_percent == 0.0 && undulation_amplitude_m == 0.0 &&
         (bump_height_m == 0.0 || bumps_per_100m2 == 0.0);
}

std::string GroundConfig::validate() const {
  if (std::string e = core::check_range("grade_percent", grade_percent, 0.0, 5.0); !e.empty())
    return e;
  if (grade_heading_deg)
    if (std::string e = core::check_range("grade_heading_deg", *grade_heading_deg, -360.0, 360.0);
        !e.empty())
      return e;
  if (std::string e = core::check_range("crown_percent", crown_percent, 0.0, 5.0); !e.empty())
    return e;
  if (std::string e = core::check_range("undulation_amplitude_m", undulation_amplitude_m, 0.0, 0.5);
      !e.empty())
    return e;
  if (std::string e =
          core::check_range("undulation_wavelength_m", undulation_wavelength_m, 10.0, 200.0);
      !e.empty())
    return e;
  if (std::string e = core::check_range("bump_height_m", bump_height_m, 0.0, 0.1); !e.empty())
    return e;
  if (std::string e = core::check_range("bump_radius_m", bump_radius_m, 0.2, 2.0); !e.empty())
    return e;
  return core::check_range("bumps_per_100m2", bumps_per_100m2, 0.0, 10.0);
}

GroundModel::GroundModel(const Track& track, const GroundConfig& config, uint64_t scenario_seed) {
  if (const std::string e = config.validate(); !e.empty())
    throw std::invalid_argument("world.ground." + e);
  if (config.flat()) return;
  core::Rng rng(
      core::derive_seed(core::derive_seed(scenario_seed, kGroundStream), config.seed_offset));

  // the driving line (for the crown) and the extent: the cones, the line and the start
  std::vector<Vec2> line = track.centre_line;
  if (line.size() < 2) line = derive_centre_line(track);
  if (track.closed && line.size() >= 2) line.push_back(line.front());
  const Vec2 start = track.start.position();
  Vec2 lo = start, hi = start;
  for (const Cone& cone : track.cones) {
    lo = lo.cwiseMin(cone.position);
    hi = hi.cwiseMax(cone.position);
  }
  for (const Vec2& p : line) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  lo.array() -= kGridMarginM;
  hi.array() += kGridMarginM;

  // the grid: fine enough for four cells across a bump, within the vertex budget
  GroundGrid& g = grid_;
  const bool bumps = config.bump_height_m > 0.0 && config.bumps_per_100m2 > 0.0;
  g.cell_m = bumps ? std::clamp(0.5 * config.bump_radius_m, 0.1, kCoarseCellM) : kCoarseCellM;
  const Vec2 span = hi - lo;
  while ((span.x() / g.cell_m + 2.0) * (span.y() / g.cell_m + 2.0) > kMaxVertices) g.cell_m *= 1.25;
  g.nx = static_cast<int>(std::ceil(span.x() / g.cell_m)) + 1;
  g.ny = static_cast<int>(std::ceil(span.y() / g.cell_m)) + 1;
  g.x0 = lo.x();
  g.y0 = lo.y();
  std::vector<double> z(static_cast<size_t>(g.nx) * g.ny, 0.0);
  const auto vertex = [&g](int i, int j) { return Vec2(g.x0 + i * g.cell_m, g.y0 + j * g.cell_m); };

  // the draws, always in this order: the grade's heading, the waves, the bumps
  const double drawn_heading = core::uniform(rng, 0.0, 2.0 * std::numbers::pi);
  const double heading = config.grade_heading_deg
                             ? *config.grade_heading_deg * std::numbers::pi / 180.0
                             : drawn_heading;
  struct Wave {
    Vec2 k;
    double phase;
  };
  std::vector<Wave> waves;
  for (int w = 0; w < kUndulationWaves; ++w) {
    const double a = core::uniform(rng, 0.0, 2.0 * std::numbers::pi);
    const double length = config.undulation_wavelength_m * core::uniform(rng, 0.7, 1.4);
    const double phase = core::uniform(rng, 0.0, 2.0 * std::numbers::pi);
    waves.push_back({2.0 * std::numbers::pi / length * Vec2(std::cos(a), std::sin(a)), phase});
  }

  // the grade (zero at the start) and the undulations
  const Vec2 rise = 0.01 * config.grade_percent * Vec2(std::cos(heading), std::sin(heading));
  const double wave_amplitude = config.undulation_amplitude_m / kUndulationWaves;
  for (int j = 0; j < g.ny; ++j)
    for (int i = 0; i < g.nx; ++i) {
      const Vec2 p = vertex(i, j);
      double h = rise.dot(p - start);
      if (wave_amplitude > 0.0)
        for (const Wave& w : waves) h += wave_amplitude * std::sin(w.k.dot(p - start) + w.phase);
      z[static_cast<size_t>(j) * g.nx + i] = h;
    }

  // the crown: each vertex's distance to the driving line, out to where the crown ends
  if (config.crown_percent > 0.0 && line.size() >= 2) {
    std::vector<double> d(z.size(), kCrownEndM);
    for (size_t s = 0; s + 1 < line.size(); ++s) {
      const Vec2 a = line[s], b = line[s + 1];
      const Vec2 l = a.cwiseMin(b).array() - kCrownEndM, h = a.cwiseMax(b).array() + kCrownEndM;
      const int i0 = std::max(0, static_cast<int>(std::floor((l.x() - g.x0) / g.cell_m)));
      const int j0 = std::max(0, static_cast<int>(std::floor((l.y() - g.y0) / g.cell_m)));
      const int i1 = std::min(g.nx - 1, static_cast<int>(std::ceil((h.x() - g.x0) / g.cell_m)));
      const int j1 = std::min(g.ny - 1, static_cast<int>(std::ceil((h.y() - g.y0) / g.cell_m)));
      for (int j = j0; j <= j1; ++j)
        for (int i = i0; i <= i1; ++i) {
          double& best = d[static_cast<size_t>(j) * g.nx + i];
          best = std::min(best, segment_distance(vertex(i, j), a, b));
        }
    }
    for (size_t k = 0; k < z.size(); ++k) z[k] -= 0.01 * config.crown_percent * crown_drop(d[k]);
  }

  // the bumps, anywhere on the grid
  if (bumps) {
    const int count =
        static_cast<int>(std::round(config.bumps_per_100m2 * span.x() * span.y() / 100.0));
    const double r = config.bump_radius_m;
    for (int b = 0; b < count; ++b) {
      const Vec2 c(core::uniform(rng, lo.x(), hi.x()), core::uniform(rng, lo.y(), hi.y()));
      const double height = config.bump_height_m * core::uniform(rng, 0.5, 1.0);
      const int i0 = std::max(0, static_cast<int>(std::floor((c.x() - r - g.x0) / g.cell_m)));
      const int j0 = std::max(0, static_cast<int>(std::floor((c.y() - r - g.y0) / g.cell_m)));
      const int i1 = std::min(g.nx - 1, static_cast<int>(std::ceil((c.x() + r - g.x0) / g.cell_m)));
      const int j1 = std::min(g.ny - 1, static_cast<int>(std::ceil((c.y() + r - g.y0) / g.cell_m)));
      for (int j = j0; j <= j1; ++j)
        for (int i = i0; i <= i1; ++i) {
          const double rho = (vertex(i, j) - c).norm();
          if (rho >= r) continue;
          const double s = std::cos(0.5 * std::numbers::pi * rho / r);
          z[static_cast<size_t>(j) * g.nx + i] += height * s * s;
        }
    }
  }

  // single precision, as the meshes hold it, its range, and its range about the grade's plane
  g.z.assign(z.begin(), z.end());
  const auto [lowest, highest] = std::minmax_element(g.z.begin(), g.z.end());
  g.min_z = *lowest;
  g.max_z = *highest;
  g.slope = rise;
  g.plane_z0 = -rise.dot(start);
  g.residual_min = std::numeric_limits<double>::infinity();
  g.residual_max = -g.residual_min;
  for (int j = 0; j < g.ny; ++j)
    for (int i = 0; i < g.nx; ++i) {
      const double r = g.at(i, j) - (rise.dot(vertex(i, j)) + g.plane_z0);
      g.residual_min = std::min(g.residual_min, r);
      g.residual_max = std::max(g.residual_max, r);
    }
}

double GroundModel::height(double x, double y) const {
  if (flat()) return 0.0;
  const GroundGrid& g = grid_;

  // the cell and the place in it (beyond the grid: its edge)
  const double u = std::clamp((x - g.x0) / g.cell_m, 0.0, g.nx - 1.0);
  const double v = std::clamp((y - g.y0) / g.cell_m, 0.0, g.ny - 1.0);
  const int i = std::min(static_cast<int>(u), g.nx - 2);
  const int j = std::min(static_cast<int>(v), g.ny - 2);
  const double fu = u - i, fv = v - j;

  // the triangle either side of the diagonal from (i, j) to (i + 1, j + 1)
  const double z00 = g.at(i, j), z11 = g.at(i + 1, j + 1);
  if (fu >= fv) return z00 + fu * (g.at(i + 1, j) - z00) + fv * (z11 - g.at(i + 1, j));
  return z00 + fv * (g.at(i, j + 1) - z00) + fu * (z11 - g.at(i, j + 1));
}

Eigen::Vector3d GroundModel::normal(double x, double y) const {
  if (flat()) return Eigen::Vector3d::UnitZ();
  const GroundGrid& g = grid_;
  const double u = std::clamp((x - g.x0) / g.cell_m, 0.0, g.nx - 1.0);
  const double v = std::clamp((y - g.y0) / g.cell_m, 0.0, g.ny - 1.0);
  const int i = std::min(static_cast<int>(u), g.nx - 2);
  const int j = std::min(static_cast<int>(v), g.ny - 2);

  // the slopes of the triangle under the point
  const double z00 = g.at(i, j), z11 = g.at(i + 1, j + 1);
  double dzdu = 0.0, dzdv = 0.0;
  if (u - i >= v - j) {
    dzdu = g.at(i + 1, j) - z00;
    dzdv = z11 - g.at(i + 1, j);
  } else {
    dzdv = g.at(i, j + 1) - z00;
    dzdu = z11 - g.at(i, j + 1);
  }
  return Eigen::Vector3d(-dzdu / g.cell_m, -dzdv / g.cell_m, 1.0).normalized();
}

}  // namespace conesim::tracks
