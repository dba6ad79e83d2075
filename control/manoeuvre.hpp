#pragma once
// Steering through turns near full lock by trying it out. In a hairpin at the car's tightest
// circle the steering is saturated, so a path tracker has no authority left: where the car ends
// up is decided by when it turns in, and a few tenths of a metre decide whether the front corner
// sweeps the outer cones. Here the driver rolls candidate manoeuvres forward on its own model of
// the car (kinematic bicycle with the measured yaw gain, the steering rate limit and the planned
// speed) and picks the one that keeps the whole footprint clearest of the cones while getting on
// along the path: follow the path, or turn in at full lock now or a little later, hold the lock
// for a while, and follow the path again.

#include <functional>
#include <utility>
#include <vector>

#include "control/path.hpp"
#include "control/pure_pursuit.hpp"
#include "control/racing_line.hpp"
#include "core/autonomy_types.hpp"

namespace conesim::control {

/// The car model and the candidates.
struct ManoeuvreParams {
  double wheelbase_m = 1.53;
  double max_steer_rad = 0.6283;
  double max_steer_rate_rps = 2.5;
  /// Yaw gain over steering angle (see TrackerParams::yaw_gain).
  std::vector<std::pair<double, double>> yaw_gain;
  /// The path tracker the candidates follow before and after holding full lock, with the
  /// curvature it feeds forward read `preview_s` ahead and averaged over `curvature_span_m`
  /// (as the driver does: see curvature_near).
  TrackerParams tracker;
  double preview_s = 0.12;
  double curvature_span_m = 2.0;
  /// The footprint checked (its margin is not used: clearance is scored, not required).
  Footprint footprint;
  /// Horizon of the roll-outs, their time step over the first fine_s and after it, s.
  double horizon_s = 3.5;
  double step_s = 0.05;
  double fine_s = 2.0;
  double coarse_step_s = 0.1;
  /// Candidates wait this long, following the path or steering straight, before they turn in, s.
  std::vector<double> wait_s = {0.0, 0.1, 0.2, 0.35, 0.5};
  /// ... and hold full lock this long, s.
  std::vector<double> hold_s = {0.5, 1.0, 1.5, 2.0, 2.5, 3.0};
  /// Lag of the car's turning behind the steering (servo, tyres), first order, s: the default
  /// car's, fitted to the MuJoCo car's path (tests/sim/vehicle_sim_test.cpp: a steering step at
  /// 8-16 m/s, and turn-ins to full lock at 3-4 m/s).
  double steer_lag_s = 0.04;
  /// The car's braking and speeding-up limits at low speed, m/s^2.
  double max_decel_mps2 = 8.0;
  double max_accel_mps2 = 5.0;
  /// Clearance beyond this counts no more, metres.
  double enough_clearance_m = 0.35;
};

/// The car as the roll-outs model it: a kinematic bicycle (rear axle pose) whose steering moves
/// towards the command at its rate, whose turning follows the steering with a first-order lag,
/// and whose yaw rate is scaled by the yaw gain.
struct RolloutCar {
  core::Pose2 pose;
  /// The steering's angle, and the angle the car turns with (lagging it), radians.
  double steer = 0.0;
  double wheels = 0.0;
  /// Moves the car on for `dt_s` at `speed_mps` with the steering command held at `command`.
  void step(const ManoeuvreParams& params, double command, double speed_mps, double dt_s);
};

/// A manoeuvre: follow the path (or steer straight) for `wait_s`, then full lock towards
/// `side` (+1 left, -1 right) for `hold_s`, then follow the path; wait_s < 0: follow the path
/// throughout.
struct Manoeuvre {
  double wait_s = -1.0;
  double hold_s = 0.0;
  double side = 0.0;
  bool straight = false;

  /// The same manoeuvre `dt_s` later.
  Manoeuvre advanced(double dt_s) const;
};

/// The chosen steering and what its roll-out promised.
struct ManoeuvreChoice {
  /// The manoeuvre chosen.
  Manoeuvre manoeuvre;
  /// Steering to command now, radians.
  double steer_rad = 0.0;
  /// Smallest footprint clearance to a cone along the roll-out, metres (negative: a cone inside
  /// the footprint by that much).
  double clearance_m = 0.0;
  /// Whether the choice is the path tracker's own.
  bool nominal = true;
};

/// The driver's speed command (m/s^2) at speed v (m/s) with the car at arc length s (m) along
/// the path: the roll-outs' speed follows what the driver would command.
using SpeedCommand = std::function<double(double v, double s)>;

/// Picks the steering for the car at `pose`, speed `speed_mps`, steering now at
/// `steer_now_rad`, on `path` (the car projects onto it at `here`), its speed following
/// `speed_command`, past `cones` (map frame). The tracker's own
/// command (`nominal_steer_rad`, what following the path gives) wins unless a manoeuvre keeps
/// the footprint clearer; `previous` (the manoeuvre under way, advanced to now) is a candidate
/// too and wins ties, so that the car carries a manoeuvre through rather than dither.
ManoeuvreChoice choose_manoeuvre(const ManoeuvreParams& params, const core::Pose2& pose,
                                 double speed_mps, double steer_now_rad, const Path& path,
                                 const PathProjection& here, const SpeedCommand& speed_command,
                                 const std::vector<core::MapCone>& cones, double nominal_steer_rad,
                                 const Manoeuvre* previous = nullptr);

/// Signed distance between the footprint with the rear axle at `pose` and the nearest cone's
/// base, metres: negative when a cone's base reaches into the footprint (by that much).
double signed_footprint_clearance(const core::Pose2& pose, const std::vector<core::MapCone>& cones,
                                  const Footprint& footprint);

}  // namespace conesim::control
