#include "vehicle_models/performance.hpp"

#include <algorithm>
#include <cmath>

namespace conesim::vehicle_models {

PerformanceEnvelope PerformanceEnvelope::of(const VehicleParams& p, double grip_fraction) {
  PerformanceEnvelope e;
  e.mass_kg = p.mass_kg;
  e.friction = p.tyre_friction * kMeasuredGripShare * grip_fraction;
  e.downforce_n_per_v2 = 0.5 * p.air_density_kgm3 * p.lift_area_m2;
  e.drag_n_per_v2 = 0.5 * p.air_density_kgm3 * p.drag_area_m2;
  e.rolling_n = p.rolling_resistance * p.mass_kg * kGravityMps2;
  e.max_drive_force_n = 2.0 * (p.max_torque_front_nm + p.max_torque_rear_nm) / p.wheel_radius_m;
  e.max_power_w = p.max_power_w;
  e.max_brake_force_n = 4.0 * p.max_brake_torque_nm / p.wheel_radius_m;

  // traction: only the driven axles' share of the load pushes the car
  double driven_share = 0.0;
  if (p.max_torque_front_nm > 0.0) driven_share += p.front_mass_fraction;
  if (p.max_torque_rear_nm > 0.0) driven_share += 1.0 - p.front_mass_fraction;
  e.max_drive_force_n =
      std::min(e.max_drive_force_n, driven_share * e.friction * p.mass_kg * kGravityMps2);
  return e;
}

double PerformanceEnvelope::lateral_limit_mps2(double v) const {
  // grip on the weight plus the downforce at this speed
  return friction * (kGravityMps2 + downforce_n_per_v2 * v * v / mass_kg);
}

double PerformanceEnvelope::accel_limit_mps2(double v) const {
  // motor force, capped by the power at speed, less drag and rolling resistance
  const double speed = std::max(std::abs(v), 0.1);
  const double drive = std::min(max_drive_force_n, max_power_w / speed);
  return (drive - drag_n_per_v2 * v * v - rolling_n) / mass_kg;
}

double PerformanceEnvelope::decel_limit_mps2(double v) const {
  // brakes or tyre grip (on weight and downforce), whichever gives out first, plus drag
  const double grip = friction * (mass_kg * kGravityMps2 + downforce_n_per_v2 * v * v);
  return (std::min(max_brake_force_n, grip) + drag_n_per_v2 * v * v + rolling_n) / mass_kg;
}

double PerformanceEnvelope::top_speed_mps() const {
  // bisection on the net forward acceleration, which falls with speed
  double lo = 0.0, hi = 200.0;
  if (accel_limit_mps2(0.1) <= 0.0) return 0.0;
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    (accel_limit_mps2(mid) > 0.0 ? lo : hi) = mid;
  }
  return lo;
}

double PerformanceEnvelope::min_radius_m(double v) const {
  return v * v / lateral_limit_mps2(v);
}

}  // namespace conesim::vehicle_models
