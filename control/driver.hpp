#pragma once
// The autonomous driver: plans from the state estimate and the cones in view, steers with pure
// pursuit, sets the speed from the path's curvature, and runs one mission per FSG event.
// It sees only core types: the estimate may come from SLAM or, for now, from ground truth.

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/autonomy_types.hpp"
#include "core/event.hpp"
#include "vehicle_models/performance.hpp"

namespace conesim::control {

/// Driver settings (scenario key `driver`). Plain values with defaults and a validate().
struct DriverParams {
  /// Speed cap while the track is unknown (autocross, trackdrive lap 1), m/s.
  double explore_speed_mps = 9.0;
  /// Speed cap once the whole track is known (trackdrive laps 2-10), m/s.
  double fast_speed_mps = 40.0;
  /// Speed cap on the acceleration straight, m/s.
  double acceleration_speed_mps = 40.0;
  /// Speed cap on skidpad, m/s.
  double skidpad_speed_mps = 9.0;
  /// Share of the car's measured grip (its PerformanceEnvelope) the speed profile plans for:
  /// lateral, drive and braking limits over speed all come from the envelope at this fraction.
  /// 0.7: on PacSim FSE22 the MuJoCo car's lateral error on the racing line peaked at 0.47 m
  /// with 0.8 (it understeers near the limit and its grip saturates abruptly), 0.23 m with 0.7
  /// and 0.17 m with 0.6, for laps of 15.65, 16.38 and 17.33 s.
  double grip_fraction = 0.7;
  /// The share of the measured grip lap 1 turns with (exploring a trackdrive or an autocross,
  /// and braking after its finish; its braking and drive stay at grip_fraction): its path is
  /// laid afresh from the cones in view each tick and moves as more of a bend comes into view,
  /// so the car needs grip to spare to follow it. Measured on PacSim FSE24 with the LiDAR (seed
  /// 1): turning with 0.7 the car entered a 4.5 m-radius bend at 6.7 m/s, turned in late and hit
  /// its outer cone; with 0.55 its footprint kept 0.53 m. Braking at 0.55 as well reached a
  /// generated minimum hairpin's turn-in 0.5 m later and hit its outer cones (hard trackdrive
  /// 7125).
  double explore_grip_fraction = 0.55;
  /// Acceleration and skidpad: the lateral acceleration their speed profile plans for and the
  /// longitudinal limits of their speed profile and command, m/s^2 (the circuits plan from the
  /// envelope).
  double max_lateral_accel_mps2 = 9.0;
  double max_accel_mps2 = 6.0;
  double max_decel_mps2 = 8.0;
  /// Clearance the racing line plans between the car's footprint (its whole rectangle) and any
  /// cone, metres; `tight_turn_margin_m` where it turns near full lock (at 0.75 of full lock's
  /// curvature or more) and from 10 m before to 25 m after such a turn, when larger. The car
  /// leaves a near-full-lock hairpin up to 0.7 m off its line, accelerating at the tyres'
  /// limit: with 0.2 m everywhere 4 of 100 generated hard trackdrives hit a cone 7-19 m past
  /// such a hairpin, none with 0.2 m and 0.3 m about the hairpins. The default covers the
  /// tracking and a SLAM estimate's error: at 0.2 m, 3 more of 100 generated hard trackdrives
  /// hit a cone on a fast lap with GraphSLAM. With an exact estimate (the ground-truth scenario
  /// sets 0.2 m) the MuJoCo car keeps 0.13-0.19 m of 0.2 m on the PacSim circuits.
  double footprint_margin_m = 0.3;
  double tight_turn_margin_m = 0.3;
  /// Check before a run that the layout is drivable by this car (`conesim run` refuses one
  /// that is not, naming the place); false runs it anyway.
  bool check_drivable = true;
  /// Pure pursuit look-ahead: distance = max(min, gain * speed), metres and seconds.
  double lookahead_min_m = 3.0;
  double lookahead_gain_s = 0.35;
  /// Laps of trackdrive, counted by the car itself.
  int trackdrive_laps = 10;
  /// Half width assumed when only one boundary is visible, metres.
  double assumed_half_width_m = 1.6;
  /// Acceleration requested on the acceleration straight (full power: the car limits it), m/s^2.
  double launch_accel_mps2 = 15.0;
  /// Gain of the speed controller: m/s^2 per m/s of speed error (on top of the profile's slope
  /// as feed-forward). The MuJoCo car reaches only about 0.7-0.8 of a commanded acceleration out
  /// of a turn (traction control, the front tyres' drag at an angle), so the feedback has to
  /// make up the rest quickly.
  double speed_gain_per_s = 4.0;

  /// Empty when usable, otherwise "key: what was expected".
  std::string validate() const;
};

/// What the vehicle knows of itself apart from the estimate.
struct VehicleGeometry {
  double wheelbase_m = 1.53;
  double max_steer_rad = 0.6283;
  /// How fast the steering turns, rad/s.
  double max_steer_rate_rps = 2.5;
  /// Distance from the reference point (rear axle centre) forward to the front wing, metres.
  double rear_axle_to_front_m = 2.25;
  /// Distance from the rear axle back to the rear end of the car, and the car's width, metres.
  double rear_axle_to_back_m = 0.65;
  double width_m = 1.4;
  /// Yaw rate at a steering angle over the kinematic v tan(d) / L at low speed: the front tyres
  /// of an anti-Ackermann car fight at large angles, so the car turns wider than the kinematic
  /// radius (full lock: 2.9 m at the rear axle, not 2.1). Pairs of (angle rad, gain), angles
  /// rising. These are the default car's, as sim::measure_yaw_gain measures them in MuJoCo
  /// (tests/sim/vehicle_sim_test.cpp holds the two equal); `conesim run` measures any other car.
  std::vector<std::pair<double, double>> yaw_gain = {
      {0.0, 1.0},      {0.1047, 0.998}, {0.2094, 0.929}, {0.3141, 0.870},
      {0.4189, 0.818}, {0.5236, 0.769}, {0.6283, 0.721}};
  /// What the car can do over speed at its full measured grip; the driver plans with
  /// DriverParams::grip_fraction of it.
  vehicle_models::PerformanceEnvelope envelope;
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
  /// Why the driver cannot go on as planned (e.g. "no path through the cones ahead"); empty
  /// while all is well. The run appends it to a DNF reason.
  std::string problem;
  /// Times the racing line was planned again because the map moved under it (a loop closure).
  int line_replans = 0;
};

/// Acceleration: how far past the finish line the front of the car comes to rest at most when
/// it crosses the line at `finish_speed_mps` (the driver brakes just past the line, or earlier
/// so as to stop inside FSG's braking zone less a margin), metres.
double acceleration_stop_past_finish_m(const DriverParams& params, const VehicleGeometry& vehicle,
                                       double finish_speed_mps);

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
