#pragma once
// The referee: FSG competition logic on ground truth. Timing from the first time-keeping gate,
// laps at the gates, cones hit (+2 s, the cone is knocked over), off-course (+10 s), DNF with a
// reason, and each event's finish rule.
//
// Conventions (see referee.cpp for the details):
// - A gate is crossed when the front wing point (rear axle + front_overhang_from_rear_axle_m
//   along the heading) crosses the gate segment in the driving direction; the crossing time is
//   interpolated between physics steps. Crossings backwards are owed and cancel the next forward
//   crossing. A track without gates gets one across the centre line just ahead of the start
//   (skidpad: kSkidpadStartToTimingLineM ahead; acceleration: a finish gate 75 m further on).
// - Open layouts driven as autocross (point-to-point courses) finish at the track's last gate,
//   or at a gate across the ends of their lanes; one pass is their lap.
// - Timeouts run from the first gate crossing; until the car reaches it they run from the run
//   start (the first update), so a car that never reaches the line is DNF too.
// - Off-course (all four wheels outside) is judged from the first gate crossing to the end.
//   A wheel is on the track when its contact patch lies between the lanes (tracks::TrackArea:
//   circuits between the closed lanes, open layouts between the lanes extended 10 m past their
//   ends); skidpad: within 1.65 m (the cone lines) of the circles of radius 9.125 m or of the
//   entry/exit lane, built from the timing gate.
// - Every cone hit, off-course and DNF is kept as an event with its time, lap and place.

#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/cone.hpp"
#include "core/event.hpp"
#include "core/time.hpp"
#include "sim/vehicle_sim.hpp"
#include "tracks/track.hpp"
#include "vehicle_models/vehicle_params.hpp"

namespace conesim::sim {

/// Penalties, time limits and thresholds (FSG handbook DV rules; PacSim's competition logic).
struct RefereeParams {
  double cone_penalty_s = 2.0;
  /// Skidpad's cone penalty is smaller (FSG handbook D 5: 0.2 s per cone down or out; PacSim).
  double cone_penalty_skidpad_s = 0.2;
  double off_course_penalty_s = 10.0;
  double timeout_acceleration_s = 25.0;
  double timeout_skidpad_s = 90.0;
  double timeout_autocross_s = 300.0;
  double timeout_trackdrive_first_lap_s = 300.0;
  double timeout_trackdrive_total_s = 1000.0;
  /// DNF "stuck": slower than stuck_speed_mps for stuck_time_s before the finish (the timer runs
  /// from the run start, so a car that never moves is stuck too). "stopped early" instead when
  /// the car has completed a lap but not the event's laps.
  double stuck_speed_mps = 0.2;
  double stuck_time_s = 15.0;
  /// DNF "left the track": farther than this from the track's centre line and every cone, metres.
  double left_track_distance_m = 10.0;
  /// Below this speed for stop_time_s the car counts as stopped (finish rules), m/s and s.
  double stopped_speed_mps = 0.1;
  double stopped_time_s = 0.5;
  /// After the last timed lap the car must stop within this time, else DNF "did not stop"
  /// (PacSim: 30 s), seconds.
  double stop_window_s = 30.0;
  /// Trackdrive laps.
  int trackdrive_laps = 10;

  /// Empty when every value is usable; otherwise "key: what was expected" for the first bad one.
  std::string validate() const;
};

/// One thing the referee ruled on during the run, where and when it happened.
struct RefereeEvent {
  enum class Kind { kConeHit, kOffCourse, kDnf };
  Kind kind = Kind::kConeHit;
  /// Sim time of the event, seconds.
  double t_s = 0.0;
  /// The lap in progress: 0 before the timing starts, then laps counted + 1.
  int lap = 0;
  /// The car's rear-axle pose at the event.
  core::Pose2 pose;
  /// What happened and where, for people: "hit blue cone 17 at (3.20, -1.50)".
  std::string reason;
  /// Time added for it, seconds (0 for a DNF).
  double penalty_s = 0.0;
  /// Cone hits: the cone's id (tracks::Cone::id), the id its file gave it
  /// (tracks::Track::file_id: what outputs show), class and position.
  int cone_id = -1;
  uint64_t cone_file_id = 0;
  core::ConeClass cone_class = core::ConeClass::kUnknown;
  core::Vec2 cone_position = core::Vec2::Zero();
  /// Off-course: the four contact patches (FL, FR, RL, RR) when the car went off, and how long
  /// it stayed off (until the end of the run when it never came back), seconds.
  std::array<core::Vec2, 4> wheels{};
  double duration_s = 0.0;
};

/// The name of an event kind in metrics.json: "cone_hit", "off_course", "dnf".
const char* to_string(RefereeEvent::Kind kind);

/// What the referee decided (copied into metrics.json).
struct RefereeResult {
  bool completed = false;
  /// Empty unless DNF: what ended the run and where the car's footprint centre was, e.g.
  /// "stuck at (12.3, -4.5)". The kinds: "timeout", "timeout (first lap)", "stuck", "stopped
  /// early", "left the track", "overran braking zone", "wrong direction", "did not stop".
  std::string dnf_reason;
  /// Laps counted at the gate (acceleration: 1 once the finish gate is crossed).
  int laps = 0;
  /// Every lap's time, seconds (skidpad: all four laps, the timed ones are the 2nd and 4th).
  std::vector<double> lap_times_s;
  /// Ids of the cones knocked over, in the order they were hit.
  std::vector<int> cones_hit;
  int off_course = 0;
  /// Every cone hit, off-course and DNF in the order they happened.
  std::vector<RefereeEvent> events;
  /// Raw time from the first gate to the finish (or to the end of the run), seconds. Skidpad:
  /// the average of the timed laps (the second right and the second left lap).
  double raw_time_s = 0.0;
  /// Cone and off-course penalties, seconds.
  double penalty_s = 0.0;
  /// Raw time plus penalties.
  double final_time_s = 0.0;
};

/// One referee per run. update() is called after every physics step with the true state.
class Referee {
 public:
  /// Prepares the judging of one run of `event` on `track` (gates, boundaries, cone index).
  /// Throws std::invalid_argument when params or vehicle do not validate.
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

  /// The FSG off-course rule applied to one state: true when all four wheels' contact patches
  /// lie outside the track's boundaries (whether or not the car is being timed).
  bool all_wheels_off(const VehicleTruth& truth) const;

  /// True when the cone with this id has been knocked over (hidden from sensors and renders).
  bool is_knocked(int cone_id) const;

  /// Laps the referee has counted so far (for the progress line).
  int laps() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace conesim::sim
