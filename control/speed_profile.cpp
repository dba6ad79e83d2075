#include "control/speed_profile.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace conesim::control {

namespace {

// curvature below this counts as straight (avoids dividing by zero)
constexpr double kMinCurvature = 1e-4;
// a turn tighter than this share of the steering's limit is driven at the tight-turn speed
constexpr double kTightTurnShare = 0.75;
// on a closed path (the fast laps' racing line) the tight-turn speed holds from this far before
// a tight stretch: the car turns in before the line's tightest point (the tracker previews the
// curvature, the steering winds up at 2.5 rad/s), and arriving faster than the tight-turn speed
// at full lock sends the front corner into the outer cones of a minimum hairpin. Measured on 100
// generated hard-profile trackdrives (`track corpus --count 200 --seed 7000 --event
// autocross,trackdrive`, ground truth): without a lead 10 failed, with 1.5 m on every path 5
// (1.0 and 2.0 m each left one of four fast-lap hits that 1.5 m removed). Not on the
// exploration's paths, replanned each tick from the cones in view: there the lead cost 3 cone
// hits in the 84 GraphSLAM runs over the shared corpus (lap 1 of FSE24, FSG; none without it)
constexpr double kTightTurnLeadM = 1.5;
// the curvature's rate of change along a path is taken over this far either side of a point, m
constexpr double kCurvatureRateSpanM = 1.0;
// the longitudinal share never drops below this fraction of the limit, so that a car at the
// lateral limit can still brake and speed up a little
constexpr double kMinLongitudinalShare = 0.2;

// longitudinal acceleration left at speed v on curvature k (friction ellipse)
double longitudinal_room(double limit, double v, double k, double a_lat_max) {
  const double used = std::min(1.0, v * v * std::abs(k) / a_lat_max);
  return limit * std::max(kMinLongitudinalShare, std::sqrt(1.0 - used * used));
}

}  // namespace

double SpeedLimits::lateral_mps2(double v) const {
  if (!envelope) return max_lateral_accel_mps2;
  return std::min(max_lateral_accel_mps2, lateral_share * envelope->lateral_limit_mps2(v));
}

double SpeedLimits::accel_mps2(double v) const {
  if (!envelope) return max_accel_mps2;
  return std::clamp(envelope->accel_limit_mps2(v), 0.0, max_accel_mps2);
}

double SpeedLimits::decel_mps2(double v) const {
  if (!envelope) return max_decel_mps2;
  return std::min(max_decel_mps2, envelope->decel_limit_mps2(v));
}

double SpeedLimits::braking_mps2(double v, double k) const {
  return longitudinal_room(decel_mps2(v), v, k, lateral_mps2(v));
}

double SpeedLimits::corner_speed_mps(double k) const {
  const double curvature = std::max(kMinCurvature, std::abs(k));
  // near full lock: the tight-turn speed
  if (max_curvature > 0.0 && curvature >= kTightTurnShare * max_curvature) {
    SpeedLimits unlimited = *this;
    unlimited.max_curvature = 0.0;
    return std::min(tight_turn_speed_mps, unlimited.corner_speed_mps(k));
  }
  if (!envelope) return std::min(max_speed_mps, std::sqrt(max_lateral_accel_mps2 / curvature));
  // v^2 k = lateral(v): bisection, since lateral(v) / v^2 falls with speed
  double lo = 0.0, hi = max_speed_mps;
  if (hi * hi * curvature <= lateral_mps2(hi)) return hi;
  for (int i = 0; i < 50; ++i) {
    const double mid = 0.5 * (lo + hi);
    (mid * mid * curvature <= lateral_mps2(mid) ? lo : hi) = mid;
  }
  return lo;
}

double SpeedProfile::speed_at(double s, double lap_m) const {
  if (s_m.empty()) return 0.0;
  if (lap_m > 0.0) {
    s = std::fmod(s, lap_m);
    if (s < 0.0) s += lap_m;
  }
  // the point after s, interpolated with the one before (the lap end wraps to the start)
  const auto it = std::upper_bound(s_m.begin(), s_m.end(), s);
  if (it == s_m.begin()) return speed_mps.front();
  const size_t i1 = static_cast<size_t>(it - s_m.begin());
  const size_t i0 = i1 - 1;
  if (i1 == s_m.size()) {
    if (lap_m <= 0.0) return speed_mps.back();
    const double span = lap_m - s_m[i0];
    const double f = span > 0.0 ? (s - s_m[i0]) / span : 0.0;
    return speed_mps[i0] + f * (speed_mps.front() - speed_mps[i0]);
  }
  const double span = s_m[i1] - s_m[i0];
  const double f = span > 0.0 ? (s - s_m[i0]) / span : 0.0;
  return speed_mps[i0] + f * (speed_mps[i1] - speed_mps[i0]);
}

SpeedProfile plan_speed(const Path& path, const SpeedLimits& limits,
                        std::optional<double> start_speed_mps, std::optional<double> end_speed_mps,
                        const std::vector<double>& point_cap_mps) {
  SpeedProfile profile;
  const size_t n = path.points.size();
  if (n == 0) return profile;
  std::vector<double> s = path.arc_lengths();
  const double lap = path.closed ? s.back() : 0.0;
  s.resize(n);
  profile.s_m = s;

  // lateral limit from the curvature
  const std::vector<double> k = curvatures(path.points, path.closed);
  std::vector<double> v(n);
  for (size_t i = 0; i < n; ++i) v[i] = limits.corner_speed_mps(k[i]);
  // the tight-turn speed from kTightTurnLeadM before each point where it applies (closed paths)
  if (limits.max_curvature > 0.0 && path.closed) {
    const double tight_k = kTightTurnShare * limits.max_curvature;
    double since = std::numeric_limits<double>::infinity();  // arc length to the next tight point
    const size_t rounds_back = path.closed ? 2 : 1;
    for (size_t r = 0; r < rounds_back; ++r)
      for (size_t m = n; m-- > 0;) {
        if (std::abs(k[m]) >= tight_k) {
          since = 0.0;
          continue;
        }
        const size_t next = (m + 1) % n;
        if (next == 0 && !path.closed) continue;
        since += next == 0 ? lap - s[m] : s[next] - s[m];
        if (since <= kTightTurnLeadM) v[m] = std::min(v[m], limits.tight_turn_speed_mps);
      }
  }
  // the steering's rate: the curvature changes over kCurvatureRateSpanM either side of a point
  if (limits.max_curvature_rate_per_s > 0.0 && n > 2) {
    // the length from point m to the one before and to the one after (round the lap's end)
    auto step_back = [&](size_t m) { return m == 0 ? lap - s[n - 1] : s[m] - s[m - 1]; };
    auto step_ahead = [&](size_t m) { return m + 1 == n ? lap - s[m] : s[m + 1] - s[m]; };
    for (size_t i = 0; i < n; ++i) {
      // the points about kCurvatureRateSpanM before and after (not past an open path's ends)
      size_t before = i, after = i;
      double back = 0.0, ahead = 0.0;
      while (back < kCurvatureRateSpanM && (path.closed || before > 0)) {
        back += step_back(before);
        before = before == 0 ? n - 1 : before - 1;
        if (before == i) break;
      }
      while (ahead < kCurvatureRateSpanM && (path.closed || after + 1 < n)) {
        ahead += step_ahead(after);
        after = (after + 1) % n;
        if (after == i) break;
      }
      const double span = back + ahead;
      if (!(span > 0.0)) continue;
      const double change = std::abs(k[after] - k[before]) / span;  // 1/m per metre
      if (change > 1e-9) v[i] = std::min(v[i], limits.max_curvature_rate_per_s / change);
    }
  }
  if (point_cap_mps.size() == n)
    for (size_t i = 0; i < n; ++i) v[i] = std::min(v[i], std::max(0.0, point_cap_mps[i]));
  if (!path.closed && start_speed_mps) v[0] = std::min(v[0], std::max(0.0, *start_speed_mps));
  if (!path.closed && end_speed_mps) v[n - 1] = std::min(v[n - 1], std::max(0.0, *end_speed_mps));

  // forward (acceleration) and backward (braking) passes; a closed path goes round twice so
  // that the limits carry over the start
  const size_t rounds = path.closed ? 2 : 1;
  const size_t steps = path.closed ? n : n - 1;
  auto ds = [&](size_t i) {  // length of the segment from point i to the next one
    const size_t j = (i + 1) % n;
    return j == 0 ? lap - s[i] : s[j] - s[i];
  };
  for (size_t r = 0; r < rounds; ++r) {
    for (size_t m = 0; m < steps; ++m) {
      const size_t i = m % n, j = (m + 1) % n;
      const double a =
          longitudinal_room(limits.accel_mps2(v[i]), v[i], k[i], limits.lateral_mps2(v[i]));
      v[j] = std::min(v[j], std::sqrt(v[i] * v[i] + 2.0 * a * ds(i)));
    }
  }
  for (size_t r = 0; r < rounds; ++r) {
    for (size_t m = steps; m-- > 0;) {
      const size_t i = m % n, j = (m + 1) % n;
      const double a = limits.braking_mps2(v[j], k[j]);
      v[i] = std::min(v[i], std::sqrt(v[j] * v[j] + 2.0 * a * ds(i)));
    }
  }
  profile.speed_mps = std::move(v);
  return profile;
}

}  // namespace conesim::control
