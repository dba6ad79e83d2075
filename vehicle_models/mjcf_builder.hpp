#pragma once
// Builds the MuJoCo model (MJCF text) of the car from its parameters.

#include <string>

#include "core/time.hpp"
#include "vehicle_models/vehicle_params.hpp"

namespace conesim::vehicle_models {

/// Names used in the generated model, so that the simulation finds joints and actuators.
/// Corners are fl, fr, rl, rr.
struct MjcfNames {
  static constexpr const char* kChassis = "chassis";
  static constexpr const char* kImuSite = "imu";
  static constexpr const char* kCorners[4] = {"fl", "fr", "rl", "rr"};
};

/// A height field in place of the ground plane (issue 17): nrow x ncol heights over a rectangle
/// centred on (centre_x_m, centre_y_m), rows along y, columns along x; the heights themselves
/// go into the model's hfield_data after loading (0..1 of elevation_m above base_z_m).
struct MjcfHeightField {
  /// 0: the flat plane of today.
  int nrow = 0, ncol = 0;
  double centre_x_m = 0.0, centre_y_m = 0.0;
  double half_x_m = 0.0, half_y_m = 0.0;
  /// Height of data 1 above the field's base level, and that level's z.
  double elevation_m = 0.0, base_z_m = 0.0;
};

/// Options of the generated world that are not car parameters.
struct MjcfOptions {
  /// Physics step, seconds (the measured settings hold for 0.5-2 ms; the sim's schedules are
  /// built on core::kPhysicsStepUs).
  double timestep_s = core::to_seconds(core::kPhysicsStepUs);
  /// Offscreen buffer for the camera renderer, pixels.
  int offscreen_width_px = 1280;
  int offscreen_height_px = 960;
  /// The ground: a plane unless the height field has rows.
  MjcfHeightField ground;
};

/// The MJCF of the car on an asphalt ground plane (or height field, named "ground" either way),
/// with the settings measured in docs/vehicle.md: elliptic friction cones, solimp first value 0,
/// sprung wheels (a slide joint per corner, preloaded so the car rests at design ride height),
/// ellipsoid tyres, front steering hinges with position servos, a motor per wheel, an IMU site with
/// gyro and accelerometer, and joint position and velocity sensors. The body frame of the chassis
/// sits at the rear axle centre at wheel-centre height, x forward. Cones are not part of the model
/// (ARCHITECTURE decision 1): the renderer and the LiDAR add them.
std::string build_mjcf(const VehicleParams& params, const MjcfOptions& options = {});

}  // namespace conesim::vehicle_models
