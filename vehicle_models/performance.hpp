#pragma once
// What the car can do at a given speed: the grip its tyres give sideways and lengthways (with
// the downforce that grows with speed), the drive force its motors and power give, the braking
// its brakes give, and the drag. The driver's speed profile, the pre-run drivability check and
// the lap-time bound all read these limits, so that they agree with each other and with the
// MuJoCo car.
//
// Measured on the MuJoCo car (tests/vehicle_models/performance_slow_test.cpp; docs/vehicle.md):
// on a steady circle the car reaches about 0.95 of the friction its tyres are given
// (tyre_friction 1.5 -> 1.43 g without aero), because the elliptic friction cone is shared
// between the slip of the four tyres. kMeasuredGripShare holds that figure.

#include "vehicle_models/vehicle_params.hpp"

namespace conesim::vehicle_models {

/// Share of the nominal tyre friction the MuJoCo car reaches on a steady circle (measured).
inline constexpr double kMeasuredGripShare = 0.95;
/// Standard gravity, m/s^2.
inline constexpr double kGravityMps2 = 9.81;

/// The car's acceleration limits as functions of speed. Plain values, copyable, cheap to query.
struct PerformanceEnvelope {
  /// Mass, kg.
  double mass_kg = 250.0;
  /// Friction the tyres give on this car (nominal friction x measured share x grip fraction).
  double friction = 1.43;
  /// Downforce per speed squared (0.5 rho ClA), N s^2/m^2.
  double downforce_n_per_v2 = 1.8;
  /// Drag per speed squared (0.5 rho CdA), N s^2/m^2.
  double drag_n_per_v2 = 0.78;
  /// Rolling resistance force, N.
  double rolling_n = 36.8;
  /// Drive force the motors give at low speed (torque over wheel radius, all driven wheels), N.
  double max_drive_force_n = 4348.0;
  /// Power at the wheels, W.
  double max_power_w = 80000.0;
  /// Braking force the brakes give (all four wheels), N.
  double max_brake_force_n = 10435.0;

  /// The envelope of `params`, with the tyres' grip scaled by grip_fraction (1 = the limit the
  /// car was measured to reach; the driver plans with less).
  static PerformanceEnvelope of(const VehicleParams& params, double grip_fraction = 1.0);

  /// Largest lateral acceleration at speed v (tyre grip on weight plus downforce), m/s^2.
  double lateral_limit_mps2(double v_mps) const;
  /// Largest forward acceleration on a straight at speed v, net of drag and rolling, m/s^2.
  double accel_limit_mps2(double v_mps) const;
  /// Largest deceleration on a straight at speed v (brakes or grip, plus drag), m/s^2 (> 0).
  double decel_limit_mps2(double v_mps) const;
  /// Speed at which drive force and resistance balance, m/s.
  double top_speed_mps() const;
  /// Tightest steady turn radius at speed v (lateral limit), metres.
  double min_radius_m(double v_mps) const;
};

}  // namespace conesim::vehicle_models
