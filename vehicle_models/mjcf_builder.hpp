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

/// Options of the generated world that are not car parameters.
struct MjcfOptions {
  /// Physics step, seconds (the measured settings hold for 0.5-2 ms; the sim's schedules are
  /// built on core::kPhysicsStepUs).
  double timestep_s = core::to_seconds(core::kPhysicsStepUs);
  /// Offscreen buffer for the camera renderer, pixels.
  int offscreen_width_px = 1280;
  int offscreen_height_px = 960;
};

/// The MJCF of the car on an asphalt ground plane, with the settings measured in
/// docs/vehicle.md: elliptic friction cones, solimp first value 0, sprung wheels (a slide joint
/// per corner, preloaded so the car rests at design ride height), ellipsoid tyres, front steering
/// hinges with position servos, a motor per wheel, an IMU site with gyro and accelerometer, and
/// joint position and velocity sensors. The body frame of the chassis sits at the rear axle
/// centre at wheel-centre height, x forward. Cones are not part of the model (ARCHITECTURE
/// decision 1): the renderer and the LiDAR add them.
std::string build_mjcf(const VehicleParams& params, const MjcfOptions& options = {});

}  // namespace conesim::vehicle_models
