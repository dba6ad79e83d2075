#include "control/driver.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>

#include "control/drivability.hpp"
#include "control/lap_line.hpp"
#include "control/manoeuvre.hpp"
#include "control/path.hpp"
#include "control/path_planner.hpp"
#include "control/pure_pursuit.hpp"
#include "control/racing_line.hpp"
#include "control/skidpad_plan.hpp"
#include "control/speed_profile.hpp"
#include "control/straight_course.hpp"

namespace conesim::control {

namespace {

using core::EventType;
using core::MapCone;
using core::Pose2;
using core::Vec2;
using core::VehicleCommand;

// the car counts as stopped below this speed, m/s
constexpr double kStoppedSpeedMps = 0.3;
// the speed target is read this far ahead in time, to make up for the actuator lag, s.
// Measured on the eleven competition circuits (ground truth, grip 0.7): 0.1 s with a speed gain
// of 4/s puts the best lap 2-5 % closer to the lap-time bound than 0.2 s with 2/s (the car
// braked a preview's distance early and answered its speed error slowly), with no cone hit
constexpr double kSpeedPreviewS = 0.1;
// where the profile falls the target is read this far ahead while exploring: braking into a
// minimum hairpin at the end of a long straight, 0.1 s reached the turn-in at 6 m/s instead of 3
// (generated hard profile, seeds 32, 83, 95), and the braking is gentler while SLAM maps (with
// 0.1 s on lap 1 GraphSLAM's maps of four EPFL circuits at seed 2 were 0.17-0.20 m off instead of
// 0.07-0.15 m). The fast laps read their target kSpeedPreviewS ahead but into the tight turns:
// 0.2 s braked about 0.2 v metres early into every corner (the PacSim circuits' best laps 1-2 %
// slower).
constexpr double kBrakePreviewS = 0.2;
// on the fast laps the longer preview is kept where the target falls below this multiple of the
// tight-turn speed: from 31 m/s into a minimum hairpin the short one reached the turn-in at
// 3.9 m/s instead of 3 and passed a cone with 11 mm (the kinematic loop on generated seed 7059;
// 0.13 m with this, as with the longer preview everywhere; that entry is on a knife's edge: 2 and
// 4 gave 0.03 m, 3 gave 0.12 m)
constexpr double kTightEntryShare = 2.5;
// the share of the steering's rate the speed profile plans curvature changes with
constexpr double kCurvatureRateShare = 0.8;
// on the circuits the envelope limits the speed profile; the command and braking are capped
// only this high (the car limits itself), and the lateral acceleration this high, m/s^2
constexpr double kCircuitLongitudinalCapMps2 = 15.0;
constexpr double kCircuitLateralCapMps2 = 30.0;
// the path's curvature is read this far ahead in time for the steering lag, s, and averaged
// over this span either side, metres
constexpr double kSteerPreviewS = 0.12;
// on the racing line (fast laps): a shorter preview and stiffer error dynamics (rad/m, capped
// at rad/s). Measured: the kinematic loop's tracking error on generated circuits fell from
// 0.27 m (0.12 s, 0.5/m, 3/s) to 0.10-0.25 m, the MuJoCo car's footprint clearance on PacSim
// FSE22 rose from 0.14 to 0.30 m; the same gains while exploring hit a cone on FSE22 lap 1
constexpr double kFastSteerPreviewS = 0.08;
constexpr double kFastFrequencyPerM = 0.6;
constexpr double kFastMaxFrequencyRps = 4.0;
constexpr double kCurvatureSpanM = 1.0;
// the car joins the racing line after lap 1 over this time at its speed (at least the
// distance), metres and seconds, and follows the line itself this far past the join
constexpr double kJoinMinM = 10.0;
constexpr double kJoinS = 2.0;
constexpr double kJoinPastM = 2.0;
// the racing line is planned again once a cone of the map it was planned from has moved this
// far (checked this often), and the car joins the new one over this time at its speed, metres
// and seconds
constexpr double kReplanMapMoveM = 0.05;
constexpr double kReplanCheckS = 0.5;
constexpr double kReplanJoinS = 1.0;
// ... where the line (over the join and a little behind the car) bends less than this, or after
// this wait at the latest, 1/m and seconds. The join bends the path where the car may have its
// grip in use: on fssim FSI with the LiDAR (seed 2) the car joined the line from lap 1 at a
// hairpin's exit (at 5 m/s, 3 m/s under the line's profile, accelerating at 15 m/s^2), ran 0.3 m
// off the line and hit a cone; a line planned again joins only where it is as calm
constexpr double kReplanMaxCurvature = 0.1;
constexpr double kReplanMaxWaitS = 5.0;
constexpr double kReplanBehindM = 2.0;
// the car switches to the racing line where its lap-1 path comes this close to it and this
// nearly parallel, or after this distance at the latest, metres and radians
constexpr double kJoinCloseM = 0.2;
constexpr double kJoinHeadingRad = 0.1;
constexpr double kJoinWaitM = 50.0;
// ... but where the line bends less than kReplanMaxCurvature near the car, unless it has waited
// this far
constexpr double kJoinMaxWaitM = 150.0;
// the feed-forward acceleration is the profile's slope over this distance, metres
constexpr double kFeedForwardSpanM = 1.0;
// cones within this distance of the car feed the local planner, metres
constexpr double kPlanningRadiusM = 30.0;
// a perceived cone this close to a map cone is that cone, metres
constexpr double kSameConeM = 0.7;
// local path length ahead of the car while exploring, metres
constexpr double kExploreHorizonM = 25.0;
// a local path shorter than this is not trusted: the previous one is kept, metres
constexpr double kMinLocalPathM = 4.0;
// a local path shorter than this ends where the cones end (the end of an open course): the car
// plans to stop at its end, metres
constexpr double kCourseEndPathM = 15.0;
// share of the braking limit planned for stopping at the end of the known path
constexpr double kEndOfPathDecelShare = 0.5;
// after the last lap on the racing line the car stops within this multiple of its straight-line
// braking distance plus kStopExtraM (room for the bends on the way, where braking shares the
// grip with turning), metres
constexpr double kStopRoomShare = 1.5;
constexpr double kStopExtraM = 10.0;
// a lap counts only after this distance since the previous one (or the start), metres (the
// racing line of eufs peanut is under 100 m)
constexpr double kMinLapDistanceM = 50.0;
// a steering command this share of full lock or more slows the car to the tight-turn speed
constexpr double kSteerSaturationShare = 0.9;
// the racing line keeps under this share of full lock's curvature where its corridor leaves
// room, below the share from which the car slows to the tight-turn speed (speed_profile.cpp)
constexpr double kLineCurvatureShare = 0.7;
// a path that asks for this share of the steering's curvature within the distance ahead, or
// steering this share of full lock now, hands the steering to the manoeuvre search
constexpr double kManoeuvreCurvatureShare = 0.75;
constexpr double kManoeuvreSteerShare = 0.6;
// steering near lock hands over only up to this speed, where the car turns as its kinematic model
// says (faster, the tracker is in a transient and the tyres may slide), m/s
constexpr double kManoeuvreMaxSpeedMps = 6.0;
// the manoeuvre search looks this far ahead at least, metres, and over this time, s
constexpr double kManoeuvreAheadM = 6.0;
constexpr double kManoeuvreAheadS = 1.5;
// a lane narrower than this (below the rules' 3 m by more than any shared competition layout,
// 2.65 m at their narrowest) leaves the car too little room either side for its tracking error
// at speed: on the fast laps the line within kNarrowLaneReachM of a cone that close to the other
// boundary is driven at kNarrowLaneSpeedMps at most. Measured on EUFS small_track_2 (a 2.3 m gap
// between a cone and the other boundary, into a near-full-lock bend): uncapped, the car entered
// at 8.9 m/s, ran 0.33 m wide of the line and its front corner hit the gap's entry cone; capped at
// 8, 7 or 6 m/s within 3 m it kept 0.02-0.05 m, within 5 m 0.05, 0.14 and 0.11 m (lap +0.1 s)
constexpr double kNarrowLaneM = 2.5;
constexpr double kNarrowLaneReachM = 5.0;
constexpr double kNarrowLaneSpeedMps = 7.0;
// the circuit from the map must pass within this of every point of the lap the car drove, and
// each closed boundary within kLapOffBoundaryM: the car drives inside the lanes, so a correct
// centre line is at most half a lane away (FSG lanes are 3-5 m wide; 4 m leaves room for a car
// hugging one side of an 8 m lane) and a boundary at most a lane
constexpr double kLapOffCircuitM = 4.0;
constexpr double kLapOffBoundaryM = 8.0;
// the lap line is searched among the big orange cones while the car is this close to the
// start (by distance travelled), metres
constexpr double kLapLineSearchOdometerM = 40.0;
// after the last lap the car runs on this far before braking (past the time-keeping gate, which
// PacSim tracks put up to 8 m beyond the start pose), metres
constexpr double kRunOutAfterFinishM = 12.0;
// half length of the assumed line through the front wing when no big orange cone is known
constexpr double kFallbackLineHalfWidthM = 4.0;
// progress along a long path is searched this many segments behind and ahead of the last one
constexpr size_t kProgressBehind = 4;
constexpr size_t kProgressWindow = 60;
// the trace of lap 1 is recorded every this distance (fallback circuit), metres
constexpr double kTraceStepM = 0.5;
// acceleration: distance from the start line to the finish line and the braking zone's length
// (FSG handbook), and how far past the finish line the rear axle is before braking, metres
constexpr double kAccelerationLengthM = 75.0;
constexpr double kBrakingZoneM = 75.0;
constexpr double kBrakePastFinishM = 1.0;
// acceleration: big orange cones beyond this distance from the start belong to the finish gate
constexpr double kFinishGateSearchM = 40.0;
// acceleration: margin kept before the end of the braking zone, and share of the braking limit
// assumed when checking that the car can still stop in it
constexpr double kBrakingZoneMarginM = 10.0;
constexpr double kBrakingZoneDecelShare = 0.8;
// acceleration: the course path reaches this far ahead of the car, metres
constexpr double kCourseAheadM = 60.0;
// skidpad: the rear axle stops this far past the timing line (the stop line is 21 m out); the
// rear must clear the circles (10.8 m) even when the car holds up to kSkidpadStopToleranceM short
constexpr double kSkidpadStopAfterM = 16.0;
// skidpad: close enough to the stop point to hold the car once slow, metres
constexpr double kSkidpadStopToleranceM = 4.0;
// skidpad laps: two right, two left
constexpr int kSkidpadLaps = 4;

// what the mission is doing
enum class Phase { kLaunch, kSkidpad, kExplore, kFast, kBraking, kStopped };

// short name of a phase for the status line
const char* phase_name(Phase p) {
  switch (p) {
    case Phase::kLaunch:
      return "launch";
    case Phase::kSkidpad:
      return "skidpad";
    case Phase::kExplore:
      return "explore";
    case Phase::kFast:
      return "fast";
    case Phase::kBraking:
      return "braking";
    case Phase::kStopped:
      return "stopped";
  }
  return "unknown";
}

// the map cones near the car plus the perceived cones not yet in the map, in the map frame
std::vector<MapCone> cones_near(const core::Estimate& estimate,
                                const core::ConeObservations& observations, double radius_m) {
  std::vector<MapCone> cones;
  const Vec2 here = estimate.pose.position();
  for (const MapCone& c : estimate.map)
    if ((c.position - here).norm() <= radius_m) cones.push_back(c);
  const size_t from_map = cones.size();
  for (const core::ConeObservation& o : observations.cones) {
    const Vec2 p = estimate.pose.transform(o.position);
    bool known = false;
    for (size_t i = 0; i < from_map && !known; ++i)
      known = (cones[i].position - p).norm() < kSameConeM;
    if (!known) cones.push_back({-1, o.cls, p, o.covariance});
  }
  return cones;
}

}  // namespace

struct Driver::Impl {
  // fixed for the run
  EventType event;
  DriverParams params;
  VehicleGeometry vehicle;
  std::vector<MapCone> prior_map;
  PlannerParams planner;
  PurePursuitParams pursuit;
  TrackerParams tracker;
  TrackerParams fast_tracker;
  ManoeuvreParams manoeuvre;
  // the car's limits at the grip fraction planned for, and its footprint with the margin
  vehicle_models::PerformanceEnvelope envelope;
  Footprint footprint;

  // mission state
  DriverStatus status;
  Phase phase = Phase::kExplore;
  bool started = false;
  Pose2 start;
  Vec2 last_position = Vec2::Zero();
  Vec2 last_front = Vec2::Zero();
  // the driver's model of the steering actuator: the angle now and the last command
  double steer_now = 0.0;
  double last_steer_command = 0.0;
  // how far the steering moved over the last update at its rate (the next one's reach), rad
  double steer_reach = 0.0;
  core::TimeUs last_stamp = 0;
  // the input of the update in progress
  const DriverInput* input = nullptr;
  // the manoeuvre under way near full lock, and when it was chosen
  std::optional<Manoeuvre> manoeuvre_now;
  core::TimeUs manoeuvre_stamp = 0;

  // the path followed, its speed profile and the car's progress along it
  Path path;
  // the fast laps' line, and the odometer reading up to which the car is still joining it
  Path racing_line;
  // its speed caps where the lane is narrow (empty: none)
  std::vector<double> racing_line_caps;
  std::optional<double> join_until_m;
  // the odometer reading when lap 1 ended, while the car has yet to reach the racing line
  std::optional<double> join_pending_since_m;
  // the map the racing line was planned from (id and position), and when it was last compared
  // with the estimate's
  std::vector<std::pair<int, Vec2>> line_map;
  core::TimeUs line_map_checked = 0;
  SpeedProfile profile;
  double lap_m = 0.0;
  size_t progress_segment = 0;
  bool track_progress = false;

  // lap counting on the start/finish line, and the trace of lap 1
  LapLine lap_line;
  double odometer_at_lap = 0.0;
  // after the last lap the car runs on this far (odometer) before it brakes
  std::optional<double> run_out_until_m;
  std::vector<Vec2> trace;
  std::optional<size_t> trace_lap_start;
  // the trace of lap 1 alone, taken when lap 1 ended
  std::vector<Vec2> lap_trace;

  // skidpad lap ends; acceleration finish line (along the start heading)
  std::vector<double> skidpad_lap_end_s;
  double skidpad_stop_s = 0.0;
  double finish_x_m = 0.0;

  Impl(EventType e, const DriverParams& p, const VehicleGeometry& v, std::vector<MapCone> prior)
      : event(e), params(p), vehicle(v), prior_map(std::move(prior)) {
    planner.assumed_half_width_m = p.assumed_half_width_m;
    pursuit = {v.wheelbase_m, v.max_steer_rad, p.lookahead_min_m, p.lookahead_gain_s};
    tracker.wheelbase_m = v.wheelbase_m;
    tracker.max_steer_rad = v.max_steer_rad;
    tracker.yaw_gain = v.yaw_gain;
    // the known racing line is held more tightly: its path does not start at the car
    fast_tracker = tracker;
    fast_tracker.frequency_per_m = kFastFrequencyPerM;
    fast_tracker.max_frequency_rps = kFastMaxFrequencyRps;
    // the grip fraction scales the tyre friction and with it the traction-limited drive force
    // (exact for a car whose drive is grip-limited at full grip, as the default car's is;
    // cautious otherwise)
    envelope = v.envelope;
    envelope.friction *= p.grip_fraction;
    envelope.max_drive_force_n *= p.grip_fraction;
    footprint = {v.rear_axle_to_front_m, v.rear_axle_to_back_m, 0.5 * v.width_m,
                 p.footprint_margin_m};
    // the racing line keeps the larger margin about the turns the manoeuvre search takes
    footprint.tight_margin_m = p.tight_turn_margin_m;
    footprint.tight_curvature = kManoeuvreCurvatureShare / full_lock_radius_m(v);
    manoeuvre.wheelbase_m = v.wheelbase_m;
    manoeuvre.max_steer_rad = v.max_steer_rad;
    manoeuvre.max_steer_rate_rps = v.max_steer_rate_rps;
    manoeuvre.yaw_gain = v.yaw_gain;
    manoeuvre.footprint = footprint;
  }

  // one update: bookkeeping, then the event's mission
  VehicleCommand update(const DriverInput& in) {
    const Pose2& pose = in.estimate.pose;
    if (!started) begin(in);
    input = &in;
    // the steering moved towards the last command at its rate since the last update
    const double dt = std::max(0.0, core::to_seconds(in.estimate.stamp - last_stamp));
    const double max_change = vehicle.max_steer_rate_rps * dt;
    steer_now = steer_towards(last_steer_command, max_change);
    steer_reach = max_change;
    last_stamp = in.estimate.stamp;
    const Vec2 front = pose.transform({vehicle.rear_axle_to_front_m, 0.0});
    status.odometer_m += (pose.position() - last_position).norm();

    VehicleCommand cmd;
    switch (event) {
      case EventType::kAcceleration:
        cmd = acceleration(in);
        break;
      case EventType::kSkidpad:
        cmd = skidpad(in);
        break;
      case EventType::kAutocross:
      case EventType::kTrackdrive:
        cmd = circuit(in, front);
        break;
    }

    // braking ends in a held stop
    if (phase == Phase::kBraking && std::abs(in.estimate.speed_mps) < kStoppedSpeedMps)
      phase = Phase::kStopped;
    if (phase == Phase::kStopped) {
      status.finished = true;
      cmd.accel_mps2 = -decel_cap();
      cmd.hold_stopped = true;
      status.target_speed_mps = 0.0;
    }
    status.state = phase_name(phase);
    last_steer_command = std::clamp(cmd.steer_rad, -vehicle.max_steer_rad, vehicle.max_steer_rad);
    input = nullptr;
    last_position = pose.position();
    last_front = front;
    return cmd;
  }

  // the first update: the start pose and the mission's initial plan
  void begin(const DriverInput& in) {
    started = true;
    start = in.estimate.pose;
    last_position = start.position();
    last_stamp = in.estimate.stamp;
    last_front = start.transform({vehicle.rear_axle_to_front_m, 0.0});
    lap_line = lap_line_at(last_front, start, kFallbackLineHalfWidthM);
    switch (event) {
      case EventType::kAcceleration:
        phase = Phase::kLaunch;
        finish_x_m = kAccelerationLengthM + vehicle.rear_axle_to_front_m;
        break;
      case EventType::kSkidpad:
        begin_skidpad(in);
        break;
      case EventType::kAutocross:
      case EventType::kTrackdrive:
        phase = Phase::kExplore;
        break;
    }
  }

  // whether the car follows the racing line: the fast laps, and the stop after the last
  bool on_racing_line() const {
    return phase == Phase::kFast || (phase == Phase::kBraking && path.closed);
  }

  // steering along the current path, and the speed command towards its profile
  VehicleCommand follow(const core::Estimate& est, double speed_cap) {
    VehicleCommand cmd;
    if (path.points.size() < 2) {
      status.target_speed_mps = 0.0;
      cmd.accel_mps2 = -decel_cap() * kEndOfPathDecelShare;
      return cmd;
    }

    // where the car is on the path: a window ahead of the last progress on long paths
    PathProjection here;
    if (track_progress) {
      const size_t n = path.segment_count();
      size_t first = progress_segment >= kProgressBehind ? progress_segment - kProgressBehind : 0;
      if (path.closed) first = (progress_segment + n - kProgressBehind) % n;
      here = project_onto(path, est.pose.position(), first, kProgressWindow);
      progress_segment = here.segment;
    } else {
      here = project_onto(path, est.pose.position(), 0, path.segment_count());
    }
    const std::vector<double> s = path.arc_lengths();
    const double s_here = s[here.segment] + here.t * (s[here.segment + 1] - s[here.segment]);
    status.target_speed_mps = speed_command_target(est.speed_mps, s_here);

    // steering: the circuits track the path's curvature with feedback on the errors, the
    // other events aim with pure pursuit; then the speed command
    if (event == EventType::kAutocross || event == EventType::kTrackdrive) {
      // the stop after the last lap runs along the racing line at the fast laps' speeds: with
      // the exploration's slower tracker the car cut 0.15 m inside the first bend past the
      // finish (the slalom of tests/control at 15 m/s, in the kinematic loop before it had the
      // steering lag)
      const bool fast = on_racing_line();
      const double preview_s = fast ? kFastSteerPreviewS : kSteerPreviewS;
      const double ahead = s_here + preview_s * std::max(0.0, est.speed_mps);
      const std::vector<double> k = curvatures(path.points, path.closed);
      cmd.steer_rad = track_path(fast ? fast_tracker : tracker, est.pose, est.speed_mps, path, here,
                                 curvature_near(path, s, k, ahead, 2.0 * kCurvatureSpanM));
      // near full lock: the manoeuvre that keeps the footprint clearest, tried out
      if (input && tight_ahead(s, k, s_here, est.speed_mps)) {
        const double reach = std::max(est.speed_mps, 8.0) * manoeuvre.horizon_s + 4.0;
        std::optional<Manoeuvre> previous;
        if (manoeuvre_now)
          previous = manoeuvre_now->advanced(core::to_seconds(est.stamp - manoeuvre_stamp));
        ManoeuvreParams mp = manoeuvre;
        mp.tracker = fast ? fast_tracker : tracker;
        mp.preview_s = preview_s;
        mp.curvature_span_m = 2.0 * kCurvatureSpanM;
        const ManoeuvreChoice choice = choose_manoeuvre(
            mp, est.pose, est.speed_mps, steer_now, path, here,
            [&](double v, double at) { return speed_command(v, at, speed_cap); },
            cones_near(est, input->observations, reach), cmd.steer_rad,
            previous ? &*previous : nullptr);
        manoeuvre_now = choice.manoeuvre;
        manoeuvre_stamp = est.stamp;
        cmd.steer_rad = choice.steer_rad;
      } else {
        manoeuvre_now.reset();
      }
    } else {
      cmd.steer_rad = pure_pursuit(pursuit, est.pose, est.speed_mps, path, here).steer_rad;
    }
    // steering near full lock: slow to the tight-turn speed, where the car still turns as
    // steered (the path may curve less than the car must turn to come back onto it)
    if (std::abs(cmd.steer_rad) >= kSteerSaturationShare * vehicle.max_steer_rad)
      speed_cap = std::min(speed_cap, SpeedLimits{}.tight_turn_speed_mps);
    cmd.accel_mps2 = speed_command(est.speed_mps, s_here, speed_cap);
    if (circuit_event()) cmd.accel_mps2 = std::min(cmd.accel_mps2, exit_accel_cap(est, cmd));
    return cmd;
  }

  // the tyres' grip is shared between turning and driving: out of a turn the car accelerates
  // with what the turn's lateral acceleration leaves of the grip (by the friction ellipse at the
  // car's full grip), none when the steering asks for more than the tyres hold (the car running
  // wide). The turn is the larger of the wheels' angle now and the angle they reach over the
  // next update (moved towards the command at the steering's rate). The command itself jumps
  // beyond what the wheels reach and cut the drive tick by tick (in the kinematic loop the
  // footprint came 0.04 m closer to a cone on hard circuit 7195); the angle now alone, or the one
  // reached alone, each hit a cone on one GraphSLAM run of the shared corpus (FSG19 seed 3,
  // FSE23 seed 1), where their S-bends leave little room at 12 m/s either way. The speed
  // command's P-term asks up to its cap when the car lags its profile: measured on generated
  // hard trackdrives, 15 m/s^2 at 8 m/s with 0.43 rad of steering out of a turn ran the car
  // wide into an outside cone.
  double exit_accel_cap(const core::Estimate& est, const VehicleCommand& cmd) const {
    const double v = std::max(0.0, est.speed_mps);
    const double steer =
        std::max(std::abs(steer_now), std::abs(steer_towards(cmd.steer_rad, steer_reach)));
    const double turn = curvature_for_steer(tracker, steer);
    const double grip =
        limits(params.fast_speed_mps).lateral_mps2(v) / std::max(params.grip_fraction, 1e-3);
    const double share = v * v * turn / grip;
    return accel_cap() * std::sqrt(std::max(0.0, 1.0 - share * share));
  }

  // the wheels' angle moved from now towards `command` by at most `reach` (the steering's rate
  // over an update)
  double steer_towards(double command, double reach) const {
    return steer_now + std::clamp(command - steer_now, -reach, reach);
  }

  // whether the path ahead (or the steering now) needs most of the steering's range
  bool tight_ahead(const std::vector<double>& s, const std::vector<double>& k, double s_here,
                   double speed) const {
    if (std::abs(steer_now) >= kManoeuvreSteerShare * vehicle.max_steer_rad &&
        speed <= kManoeuvreMaxSpeedMps)
      return true;
    const double limit = kManoeuvreCurvatureShare / full_lock_radius_m(vehicle);
    const double lap = path.closed ? s.back() : 0.0;
    const double ahead = std::max(kManoeuvreAheadM, kManoeuvreAheadS * std::max(0.0, speed));
    for (size_t i = 0; i < k.size(); ++i) {
      double d = s[i] - s_here;
      if (lap > 0.0 && d < 0.0) d += lap;
      if (d >= -1.0 && d <= ahead && std::abs(k[i]) >= limit) return true;
    }
    return false;
  }

  // where the speed target is read: a short preview ahead of s, and a longer one where the
  // profile falls there while the track is being explored (and mapped), and on the fast laps
  // where it falls towards a tight turn
  struct SpeedPreview {
    double s_m = 0.0;
    bool long_preview = false;
  };
  SpeedPreview speed_preview_at(double v, double s) const {
    const double near = s + std::max(0.0, v) * kSpeedPreviewS;
    const double far = s + std::max(0.0, v) * kBrakePreviewS;
    const double far_speed = profile.speed_at(far, lap_m);
    if (!(far_speed < profile.speed_at(near, lap_m))) return {near, false};
    if (phase == Phase::kFast &&
        far_speed > kTightEntryShare * SpeedLimits{}.tight_turn_speed_mps)
      return {near, false};
    return {far, true};
  }

  // the profile speed a short preview ahead of s
  double speed_command_target(double v, double s) const {
    return profile.speed_at(speed_preview_at(v, s).s_m, lap_m);
  }

  // P-control towards the profile speed plus its slope as feed-forward, read a preview ahead
  // for the actuators' lag. On the fast laps at the short preview the P-term compares the
  // car's speed with the profile where the car is: aimed at the profile's speed 0.1 s ahead, it
  // held the car that much early on every slope of the profile (braking at 9 m/s^2 from 16 m/s
  // on FSE24, 1 m/s under the profile all the way into the corner; over it accelerating),
  // 0.3-0.9 % of the PacSim fast laps. The long preview keeps aiming ahead: it is there to brake
  // early into the tight turns and while lap 1 is mapped.
  double speed_command(double v, double s, double speed_cap) const {
    const SpeedPreview preview = speed_preview_at(v, s);
    const double s0 = preview.s_m;
    const double v0 = std::min(speed_cap, profile.speed_at(s0, lap_m));
    const double v1 = std::min(speed_cap, profile.speed_at(s0 + kFeedForwardSpanM, lap_m));
    const double feed_forward = (v1 * v1 - v0 * v0) / (2.0 * kFeedForwardSpanM);
    const double aim = phase == Phase::kFast && !preview.long_preview
                           ? std::min(speed_cap, profile.speed_at(s, lap_m))
                           : v0;
    const double a = feed_forward + params.speed_gain_per_s * (aim - v);
    return std::clamp(a, -decel_cap(), accel_cap());
  }

  // the speed limits with a cap: the envelope at the grip fraction (lap 1's at its own)
  SpeedLimits limits(double cap, bool exploring = false) const {
    SpeedLimits l;
    l.max_speed_mps = cap;
    l.max_lateral_accel_mps2 =
        circuit_event() ? kCircuitLateralCapMps2 : params.max_lateral_accel_mps2;
    l.max_accel_mps2 = accel_cap();
    l.max_decel_mps2 = decel_cap();
    if (!circuit_event()) return l;  // acceleration and skidpad keep their constant limits
    l.envelope = envelope;
    // lap 1 turns with less of the grip than the fast laps, and brakes as they do: braking later
    // into a minimum hairpin's turn-in is what the turn-in cannot afford
    if (exploring) l.lateral_share = params.explore_grip_fraction / params.grip_fraction;
    l.max_curvature = 1.0 / full_lock_radius_m(vehicle);
    return l;
  }

  // the racing line's limits: also the curvature the steering can add per second, on average
  // over its range, with room left for the tracker's corrections (the exploration's paths, laid
  // afresh each tick from the cones in view, bend at their far ends as the view changes: there
  // the limit only slowed lap 1, and the example SLAM plug-in then ran into a cone after its
  // autocross finish)
  SpeedLimits fast_limits() const {
    SpeedLimits l = limits(params.fast_speed_mps);
    l.max_curvature_rate_per_s =
        kCurvatureRateShare * vehicle.max_steer_rate_rps * l.max_curvature / vehicle.max_steer_rad;
    return l;
  }

  // autocross and trackdrive plan from the envelope; acceleration and skidpad from the keys
  bool circuit_event() const {
    return event == EventType::kAutocross || event == EventType::kTrackdrive;
  }

  // the longitudinal limits of the speed command and of braking, m/s^2
  double decel_cap() const {
    return circuit_event() ? kCircuitLongitudinalCapMps2 : params.max_decel_mps2;
  }
  double accel_cap() const {
    return circuit_event() ? kCircuitLongitudinalCapMps2 : params.max_accel_mps2;
  }

  // --- acceleration ---------------------------------------------------------------------------

  // straight along the fitted course at full power, brake past the finish, stop in the zone
  VehicleCommand acceleration(const DriverInput& in) {
    const core::Estimate& est = in.estimate;
    const std::vector<MapCone> cones = cones_near(est, in.observations, 1e9);

    // the course from the cones, and the finish line from the far big orange cones
    const StraightCourse course = fit_straight_course(cones, start, params.assumed_half_width_m);
    double finish_sum = 0.0;
    int finish_n = 0;
    for (const MapCone& c : cones) {
      const double x = start.inverse_transform(c.position).x();
      if (c.cls == core::ConeClass::kOrangeBig && x > kFinishGateSearchM)
        finish_sum += x, ++finish_n;
    }
    if (finish_n > 0) finish_x_m = finish_sum / finish_n;

    // follow the course; the profile is flat at the speed cap
    const double x = start.inverse_transform(est.pose.position()).x();
    path = straight_course_path(course, start, x - 2.0, x + kCourseAheadM);
    profile = plan_speed(path, limits(params.acceleration_speed_mps));
    lap_m = 0.0;
    track_progress = false;
    status.path = path.points;
    VehicleCommand cmd = follow(est, params.acceleration_speed_mps);

    // brake once past the finish line, or earlier if the braking zone would be too short
    const double v = std::max(0.0, est.speed_mps);
    const double stop_x = x + v * v / (2.0 * kBrakingZoneDecelShare * decel_cap());
    const double zone_end_x = finish_x_m + kBrakingZoneM - vehicle.rear_axle_to_front_m;
    if (phase == Phase::kLaunch &&
        (x > finish_x_m + kBrakePastFinishM || stop_x > zone_end_x - kBrakingZoneMarginM))
      phase = Phase::kBraking;
    if (phase == Phase::kLaunch) {
      cmd.accel_mps2 = v < params.acceleration_speed_mps - 1.0
                           ? params.launch_accel_mps2
                           : params.speed_gain_per_s * (params.acceleration_speed_mps - v);
      status.target_speed_mps = params.acceleration_speed_mps;
    } else {
      cmd.accel_mps2 = -decel_cap();
      status.target_speed_mps = 0.0;
    }
    return cmd;
  }

  // --- skidpad --------------------------------------------------------------------------------

  // the figure-eight path on the fitted layout
  void begin_skidpad(const DriverInput& in) {
    phase = Phase::kSkidpad;
    const std::vector<MapCone>& layout = prior_map.empty() ? in.estimate.map : prior_map;
    const std::optional<SkidpadGeometry> g = fit_skidpad(layout, start);
    if (!g) {
      phase = Phase::kStopped;  // no layout to drive on: stay put
      return;
    }
    const SkidpadPlan plan = plan_skidpad(*g, start, kSkidpadStopAfterM);
    path = plan.path;
    skidpad_lap_end_s = plan.lap_end_s;
    skidpad_stop_s = plan.stop_s;
    profile = plan_speed(path, limits(params.skidpad_speed_mps), 0.0, 0.0);
    lap_m = 0.0;
    track_progress = true;
    progress_segment = project_onto(path, start.position(), 0, path.segment_count()).segment;
    status.path = path.points;
  }

  // follow the figure eight, count laps by progress, hold at the end of the exit
  VehicleCommand skidpad(const DriverInput& in) {
    if (phase == Phase::kStopped) return {};
    VehicleCommand cmd = follow(in.estimate, params.skidpad_speed_mps);
    const std::vector<double> s = path.arc_lengths();
    const PathProjection here =
        project_onto(path, in.estimate.pose.position(), progress_segment, 2);
    const double s_here = s[here.segment] + here.t * (s[here.segment + 1] - s[here.segment]);
    status.laps_counted =
        static_cast<int>(std::count_if(skidpad_lap_end_s.begin(), skidpad_lap_end_s.end(),
                                       [&](double end) { return s_here >= end; }));
    const double remaining = skidpad_stop_s - s_here;
    if (status.laps_counted >= kSkidpadLaps &&
        (remaining < 0.3 ||
         (remaining < kSkidpadStopToleranceM && in.estimate.speed_mps < kStoppedSpeedMps)))
      phase = Phase::kStopped;
    return cmd;
  }

  // --- autocross and trackdrive ---------------------------------------------------------------

  // explore lap 1 from the cones, then (trackdrive) fast laps on the known circuit
  VehicleCommand circuit(const DriverInput& in, const Vec2& front) {
    const core::Estimate& est = in.estimate;

    // the start/finish line from the big orange cones near the start
    if (status.odometer_m < kLapLineSearchOdometerM) {
      const std::optional<LapLine> line = lap_line_from_cones(est.map, start);
      if (line) lap_line = *line;
    }

    // lap counting: a forward crossing of the line by the front wing, far enough from the last
    if (crosses_forward(lap_line, last_front, front)) {
      if (status.odometer_m - odometer_at_lap > kMinLapDistanceM) {
        ++status.laps_counted;
        odometer_at_lap = status.odometer_m;
        on_lap(est);
      } else if (!trace_lap_start) {
        trace_lap_start = trace.size();  // the start crossing opens the lap-1 trace
      }
    }
    if (run_out_until_m && status.odometer_m >= *run_out_until_m && phase != Phase::kBraking) {
      phase = Phase::kBraking;
      if (path.closed) plan_stop(est);
    }
    if (phase == Phase::kExplore &&
        (trace.empty() || (est.pose.position() - trace.back()).norm() >= kTraceStepM))
      trace.push_back(est.pose.position());

    // exploring (and braking after an autocross) replans from the cones near the car
    if (phase == Phase::kExplore || (phase == Phase::kBraking && !path.closed)) {
      const std::vector<MapCone> near = cones_near(est, in.observations, kPlanningRadiusM);
      const Path local = plan_local_path(near, est.pose, planner, kExploreHorizonM);
      status.problem = local.points.size() < 2 ? "no path through the cones ahead" : "";
      if (local.length() >= kMinLocalPathM || path.points.size() < 2) {
        path = local;
        // a short path is where the cones end (an open course's end): stop there; a longer one
        // reaches as far as the car sees, and grows as it goes
        const double end_v =
            path.length() < kCourseEndPathM
                ? 0.0
                : std::sqrt(2.0 * kEndOfPathDecelShare * decel_cap() * path.length());
        profile = plan_speed(path, limits(params.explore_speed_mps, true), est.speed_mps, end_v);
        lap_m = 0.0;
        track_progress = false;
        status.path = path.points;
      }
    }
    if (phase == Phase::kFast || join_pending_since_m) replan_if_map_moved(est);
    if (phase == Phase::kExplore && join_pending_since_m) join_line(est);
    // past the join: the racing line itself (the same points from there on)
    if (join_until_m && status.odometer_m >= *join_until_m) {
      join_until_m.reset();
      path = racing_line;
      status.path = path.points;
    }
    const double cap = on_racing_line() ? params.fast_speed_mps : params.explore_speed_mps;
    VehicleCommand cmd = follow(est, cap);
    if (phase == Phase::kBraking && !path.closed) {
      cmd.accel_mps2 = -decel_cap();
      status.target_speed_mps = 0.0;
    }
    return cmd;
  }

  // after the last lap on the racing line: a profile along it that brakes the car to a stop at
  // once, as the speed profile plans braking (the envelope at the grip fraction, less what a
  // bend takes of the grip by the friction ellipse: earlier before a bend). The command's full 15
  // m/s^2 from 19 m/s in a bend past the finish of EUFS BM_text_bubble brought the car's rear round
  // and a cone under it.
  void plan_stop(const core::Estimate& est) {
    const size_t n = path.points.size();
    const std::vector<double> s = path.arc_lengths();
    const PathProjection here = project_onto(path, est.pose.position(), 0, path.segment_count());
    const double v = std::max(0.0, est.speed_mps);
    const SpeedLimits l = fast_limits();
    const double room =
        kStopRoomShare * v * v / (2.0 * std::max(1.0, l.decel_mps2(v))) + kStopExtraM;
    // the points from the one after the car to the stop, as an open path
    std::vector<size_t> index;
    Path ahead;
    double length = 0.0;
    for (size_t k = 1; k <= n && length < room; ++k) {
      index.push_back((here.segment + k) % n);
      if (!ahead.points.empty()) length += (path.points[index.back()] - ahead.points.back()).norm();
      ahead.points.push_back(path.points[index.back()]);
    }
    // from the car on: braking at once with what the path's curvature leaves of the grip
    const std::vector<double> curv = curvatures(ahead.points, false);
    std::vector<double> caps(index.size());
    double speed = v;
    Vec2 from = est.pose.position();
    for (size_t k = 0; k < index.size(); ++k) {
      const double decel = l.braking_mps2(speed, curv[k]);
      const double step = (ahead.points[k] - from).norm();
      speed = std::sqrt(std::max(0.0, speed * speed - 2.0 * decel * step));
      caps[k] = std::min(profile.speed_at(s[index[k]], lap_m), speed);
      from = ahead.points[k];
    }
    const SpeedProfile stop = plan_speed(ahead, l, v, 0.0, caps);
    // past the stop, and behind the car, nothing
    std::vector<double> stop_speed(n, 0.0);
    for (size_t k = 0; k < index.size() && k < stop.speed_mps.size(); ++k)
      stop_speed[index[k]] = stop.speed_mps[k];
    profile.speed_mps = stop_speed;
  }

  // the racing line for the fast laps: least curvature with the footprint clear of the cones,
  // within the corridor between the boundaries the circuit was walked between; where the cones
  // do not chain into two loops (the inner cones of a minimum hairpin turn more than a chain
  // link may) the lap the car drove orders them into boundaries. Measured on generated
  // hard-profile trackdrives: the chains did not close on 56 of the first 71, whose fast laps then
  // drove the lap-1 trace at speed with no clearance check (6 of 100 hit a cone)
  Path fast_line(const Path& centre, const std::vector<MapCone>& map, const Pose2& from,
                 Boundaries* sides) const {
    constexpr double kMaxCircuitM = 3000.0;
    Boundaries b = chain_boundaries(map, from, planner, kMaxCircuitM, true);
    // chains that leave out part of the lap the car drove (see follows_lap) are no boundaries
    if (b.left_closed && b.right_closed &&
        !(follows_lap(Path{b.left, true}, lap_trace, kLapOffBoundaryM) &&
          follows_lap(Path{b.right, true}, lap_trace, kLapOffBoundaryM)))
      b = {};
    if (!b.left_closed || !b.right_closed) b = boundaries_along(centre, map, planner);
    if (!b.left_closed || !b.right_closed) return centre;
    // a cone of the wrong colour for its side (a perception error) is an obstacle, not a side
    // the line must keep: kept, it would send the line round the outside of it; a cone never
    // seen is assumed where the lane's curve puts it
    std::vector<MapCone> cones = with_sides_kept(centre, map, planner);
    b = with_gaps_filled(b, cones);
    const RacingLine line =
        plan_racing_line(centre.points, true, b.left, b.right, cones, footprint, 3, 1.0,
                         kLineCurvatureShare / full_lock_radius_m(vehicle));
    if (line.path.points.size() < 20) return centre;
    *sides = b;
    return Path{resample(line.path.points, 1.0, true), true};
  }

  // whether every point of the lap the car drove lies within `within_m` of the closed line
  // (true without a lap to check against). Chains through the cones can link two parts of the
  // track that pass close to each other and close without the stretch between: measured on a
  // generated hard trackdrive (seed 7059) whose fast laps cut a 60 m loop through its cones
  static bool follows_lap(const Path& line, const std::vector<Vec2>& lap, double within_m) {
    if (lap.size() < 2 || line.points.size() < 3) return true;
    for (const Vec2& p : lap)
      if (project_onto(line, p, 0, line.segment_count()).distance_m > within_m) return false;
    return true;
  }

  // the speed caps along the racing line where its lane is narrower than kNarrowLaneM (a blue
  // cone that close to the right boundary, a yellow one to the left): kNarrowLaneSpeedMps within
  // kNarrowLaneReachM of the cone; empty when the line has no such place
  std::vector<double> narrow_lane_caps(const Path& line, const Boundaries& sides,
                                       const std::vector<MapCone>& map) const {
    if (sides.left.size() < 2 || sides.right.size() < 2) return {};
    std::vector<double> caps(line.points.size(), std::numeric_limits<double>::infinity());
    bool any = false;
    auto mark = [&](core::ConeClass cls, const std::vector<Vec2>& other) {
      for (const MapCone& cone : map) {
        if (cone.cls != cls) continue;
        double w = std::numeric_limits<double>::infinity();
        for (size_t j = 0; j < other.size(); ++j)
          w = std::min(
              w, core::distance_to_segment(cone.position, other[j], other[(j + 1) % other.size()]));
        if (w >= kNarrowLaneM) continue;
        for (size_t i = 0; i < caps.size(); ++i)
          if ((line.points[i] - cone.position).norm() <= kNarrowLaneReachM)
            caps[i] = kNarrowLaneSpeedMps, any = true;
      }
    };
    mark(core::ConeClass::kBlue, sides.right);
    mark(core::ConeClass::kYellow, sides.left);
    if (!any) return {};
    return caps;
  }

  // a lap is done: brake after the last one, or switch to the fast circuit after lap 1
  void on_lap(const core::Estimate& est) {
    const int laps = event == EventType::kAutocross ? 1 : params.trackdrive_laps;
    if (status.laps_counted >= laps) {
      // the car's own line may sit ahead of the time-keeping gate (tracks without big orange
      // cones put it at the start pose): run on past any gate nearby, then brake
      run_out_until_m = status.odometer_m + kRunOutAfterFinishM;
      return;
    }
    if (phase != Phase::kExplore) return;

    if (!plan_fast_laps(est)) return;  // keep exploring
    // the car goes on along its lap-1 path until it is near the racing line (see join_line)
    join_pending_since_m = status.odometer_m;
  }

  // the racing line and its caps from the map now (the whole circuit from the map, else the
  // trace of lap 1); false when neither gives a circuit
  bool plan_fast_laps(const core::Estimate& est) {
    std::optional<Path> circuit = plan_circuit(est.map, start, planner);
    // lap 1's trace ends where lap 1 did (the car goes on tracing until it joins the line)
    if (lap_trace.empty() && trace_lap_start && trace.size() > *trace_lap_start + 20)
      lap_trace.assign(trace.begin() + static_cast<long>(*trace_lap_start), trace.end());
    // a circuit from the map that skips part of lap 1 (its chains jumped between two parts of
    // the track that pass close) is not the circuit
    if (circuit && !follows_lap(*circuit, lap_trace, kLapOffCircuitM)) circuit.reset();
    if (!circuit && !lap_trace.empty()) {
      // (a loop that doubled back past the start kinked the racing line there: a 0.4 rad
      // steering step and a cone at the start of lap 3 of a hard trackdrive with GraphSLAM)
      const std::vector<Vec2> lap = smooth(resample(closed_lap(lap_trace), 1.0, true), 3, true);
      circuit = Path{resample(lap, 1.0, true), true};
    }
    if (!circuit) return false;
    Boundaries sides;
    racing_line = fast_line(*circuit, est.map, start, &sides);
    racing_line_caps = narrow_lane_caps(racing_line, sides, est.map);
    line_map.clear();
    for (const MapCone& cone : est.map) line_map.emplace_back(cone.id, cone.position);
    std::sort(line_map.begin(), line_map.end(),
              [](const auto& a, const auto& b) { return a.first < b.first; });
    line_map_checked = est.stamp;
    return true;
  }

  // the largest move of a map cone since the racing line was planned from the map, metres
  double map_moved_since_line(const std::vector<MapCone>& map) const {
    double moved = 0.0;
    for (const MapCone& cone : map) {
      const auto it = std::lower_bound(line_map.begin(), line_map.end(), cone.id,
                                       [](const auto& e, int id) { return e.first < id; });
      if (it != line_map.end() && it->first == cone.id)
        moved = std::max(moved, (cone.position - it->second).norm());
    }
    return moved;
  }

  // SLAM may move the map after the racing line was planned from it (GraphSLAM's loop closure
  // lands a few metres after lap 1 ends and shifts cones by up to a few decimetres; a filter
  // keeps correcting its map): the car would localise on the corrected map and follow a line
  // laid between the old cones. Once a cone has moved kReplanMapMoveM, the line is planned
  // again from the map now and the car joins it over a short distance.
  void replan_if_map_moved(const core::Estimate& est) {
    if (line_map.empty() || est.stamp - line_map_checked < core::from_seconds(kReplanCheckS))
      return;
    if (phase == Phase::kFast && bends_near(path, progress_segment, est.speed_mps) &&
        est.stamp - line_map_checked < core::from_seconds(kReplanMaxWaitS))
      return;  // checked again next tick
    line_map_checked = est.stamp;
    if (map_moved_since_line(est.map) < kReplanMapMoveM) return;
    if (!plan_fast_laps(est)) return;
    ++status.line_replans;
    if (phase != Phase::kFast) return;  // join_line picks the new line up
    const PathProjection at =
        project_onto(racing_line, est.pose.position(), 0, racing_line.segment_count());
    join_racing_line(est, at, std::max(kJoinMinM, kReplanJoinS * std::max(0.0, est.speed_mps)));
  }

  // the racing line joined from the car's pose (projected onto it at `at`) over join_m: the
  // joined path leaves the car along its heading. Started along the line's heading instead,
  // it left the car up to 0.3 rad off its path where lap 1's line and the racing line cross,
  // and the tracker's turn onto it swung the car 0.7 m either side of the line (EUFS
  // Jellybean: two cones at the start of lap 3)
  Path join_path(const core::Estimate& est, const PathProjection& at, double join_m) const {
    return join_from(racing_line, est.pose.position(), at, join_m, est.pose.yaw);
  }

  // the smallest clearance of the footprint to the map's cones along a joined path, from the
  // car to kJoinPastM past the join's end, metres
  double join_clearance(const Path& joined, const PathProjection& at, double join_m,
                        const std::vector<MapCone>& map) const {
    const size_t n = joined.points.size();
    double clearance = std::numeric_limits<double>::infinity();
    double d = 0.0;
    for (size_t k = 0; k + 1 < n && d <= join_m + kJoinPastM; ++k) {
      const size_t j = (at.segment + k) % n;
      const Vec2 a = joined.points[j], b = joined.points[(j + 1) % n];
      const Pose2 pose{a.x(), a.y(), std::atan2(b.y() - a.y(), b.x() - a.x())};
      clearance = std::min(clearance, footprint_clearance(pose, map, footprint));
      d += (b - a).norm();
    }
    return clearance;
  }

  // whether a closed line bends by more than kReplanMaxCurvature from a little behind
  // `segment` to the end of a join ahead of it at this speed
  static bool bends_near(const Path& line, size_t segment, double speed_mps) {
    const size_t n = line.points.size();
    if (n < 5 || !line.closed) return false;
    const double reach = std::max(kJoinMinM, kReplanJoinS * std::max(0.0, speed_mps));
    const size_t behind = static_cast<size_t>(std::ceil(kReplanBehindM)) + 2;
    std::vector<Vec2> window;
    double d = 0.0;
    for (size_t k = 0; k < n && d < reach + kReplanBehindM + 4.0; ++k) {
      const size_t j = (segment + n - behind + k) % n;
      if (!window.empty()) d += (line.points[j] - window.back()).norm();
      window.push_back(line.points[j]);
    }
    const std::vector<double> k = curvatures(window, false);
    return std::any_of(k.begin(), k.end(),
                       [](double c) { return std::abs(c) > kReplanMaxCurvature; });
  }

  // the path onto the racing line from where the car is (projected at `at`) over join_m, and
  // the line's speed profile (the join curves the path by a few thousandths of 1/m ahead of the
  // car, and more behind it, where the car will not be before the join ends)
  void join_racing_line(const core::Estimate& est, const PathProjection& at, double join_m) {
    join_racing_line(join_path(est, at, join_m), at, join_m);
  }
  void join_racing_line(const Path& joined, const PathProjection& at, double join_m) {
    path = joined;
    join_until_m = status.odometer_m + join_m + kJoinPastM;
    profile = plan_speed(racing_line, fast_limits(), std::nullopt, std::nullopt,
                         racing_line_caps);
    lap_m = racing_line.length();
    track_progress = true;
    progress_segment = at.segment;
    status.path = path.points;
  }

  // after lap 1 the car is on its lap-1 path, off the racing line: it switches to the line where
  // the two meet (close and nearly parallel) where the line is calm, or after kJoinWaitM at the
  // first calm place (kJoinMaxWaitM at the latest), and joins it
  // over a distance rather than steering onto it at once while it speeds up
  void join_line(const core::Estimate& est) {
    const PathProjection at =
        project_onto(racing_line, est.pose.position(), 0, racing_line.segment_count());
    const Vec2 along = racing_line.segment_end(at.segment) - racing_line.points[at.segment];
    const double heading_error =
        std::remainder(est.pose.yaw - std::atan2(along.y(), along.x()), 2.0 * std::numbers::pi);
    // where the line bends the join waits (it bends the path where the grip is in use)
    const bool calm = !bends_near(racing_line, at.segment, est.speed_mps);
    const bool meet = at.distance_m <= kJoinCloseM && std::abs(heading_error) <= kJoinHeadingRad;
    const double waited = status.odometer_m - *join_pending_since_m;
    if (!(calm && (meet || waited >= kJoinWaitM)) && waited < kJoinMaxWaitM) return;
    // nor does it join where the joined path would take the car closer to a cone than the
    // racing line's margin (it leaves the car along its heading, which may point at the
    // outside of a bend ahead)
    const double join_m = std::max(kJoinMinM, kJoinS * std::max(0.0, est.speed_mps));
    const Path joined = join_path(est, at, join_m);
    if (waited < kJoinMaxWaitM && join_clearance(joined, at, join_m, est.map) < footprint.margin_m)
      return;
    join_pending_since_m.reset();
    join_racing_line(joined, at, join_m);
    phase = Phase::kFast;
  }
};

double acceleration_stop_past_finish_m(const DriverParams& params, const VehicleGeometry& vehicle,
                                       double finish_speed_mps) {
  const double v = std::max(0.0, finish_speed_mps);
  const double braking = v * v / (2.0 * kBrakingZoneDecelShare * params.max_decel_mps2);
  return std::min(kBrakePastFinishM + vehicle.rear_axle_to_front_m + braking,
                  kBrakingZoneM - kBrakingZoneMarginM);
}

Driver::Driver(core::EventType event, const DriverParams& params, const VehicleGeometry& vehicle,
               std::vector<core::MapCone> prior_map)
    : impl_(std::make_unique<Impl>(event, params, vehicle, std::move(prior_map))) {}

Driver::~Driver() = default;

core::VehicleCommand Driver::update(const DriverInput& input) {
  return impl_->update(input);
}

const DriverStatus& Driver::status() const {
  return impl_->status;
}

}  // namespace conesim::control
