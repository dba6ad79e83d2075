#pragma once
// The autonomous driver: plans from the state estimate and the cones in view, steers with pure
// pursuit, sets the speed from the path's curvature, and runs one mission per FSG event.
// It sees only core types: the estimate may come from SLAM or, for now, from ground truth.

#include <memory>
#include <string>
#include <vector>

#include "core/autonomy_types.hpp"
#include "core/event.hpp"

namespace conesim::control {

/// Driver settings (scenario key `driver`). Plain values with defaults and a validate().
struct DriverParams {
  /// Speed cap while the track is unknown (autocross, trackdrive lap 1), m/s.
  double explore_speed_mps = 9.0;
  /// Speed cap once the whole track is known (trackdrive laps 2-10), m/s.
  double fast_speed_mps = 16.0;
  /// Speed cap on the acceleration straight, m/s.
  double acceleration_speed_mps = 40.0;
  /// Speed cap on skidpad, m/s.
  double skidpad_speed_mps = 9.0;
  /// Lateral acceleration the speed profile plans for, m/s^2.
  double max_lateral_accel_mps2 = 9.0;
  /// Longitudinal limits of the speed profile, m/s^2.
  double max_accel_mps2 = 6.0;
  double max_decel_mps2 = 8.0;
  /// Pure pursuit look-ahead: distance = max(min, gain * speed), metres and seconds.
  double lookahead_min_m = 3.0;
  double lookahead_gain_s = 0.35;
  /// Laps of trackdrive, counted by the car itself.
  int trackdrive_laps = 10;
  /// Half width assumed when only one boundary is visible, metres.
  double assumed_half_width_m = 1.6;
  /// Acceleration requested on the acceleration straight (full power: the car limits it), m/s^2.
  double launch_accel_mps2 = 15.0;
  /// Gain of the speed controller: m/s^2 per m/s of speed error.
  double speed_gain_per_s = 2.0;

  /// Empty when usable, otherwise "key: what was expected".
  std::string validate() const;
};

/// What the vehicle knows of itself apart from the estimate.
struct VehicleGeometry {
  double wheelbase_m = 1.53;
  double max_steer_rad = 0.4712;
  /// Distance from the reference point (rear axle centre) forward to the front wing, metres.
  double rear_axle_to_front_m = 2.25;
};

/// Everything the driver gets each time it runs.
struct DriverInput {
  /// The state estimate (pose of the rear axle centre in the map frame, speed, map so far).
  core::Estimate estimate;
  /// The cones perceived at this instant, in the vehicle frame.
  core::ConeObservations observations;
};

/// What the driver reports about its mission (for logs and the progress line).
struct DriverStatus {
  /// Laps the car has counted itself (trackdrive, autocross) or skidpad laps done.
  int laps_counted = 0;
  /// True once the mission is done and the car is being held at a stop.
  bool finished = false;
  /// Short state name, e.g. "explore", "fast", "braking", "stopped".
  std::string state;
  /// The path currently followed, in the map frame (for plots).
  std::vector<core::Vec2> path;
  /// Speed the car is asked to reach now, m/s.
  double target_speed_mps = 0.0;
  /// Distance the reference point has travelled since the start, metres.
  double odometer_m = 0.0;
};

/// One driver per run; not copyable (holds the mission state).
class Driver {
 public:
  /// A driver for the event. `prior_map` is the known layout given to the car before the run
  /// (skidpad: the FSG layout, in the map frame); empty when there is none.
  Driver(core::EventType event, const DriverParams& params, const VehicleGeometry& vehicle,
         std::vector<core::MapCone> prior_map = {});
  ~Driver();
  Driver(const Driver&) = delete;
  Driver& operator=(const Driver&) = delete;

  /// Plans and returns the command to hold until the next call.
  core::VehicleCommand update(const DriverInput& input);

  /// The mission's status after the last update.
  const DriverStatus& status() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace conesim::control
