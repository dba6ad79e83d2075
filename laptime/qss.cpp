#include "laptime/qss.hpp"

#include <algorithm>
#include <cmath>

namespace conesim::laptime {

namespace {

using vehicle_models::kGravityMps2;

// the tyres' total grip force at speed v (weight plus downforce), N
double grip_force_n(const PerformanceEnvelope& e, double v) {
  return e.friction * (e.mass_kg * kGravityMps2 + e.downforce_n_per_v2 * v * v);
}

// the share of the tyre force left lengthways when v^2 |curvature| is used sideways
double ellipse_share(const PerformanceEnvelope& e, double v, double curvature) {
  const double lateral = v * v * std::abs(curvature) / e.lateral_limit_mps2(v);
  return lateral >= 1.0 ? 0.0 : std::sqrt(1.0 - lateral * lateral);
}

// the speed after ds at acceleration accel(v): v^2 changes by 2 a ds, with a taken at the
// half-way speed (second order; never below zero)
template <typename Accel>
double advance(double v, const Accel& accel, double ds) {
  const double half = std::sqrt(std::max(0.0, v * v + accel(v) * ds));
  return std::sqrt(std::max(0.0, v * v + 2.0 * accel(half) * ds));
}

// times at each point and over the line from speeds (trapezoidal in 1/v over each step)
void fill_times(SpeedTrace& trace, double end_s, bool closed) {
  const size_t n = trace.s_m.size();
  trace.time_s.assign(n, 0.0);
  auto step_time = [](double ds, double v0, double v1) {
    return 2.0 * ds / std::max(v0 + v1, 1e-6);
  };
  for (size_t i = 1; i < n; ++i)
    trace.time_s[i] = trace.time_s[i - 1] + step_time(trace.s_m[i] - trace.s_m[i - 1],
                                                      trace.speed_mps[i - 1], trace.speed_mps[i]);
  trace.total_time_s = trace.time_s.back();
  if (closed)
    trace.total_time_s +=
        step_time(end_s - trace.s_m.back(), trace.speed_mps.back(), trace.speed_mps.front());
}

}  // namespace

double SpeedTrace::time_at(double s) const {
  if (s_m.empty()) return 0.0;
  if (s <= s_m.front()) return time_s.front();
  if (s >= s_m.back()) return time_s.back();
  const size_t i = static_cast<size_t>(std::upper_bound(s_m.begin(), s_m.end(), s) - s_m.begin());
  const double f = (s - s_m[i - 1]) / std::max(1e-12, s_m[i] - s_m[i - 1]);
  // time over a part of a step at the speeds of its ends, linear in speed
  const double v0 = speed_mps[i - 1], v1 = speed_mps[i];
  const double vf = v0 + f * (v1 - v0);
  return time_s[i - 1] + 2.0 * (s - s_m[i - 1]) / std::max(v0 + vf, 1e-6);
}

double cornering_speed_mps(const PerformanceEnvelope& e, double curvature) {
  // v^2 |k| = friction (g + downforce v^2 / m)  =>  v^2 (|k| - friction downforce / m) = friction g
  const double top = e.top_speed_mps();
  const double k = std::abs(curvature) - e.friction * e.downforce_n_per_v2 / e.mass_kg;
  if (k <= 0.0) return top;
  return std::min(top, std::sqrt(e.friction * kGravityMps2 / k));
}

double drive_accel_mps2(const PerformanceEnvelope& e, double v, double curvature) {
  const double speed = std::max(std::abs(v), 0.1);
  const double motor = std::min(e.max_drive_force_n, e.max_power_w / speed);
  const double tyre = grip_force_n(e, v) * ellipse_share(e, v, curvature);
  return (std::min(motor, tyre) - e.drag_n_per_v2 * v * v - e.rolling_n) / e.mass_kg;
}

double brake_decel_mps2(const PerformanceEnvelope& e, double v, double curvature) {
  const double tyre = grip_force_n(e, v) * ellipse_share(e, v, curvature);
  return (std::min(e.max_brake_force_n, tyre) + e.drag_n_per_v2 * v * v + e.rolling_n) / e.mass_kg;
}

SpeedTrace flying_lap(const std::vector<double>& s_m, const std::vector<double>& curvature,
                      double lap_m, const PerformanceEnvelope& e) {
  SpeedTrace trace;
  trace.s_m = s_m;
  const size_t n = s_m.size();
  if (n < 3) return trace;
  auto ds = [&](size_t i) {  // from point i to the next one round the loop
    return i + 1 < n ? s_m[i + 1] - s_m[i] : lap_m - s_m[i] + s_m[0];
  };

  // the cornering limit, and the slowest corner the passes start from
  std::vector<double> limit(n);
  for (size_t i = 0; i < n; ++i) limit[i] = cornering_speed_mps(e, curvature[i]);
  const size_t slowest =
      static_cast<size_t>(std::min_element(limit.begin(), limit.end()) - limit.begin());

  // forward pass twice round: accelerating out of each corner
  std::vector<double> fwd = limit;
  double v = limit[slowest];
  for (size_t step = 1; step <= 2 * n; ++step) {
    const size_t prev = (slowest + step - 1) % n, i = (slowest + step) % n;
    const double k = 0.5 * (curvature[prev] + curvature[i]);
    v = std::min(limit[i], advance(
                               v, [&](double u) { return drive_accel_mps2(e, u, k); }, ds(prev)));
    fwd[i] = v;
  }
  // backward pass twice round: braking into each corner
  std::vector<double> bwd = limit;
  v = limit[slowest];
  for (size_t step = 1; step <= 2 * n; ++step) {
    const size_t next = (slowest + 2 * n - step + 1) % n, i = (slowest + 2 * n - step) % n;
    const double k = 0.5 * (curvature[next] + curvature[i]);
    v = std::min(limit[i], advance(
                               v, [&](double u) { return brake_decel_mps2(e, u, k); }, ds(i)));
    bwd[i] = v;
  }
  trace.speed_mps.resize(n);
  for (size_t i = 0; i < n; ++i) trace.speed_mps[i] = std::min(fwd[i], bwd[i]);
  fill_times(trace, lap_m + s_m[0], true);
  return trace;
}

SpeedTrace standing_start(const std::vector<double>& s_m, const std::vector<double>& curvature,
                          const PerformanceEnvelope& e) {
  SpeedTrace trace;
  trace.s_m = s_m;
  const size_t n = s_m.size();
  if (n < 2) return trace;
  std::vector<double> limit(n);
  for (size_t i = 0; i < n; ++i) limit[i] = cornering_speed_mps(e, curvature[i]);

  // forward from standstill, backward from the last point's limit
  std::vector<double> fwd(n), bwd(n);
  fwd[0] = 0.0;
  for (size_t i = 1; i < n; ++i) {
    const double k = 0.5 * (curvature[i - 1] + curvature[i]);
    fwd[i] = std::min(limit[i], advance(
                                    fwd[i - 1], [&](double u) { return drive_accel_mps2(e, u, k); },
                                    s_m[i] - s_m[i - 1]));
  }
  bwd[n - 1] = limit[n - 1];
  for (size_t i = n - 1; i-- > 0;) {
    const double k = 0.5 * (curvature[i] + curvature[i + 1]);
    bwd[i] = std::min(limit[i], advance(
                                    bwd[i + 1], [&](double u) { return brake_decel_mps2(e, u, k); },
                                    s_m[i + 1] - s_m[i]));
  }
  trace.speed_mps.resize(n);
  for (size_t i = 0; i < n; ++i) trace.speed_mps[i] = std::min(fwd[i], bwd[i]);
  fill_times(trace, s_m.back(), false);
  return trace;
}

}  // namespace conesim::laptime
