// The performance envelope against the MuJoCo car it describes: the lateral limit on a steady
// circle at rising speed, and the 75 m acceleration from standstill against the lap-time
// bound's standing start. Slow (a few hundred thousand physics steps), so run with --all.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <deque>
#include <numbers>
#include <vector>

#include "core/cone.hpp"
#include "laptime/qss.hpp"
#include "sim/vehicle_sim.hpp"
#include "vehicle_models/performance.hpp"

namespace conesim::sim {
namespace {

using core::Vec2;
using core::VehicleCommand;
using vehicle_models::kGravityMps2;
using vehicle_models::PerformanceEnvelope;
using vehicle_models::VehicleParams;

// what the circle run found: the largest lateral acceleration held for a second while the car
// stayed on its circle, the speed it was held at, and the envelope's limit at that speed
struct CircleResult {
  double measured_mps2 = 0.0;
  double speed_mps = 0.0;
  double envelope_mps2 = 0.0;
};

// drives a counter-clockwise circle of radius r about (0, r) from rest: pure pursuit on the
// circle, the target speed rising by ramp_mps2 from start_mps until the car runs more than
// kOffLineM wide of it (it understeers at the limit)
CircleResult drive_circle(double r, double start_mps, double ramp_mps2) {
  constexpr double kOffLineM = 1.0;
  constexpr double kWindowS = 1.0;
  const VehicleParams params;
  const PerformanceEnvelope envelope = PerformanceEnvelope::of(params);
  VehicleSim car(params, {0.0, 0.0, 0.0});
  const Vec2 centre(0.0, r);
  const double dt = car.timestep_s();
  const int window = static_cast<int>(std::round(kWindowS / dt));

  CircleResult best;
  std::deque<double> lateral, speed;
  double lateral_sum = 0.0, speed_sum = 0.0;
  double target = 0.0, t = 0.0;
  while (t < 400.0) {
    const VehicleTruth truth = car.truth();
    const Vec2 p = truth.pose.position();
    const double off_line = (p - centre).norm() - r;
    if (t > 20.0 && off_line > kOffLineM) break;

    // pure pursuit: the point of the circle 6 m of arc ahead of the car's own angle
    const Vec2 from_centre = p - centre;
    const double angle = std::atan2(from_centre.y(), from_centre.x()) + 6.0 / r;
    const Vec2 goal = centre + r * Vec2(std::cos(angle), std::sin(angle));
    const Vec2 local = truth.pose.inverse_transform(goal);
    const double steer = std::atan2(2.0 * params.wheelbase_m * local.y(), local.squaredNorm());

    // the target speed: up to start_mps, then rising slowly
    target = t < 15.0 ? std::min(start_mps, 2.0 * t) : start_mps + ramp_mps2 * (t - 15.0);
    car.step({steer, std::clamp(4.0 * (target - truth.vx_mps), -8.0, 8.0), false});
    t += dt;

    // a one-second average of v * yaw rate while the car holds the circle
    lateral.push_back(truth.vx_mps * truth.yaw_rate_rps);
    speed.push_back(truth.vx_mps);
    lateral_sum += lateral.back();
    speed_sum += speed.back();
    if (static_cast<int>(lateral.size()) > window) {
      lateral_sum -= lateral.front();
      speed_sum -= speed.front();
      lateral.pop_front();
      speed.pop_front();
    }
    if (t > 15.0 && static_cast<int>(lateral.size()) == window && std::abs(off_line) < kOffLineM &&
        lateral_sum / window > best.measured_mps2) {
      best.measured_mps2 = lateral_sum / window;
      best.speed_mps = speed_sum / window;
    }
  }
  best.envelope_mps2 = envelope.lateral_limit_mps2(best.speed_mps);
  std::printf(
      "circle R %.2f m: measured %.2f m/s^2 (%.3f g) at %.2f m/s, envelope %.2f m/s^2, "
      "ratio %.3f\n",
      r, best.measured_mps2, best.measured_mps2 / kGravityMps2, best.speed_mps, best.envelope_mps2,
      best.measured_mps2 / best.envelope_mps2);
  return best;
}

TEST(MeasuredGrip, SteadyCircleReachesTheEnvelopesLateralLimit) {
  // measured: 0.983 of the envelope on the 9.125 m circle (1.55 g at 12.0 m/s, as docs/vehicle.md
  // found) and 0.979 on the 20 m one (1.75 g at 18.6 m/s): the car reaches 0.93 of its tyre
  // friction where the envelope assumes kMeasuredGripShare 0.95, a 2 % difference that puts the
  // lap-time bound 1 % on the fast side (speed goes with the root of the grip).
  // the speed rises by 0.05 m/s per second: v^2 / R rises by under 0.15 m/s^2 over the
  // averaging second (under 1 %), and the car is that close to steady state; the envelope's
  // share of the tyre friction is one figure for all speeds, so the two radii (little and much
  // downforce) bracket it. 3 %: the averaging, the ramp, and the grip the pursuit's slip angle
  // costs
  for (double r : {9.125, 20.0}) {
    SCOPED_TRACE("R " + std::to_string(r));
    const CircleResult c = drive_circle(r, 0.8 * std::sqrt(14.0 * r), 0.05);
    EXPECT_NEAR(c.measured_mps2 / c.envelope_mps2, 1.0, 0.03);
  }
}

TEST(MeasuredGrip, AccelerationMatchesTheStandingStartBound) {
  // full throttle over 75 m from standstill: the car's traction control and power limit against
  // the bound's standing start on the same envelope
  const VehicleParams params;
  VehicleSim car(params, {});
  double t_s = 0.0;
  while (car.truth().pose.x < 75.0 && t_s < 10.0) {
    car.step({0.0, 30.0, false});
    t_s += car.timestep_s();
  }
  std::vector<double> s, kappa;
  for (int i = 0; i <= 75 * 4; ++i) {
    s.push_back(0.25 * i);
    kappa.push_back(0.0);
  }
  const laptime::SpeedTrace bound =
      laptime::standing_start(s, kappa, PerformanceEnvelope::of(params));
  std::printf(
      "acceleration 75 m: MuJoCo %.3f s at %.2f m/s, bound %.3f s at %.2f m/s, "
      "ratio %.3f\n",
      t_s, car.truth().vx_mps, bound.total_time_s, bound.speed_mps.back(),
      t_s / bound.total_time_s);
  // a bound: never slower than the car; and close to it. Measured: 3.76 s against 3.51 s
  // (+7 %), 35.2 m/s against 36.3 m/s at the line: the bound launches on the whole tyre grip
  // (friction x weight) where the car's traction control holds the slip at 8 % and cuts the
  // torque above it; 10 % leaves room for that and no more
  EXPECT_GE(t_s, bound.total_time_s);
  EXPECT_LE(t_s, bound.total_time_s * 1.10);
}

TEST(MeasuredGrip, FullLockFitsTheFsgMinimumHairpin) {
  // at walking pace on full lock the car turns a rear-axle circle of 5.8 m, not the kinematic
  // 4.2 m (L / tan 36 deg): the anti-Ackermann front tyres fight. Its outer front corner sweeps
  // 8.5 m across: inside an FSG minimum hairpin (9 m outside diameter, cones of 0.23 m base on
  // it leave 8.77 m); the car's inner side stays outside the 3 m inner diameter of 3 m lanes
  const VehicleParams p;
  VehicleSim car(p, {});
  double t = 0.0;
  Eigen::AlignedBox2d rear, corner, inner;
  while (t < 25.0) {
    const VehicleTruth tr = car.truth();
    car.step({p.max_steer_rad, std::clamp(3.0 * (3.0 - tr.vx_mps), -5.0, 5.0), false});
    t += car.timestep_s();
    if (t < 12.0) continue;  // a full circle after settling
    rear.extend(tr.pose.position());
    corner.extend(tr.pose.transform({p.front_overhang_from_rear_axle_m, -0.5 * p.width_m}));
    inner.extend(tr.pose.transform({0.0, 0.5 * p.width_m}));  // nearest the centre
  }
  const double rear_d = rear.sizes().x(), swept_d = corner.sizes().x();
  std::printf(
      "full lock at 3 m/s: rear axle circle %.2f m across (kinematic %.2f m), outer front "
      "corner %.2f m, inner side %.2f m\n",
      rear_d, 2.0 * p.wheelbase_m / std::tan(p.max_steer_rad), swept_d, inner.sizes().x());
  EXPECT_GT(rear_d, 2.0 * p.wheelbase_m / std::tan(p.max_steer_rad));
  EXPECT_LT(swept_d, 9.0 - core::cone_size(core::ConeClass::kBlue).base_m);
  EXPECT_GT(inner.sizes().x(), 3.0 + core::cone_size(core::ConeClass::kBlue).base_m);
}

}  // namespace
}  // namespace conesim::sim
