#pragma once
// The referee: FSG competition logic on ground truth. Timing from the first time-keeping gate,
// laps at the gates, cones hit (+2 s, the cone is knocked over), off-course (+10 s), DNF with a
// reason, and each event's finish rule.

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/event.hpp"
#include "core/time.hpp"
#include "sim/vehicle_sim.hpp"
#include "tracks/track.hpp"
#include "vehicle_models/vehicle_params.hpp"

namespace conesim::sim {

/// Penalties, time limits and thresholds (FSG handbook DV rules; PacSim's competition logic).
struct RefereeParams {
  double cone_penalty_s = 2.0;
  double off_course_penalty_s = 10.0;
  double timeout_acceleration_s = 25.0;
  double timeout_skidpad_s = 90.0;
  double timeout_autocross_s = 300.0;
  double timeout_trackdrive_first_lap_s = 300.0;
  double timeout_trackdrive_total_s = 1000.0;
  /// DNF "stuck": slower than stuck_speed_mps for stuck_time_s after the car has started.
  double stuck_speed_mps = 0.2;
  double stuck_time_s = 15.0;
  /// DNF "left the track": farther than this from the track's centre line, metres.
  double left_track_distance_m = 10.0;
  /// Below this speed for stop_time_s the car counts as stopped (finish rules), m/s and s.
  double stopped_speed_mps = 0.1;
  double stopped_time_s = 0.5;
  /// Trackdrive laps.
  int trackdrive_laps = 10;
};

/// What the referee decided (copied into metrics.json).
struct RefereeResult {
  bool completed = false;
  /// Empty unless DNF: "timeout", "stuck", "left the track", "stopped early", ...
  std::string dnf_reason;
  int laps = 0;
  std::vector<double> lap_times_s;
  /// Ids of the cones knocked over, in the order they were hit.
  std::vector<int> cones_hit;
  int off_course = 0;
  /// Raw time from the first gate to the finish (or to the end of the run), seconds.
  double raw_time_s = 0.0;
  /// Raw time plus penalties.
  double final_time_s = 0.0;
};

/// One referee per run. update() is called after every physics step with the true state.
class Referee {
 public:
  Referee(const tracks::Track& track, core::EventType event,
          const vehicle_models::VehicleParams& vehicle, const RefereeParams& params = {});
  ~Referee();
  Referee(const Referee&) = delete;
  Referee& operator=(const Referee&) = delete;

  /// Judges the state at sim time t.
  void update(core::TimeUs t, const VehicleTruth& truth);

  /// True once the event is over: completed or DNF.
  bool finished() const;

  /// The verdict so far.
  const RefereeResult& result() const;

  /// True when the cone with this id has been knocked over (hidden from sensors and renders).
  bool is_knocked(int cone_id) const;

  /// Laps the referee has counted so far (for the progress line).
  int laps() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace conesim::sim
