#pragma once
// Vehicle parameters: one plain struct with defaults and a validate() that names the bad key.

#include <string>

namespace conesim::vehicle_models {

/// A Formula Student electric car with its driverless kit. Defaults and their sources:
/// - mass 250 kg, wheelbase 1.53 m, 45/55 front/rear, track 1.2 m, CoG 0.30 m, tyre radius
///   0.23 m and width 0.2 m: a typical FS electric car (the RaceUp and FST theses quote
///   1.53-1.55 m wheelbase and 1.2 m track; 10-inch rims with 0.46 m tyres).
/// - steering 36 degrees single-track at full lock with 2.5 rad/s rate, anti-Ackermann factor -0.3
///   (outer wheel 38 degrees, inner 33): what a car needs to turn an FSG minimum hairpin (9 m
///   outside diameter) with its whole footprint inside the cones. In this contact model the front
///   tyres fight once they point different ways (no slip-angle curve to share the load), so the
///   car turns wider than the kinematic radius: at full lock the rear axle circles on 2.9 m (1.53 m
///   / tan 36 deg = 2.1 kinematic) and the outer front corner sweeps 8.5 m across. The earlier
///   defaults, 27 degrees with full anti-Ackermann (-1, the RaceUp car), turned on 4.4 m and swept
///   11.1 m: no FSG minimum hairpin without cones (docs: README, vehicle). Driverless steering
///   actuators reach full lock in about 0.25 s.
/// - four 250 N m wheel motors, 80 kW total: the 4WD hub-motor cars of the top FS teams
///   (FSG power limit 80 kW).
/// - brakes 600 N m per wheel: enough to lock a loaded wheel; ABS limits the slip.
/// - tyre friction 1.5: FS slicks on dry asphalt (1.4-1.6 g steady-state skidpad).
/// - ClA 3.0 m^2 and CdA 1.3 m^2: full aero package figures of FS cars (docs/vehicle.md).
struct VehicleParams {
  std::string name = "fs-electric-4wd";

  // mass and geometry
  double mass_kg = 250.0;
  double wheelbase_m = 1.53;
  double front_mass_fraction = 0.45;
  double track_m = 1.2;
  double cog_height_m = 0.30;
  double yaw_inertia_kgm2 = 110.0;
  double wheel_radius_m = 0.23;
  double wheel_width_m = 0.20;
  double wheel_mass_kg = 8.0;
  /// Footprint for cone hits and off-course: length and width of the car, and how far its front
  /// (the front wing) is ahead of the rear axle.
  double length_m = 2.9;
  double width_m = 1.4;
  double front_overhang_from_rear_axle_m = 2.25;

  // steering
  double max_steer_rad = 0.6283;  // 36 degrees
  double max_steer_rate_rps = 2.5;
  /// 1 full Ackermann, 0 parallel steer, negative anti-Ackermann.
  double ackermann_factor = -0.3;

  // drivetrain and brakes
  double max_torque_front_nm = 250.0;  // per wheel
  double max_torque_rear_nm = 250.0;   // per wheel
  double max_power_w = 80'000.0;       // all motors together
  double max_brake_torque_nm = 600.0;  // per wheel
  double motor_rotor_inertia_kgm2 = 0.06;
  /// Slip ratio above which traction control and ABS cut the torque.
  double slip_target = 0.08;

  // tyres, resistances and aero
  double tyre_friction = 1.5;
  double rolling_resistance = 0.015;
  double drag_area_m2 = 1.3;  // CdA
  double lift_area_m2 = 3.0;  // ClA (downforce)
  double air_density_kgm3 = 1.2;

  // suspension (vertical travel per corner)
  double spring_n_per_m = 35'000.0;
  double damper_ns_per_m = 2'000.0;
  double suspension_travel_m = 0.035;

  /// Distance from the rear axle to the centre of gravity.
  double cog_from_rear_axle_m() const { return wheelbase_m * front_mass_fraction; }

  /// Empty when every value is usable; otherwise "key: what was expected" for the first bad one.
  std::string validate() const;

  bool operator==(const VehicleParams&) const = default;
};

}  // namespace conesim::vehicle_models
