#include "sim/big_layouts.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <unordered_map>

#include "core/rng.hpp"
#include "tracks/generator.hpp"
#include "tracks/spatial_index.hpp"

namespace conesim::sim {

namespace {

using core::ConeClass;
using core::Vec2;

constexpr ConeClass kClasses[] = {ConeClass::kBlue, ConeClass::kYellow, ConeClass::kOrangeSmall,
                                  ConeClass::kOrangeBig, ConeClass::kUnknown};

// cones never closer than this to one another in the made layouts (no base overlaps), metres
constexpr double kMinGapM = 0.5;

// a grid of the cones placed so far, to keep new ones apart from them
class Occupancy {
 public:
  bool free(const Vec2& p) const {
    const int64_t cx = cell(p.x()), cy = cell(p.y());
    for (int64_t dx = -1; dx <= 1; ++dx)
      for (int64_t dy = -1; dy <= 1; ++dy)
        if (const auto it = cells_.find(key(cx + dx, cy + dy)); it != cells_.end())
          for (const Vec2& q : it->second)
            if ((q - p).norm() < kMinGapM) return false;
    return true;
  }
  void add(const Vec2& p) { cells_[key(cell(p.x()), cell(p.y()))].push_back(p); }

 private:
  static int64_t cell(double v) { return static_cast<int64_t>(std::floor(v / kMinGapM)); }
  static uint64_t key(int64_t x, int64_t y) {
    return (static_cast<uint64_t>(x) << 32) ^ static_cast<uint32_t>(y);
  }
  std::unordered_map<uint64_t, std::vector<Vec2>> cells_;
};

void add_cone(tracks::Track& t, ConeClass cls, const Vec2& p) {
  t.cones.push_back({static_cast<int>(t.cones.size()), cls, p, std::nullopt});
}

// a generated circuit with scattered cones around it, off its lanes
tracks::Track clutter(int cones, uint64_t seed) {
  tracks::Track t = tracks::generate_circuit(seed);
  t.name = "clutter-" + std::to_string(cones);
  Occupancy occupied;
  Vec2 lo = t.cones.front().position, hi = lo;
  for (const tracks::Cone& c : t.cones) {
    occupied.add(c.position);
    lo = lo.cwiseMin(c.position);
    hi = hi.cwiseMax(c.position);
  }
  const tracks::PolylineIndex left(t.lane_points(t.left_lane), true);
  const tracks::PolylineIndex right(t.lane_points(t.right_lane), true);
  // the field: the circuit's box with a margin, grown with the count (about 1 cone per 100 m^2)
  const double side = std::sqrt(std::max(0.0, static_cast<double>(cones)) * 100.0);
  const Vec2 centre = 0.5 * (lo + hi);
  const Vec2 half = (0.5 * (hi - lo)).cwiseMax(Vec2(0.5 * side, 0.5 * side)) + Vec2(20.0, 20.0);
  core::Rng rng(seed * 7919 + 17);
  int guard = 0;
  while (static_cast<int>(t.cones.size()) < cones && ++guard < 50 * cones) {
    // one draw a statement (argument order is the compiler's; this is gcc's)
    const double y = core::uniform(rng, centre.y() - half.y(), centre.y() + half.y());
    const Vec2 p(core::uniform(rng, centre.x() - half.x(), centre.x() + half.x()), y);
    const ConeClass cls = kClasses[rng() % 5];
    if (left.nearest(p).distance2 < 9.0 || right.nearest(p).distance2 < 9.0) continue;
    if (!occupied.free(p)) continue;
    occupied.add(p);
    add_cone(t, cls, p);
  }
  return t;
}

// how far the outlier lies from the rest, along x and along y, metres (a row in UTM among
// local coordinates, within the readers' bound of 1e7 m)
constexpr double kOutlierM = 1e6;

// a long winding circuit: a circle with a wave on its radius, lanes 3.5 m apart
tracks::Track long_circuit(int cones, uint64_t seed) {
  tracks::Track t;
  t.name = "long-" + std::to_string(cones);
  t.closed = true;
  t.event = core::EventType::kTrackdrive;
  const int per_lane = std::max(20, cones / 2);
  const double spacing_m = 1.8;
  const double length_m = per_lane * spacing_m;
  const double radius_m = length_m / (2.0 * std::numbers::pi);
  core::Rng rng(seed);
  const int waves = 8 + static_cast<int>(rng() % 8);
  const double amplitude_m = std::min(0.05 * radius_m, 40.0);
  // the centre line, sampled densely, then cones every spacing_m along it on both sides
  const int samples = per_lane * 8;
  std::vector<Vec2> centre;
  for (int i = 0; i < samples; ++i) {
    const double a = 2.0 * std::numbers::pi * i / samples;
    const double r = radius_m + amplitude_m * std::sin(waves * a);
    centre.emplace_back(r * std::cos(a), r * std::sin(a));
  }
  double s = 0.0, next = 0.0;
  for (int i = 0; i < samples; ++i) {
    const Vec2 a = centre[i], b = centre[(i + 1) % samples];
    const double len = (b - a).norm();
    while (next <= s + len && static_cast<int>(t.left_lane.size()) < per_lane) {
      const Vec2 p = a + (b - a) * ((next - s) / len);
      const Vec2 d = (b - a) / len;
      const Vec2 left(-d.y(), d.x());
      t.left_lane.push_back(static_cast<int>(t.cones.size()));
      add_cone(t, ConeClass::kBlue, p + 1.75 * left);
      t.right_lane.push_back(static_cast<int>(t.cones.size()));
      add_cone(t, ConeClass::kYellow, p - 1.75 * left);
      next += spacing_m;
    }
    s += len;
  }
  const Vec2 d = (centre[1] - centre[0]).normalized();
  t.start = {centre[0].x() - 6.0 * d.x(), centre[0].y() - 6.0 * d.y(), std::atan2(d.y(), d.x())};
  t.centre_line = tracks::derive_centre_line(t);
  return t;
}

// cones of random classes strewn uniformly
tracks::Track random_cones(int cones, uint64_t seed) {
  tracks::Track t;
  t.name = "random-" + std::to_string(cones);
  const double side = std::sqrt(std::max(1, cones) * 25.0);
  core::Rng rng(seed);
  Occupancy occupied;
  int guard = 0;
  while (static_cast<int>(t.cones.size()) < cones && ++guard < 50 * cones) {
    const double y = core::uniform(rng, 0.0, side);  // before x: gcc's argument order
    const Vec2 p(core::uniform(rng, 0.0, side), y);
    const ConeClass cls = kClasses[rng() % 5];
    if (!occupied.free(p)) continue;
    occupied.add(p);
    add_cone(t, cls, p);
  }
  return t;
}

// the long circuit and one cone far from it
tracks::Track with_outlier(int cones, uint64_t seed) {
  tracks::Track t = long_circuit(std::max(1, cones - 1), seed);
  t.name = "outlier-" + std::to_string(cones);
  Vec2 hi = t.cones.front().position;
  for (const tracks::Cone& c : t.cones) hi = hi.cwiseMax(c.position);
  add_cone(t, ConeClass::kUnknown, hi + Vec2(kOutlierM, kOutlierM));
  return t;
}

}  // namespace

const char* to_string(BigLayout kind) {
  switch (kind) {
    case BigLayout::kClutter:
      return "clutter";
    case BigLayout::kLong:
      return "long";
    case BigLayout::kRandom:
      return "random";
    case BigLayout::kOutlier:
      return "outlier";
  }
  return "?";
}

tracks::Track big_layout(BigLayout kind, int cones, uint64_t seed) {
  switch (kind) {
    case BigLayout::kClutter:
      return clutter(cones, seed);
    case BigLayout::kLong:
      return long_circuit(cones, seed);
    case BigLayout::kRandom:
      return random_cones(cones, seed);
    case BigLayout::kOutlier:
      return with_outlier(cones, seed);
  }
  return {};
}

}  // namespace conesim::sim
