#include "laptime/qss.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

namespace conesim::laptime {
namespace {

using vehicle_models::kGravityMps2;
using vehicle_models::VehicleParams;

constexpr double kPi = std::numbers::pi;

// a closed line of constant curvature every ds
struct Line {
  std::vector<double> s, kappa;
  double length = 0.0;
};
Line circle(double radius, double ds) {
  Line l;
  l.length = 2.0 * kPi * radius;
  const int n = static_cast<int>(std::round(l.length / ds));
  for (int i = 0; i < n; ++i) {
    l.s.push_back(l.length * i / n);
    l.kappa.push_back(1.0 / radius);
  }
  return l;
}

// the steady speed on a circle by bisection on v^2 / R = lateral limit at v
double steady_speed(const PerformanceEnvelope& e, double radius) {
  double lo = 0.0, hi = 100.0;
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    (mid * mid / radius < e.lateral_limit_mps2(mid) ? lo : hi) = mid;
  }
  return lo;
}

TEST(Qss, CorneringSpeedSolvesTheLateralLimit) {
  const PerformanceEnvelope e = PerformanceEnvelope::of(VehicleParams{});
  for (double r : {3.0, 9.125, 20.0, 40.0})
    EXPECT_NEAR(cornering_speed_mps(e, 1.0 / r), steady_speed(e, r), 1e-9);
  // gentle enough a curve, or a straight: the top speed
  EXPECT_NEAR(cornering_speed_mps(e, 0.0), e.top_speed_mps(), 1e-9);
  EXPECT_NEAR(cornering_speed_mps(e, 1e-4), e.top_speed_mps(), 1e-9);
}

TEST(Qss, FrictionEllipseLeavesNoGripAtTheLateralLimit) {
  const PerformanceEnvelope e = PerformanceEnvelope::of(VehicleParams{});
  const double r = 9.125, v = steady_speed(e, r);
  // straight: the envelope's own limits
  EXPECT_NEAR(drive_accel_mps2(e, 20.0, 0.0), e.accel_limit_mps2(20.0), 1e-9);
  EXPECT_NEAR(brake_decel_mps2(e, 20.0, 0.0), e.decel_limit_mps2(20.0), 1e-9);
  // at the limit only drag and rolling remain: the car slows, and brakes with them alone
  const double resistance = (e.drag_n_per_v2 * v * v + e.rolling_n) / e.mass_kg;
  EXPECT_NEAR(drive_accel_mps2(e, v, 1.0 / r), -resistance, 1e-6);
  EXPECT_NEAR(brake_decel_mps2(e, v, 1.0 / r), resistance, 1e-6);
  // half-way round the ellipse: sqrt(3)/2 of the grip is left lengthways
  const double v_half = std::sqrt(0.5 * e.lateral_limit_mps2(v) * r);
  const double grip =
      e.friction * (e.mass_kg * kGravityMps2 + e.downforce_n_per_v2 * v_half * v_half);
  const double lateral_share = v_half * v_half / r / e.lateral_limit_mps2(v_half);
  EXPECT_NEAR(brake_decel_mps2(e, v_half, 1.0 / r),
              (std::sqrt(1.0 - lateral_share * lateral_share) * grip +
               e.drag_n_per_v2 * v_half * v_half + e.rolling_n) /
                  e.mass_kg,
              1e-6);
}

// the steady speed on a circle when the tyres must also hold the speed against drag and
// rolling: (lateral share)^2 + (resistance / grip)^2 = 1 on the friction ellipse
double steady_speed_with_drag(const PerformanceEnvelope& e, double radius) {
  double lo = 0.0, hi = 100.0;
  for (int i = 0; i < 100; ++i) {
    const double v = 0.5 * (lo + hi);
    const double lateral = v * v / radius / e.lateral_limit_mps2(v);
    const double grip = e.friction * (e.mass_kg * kGravityMps2 + e.downforce_n_per_v2 * v * v);
    const double lengthways = (e.drag_n_per_v2 * v * v + e.rolling_n) / grip;
    (lateral * lateral + lengthways * lengthways < 1.0 ? lo : hi) = v;
  }
  return lo;
}

TEST(Qss, CircleLapIsCircumferenceOverTheSteadySpeed) {
  // the flying lap of a circle of radius R: 2 pi R / v with v^2 = a_lat(v) R, and no faster; the
  // tyres also have to hold the speed against drag, which can cost up to the time at the speed
  // where the friction ellipse balances both (0.02 % at 5 m, 0.3 % at 25 m)
  for (double grip : {1.0, 0.7}) {
    const PerformanceEnvelope e = PerformanceEnvelope::of(VehicleParams{}, grip);
    for (double r : {5.0, 9.125, 25.0}) {
      SCOPED_TRACE("R " + std::to_string(r) + " grip " + std::to_string(grip));
      const Line l = circle(r, 0.25);
      const SpeedTrace t = flying_lap(l.s, l.kappa, l.length, e);
      const double lateral_only = 2.0 * kPi * r / steady_speed(e, r);
      const double with_drag = 2.0 * kPi * r / steady_speed_with_drag(e, r);
      EXPECT_GE(t.total_time_s, lateral_only * (1.0 - 1e-9));
      EXPECT_LE(t.total_time_s, with_drag * (1.0 + 1e-4));
    }
  }
}

TEST(Qss, StandingStartOnAStraightIntegratesTheEnvelope) {
  // 75 m from standstill: the time matches a fine integration of dv/dt = accel_limit(v)
  const PerformanceEnvelope e = PerformanceEnvelope::of(VehicleParams{});
  std::vector<double> s, kappa;
  for (int i = 0; i <= 100 * 4; ++i) {
    s.push_back(0.25 * i);
    kappa.push_back(0.0);
  }
  const SpeedTrace t = standing_start(s, kappa, e);

  double time = 0.0, x = 0.0, v = 0.0;
  const double dt = 1e-5;
  while (x < 75.0) {
    const double a = e.accel_limit_mps2(v);
    x += v * dt + 0.5 * a * dt * dt;
    v += a * dt;
    time += dt;
  }
  EXPECT_NEAR(t.time_at(75.0), time, 0.01);
  // and it is a sane FS acceleration run: 3.5-4.5 s for top cars
  EXPECT_GT(time, 3.0);
  EXPECT_LT(time, 4.5);
  // the end of the line is free: no braking planned for it
  EXPECT_NEAR(t.speed_mps.back(), t.speed_mps[t.speed_mps.size() - 2], 0.2);
}

TEST(Qss, BrakesIntoATightCornerAndAcceleratesOut) {
  // a closed line: 100 m straight, a 5 m radius half turn, 100 m straight, half turn
  std::vector<double> s, kappa;
  const double ds = 0.25, r = 5.0;
  const double parts[4] = {100.0, kPi * r, 100.0, kPi * r};
  double at = 0.0;
  for (int p = 0; p < 4; ++p) {
    for (int i = 0; i < static_cast<int>(std::round(parts[p] / ds)); ++i) {
      s.push_back(at);
      kappa.push_back(p % 2 == 1 ? 1.0 / r : 0.0);
      at += ds;
    }
  }
  const PerformanceEnvelope e = PerformanceEnvelope::of(VehicleParams{});
  const SpeedTrace t = flying_lap(s, kappa, at, e);
  const double v_corner = cornering_speed_mps(e, 1.0 / r);
  double v_min = 1e9, v_max = 0.0;
  for (double v : t.speed_mps) {
    v_min = std::min(v_min, v);
    v_max = std::max(v_max, v);
  }
  EXPECT_NEAR(v_min, v_corner, 0.01 * v_corner);
  EXPECT_GT(v_max, 2.0 * v_corner);  // the straights are long enough to gain a lot
  EXPECT_LT(v_max, e.top_speed_mps());
  // the speed at the end of a straight is what braking from it to the corner speed allows:
  // the backward pass agrees with v^2 = v_c^2 + 2 * decel * distance within the step error
  const size_t corner = static_cast<size_t>(std::round(100.0 / ds));
  const double v_before = t.speed_mps[corner - 8];  // 2 m before the corner
  EXPECT_NEAR(v_before * v_before, v_corner * v_corner + 2.0 * 2.0 * e.decel_limit_mps2(v_corner),
              0.05 * v_before * v_before);
}

}  // namespace
}  // namespace conesim::laptime
