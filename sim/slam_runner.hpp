#pragma once
// SLAM in the loop: a driver of back-end lanes (docs/architecture.md, "SLAM lanes"). The vehicle
// sensors feed one odometry; each delivered cone frame becomes one SlamInput, and every lane's
// back-end gets that same input. The driving lane's estimate, carried forward to the present
// with the odometry, steers the car; with `slam_latency_s` > 0 its update takes that long on
// the sim clock (it runs on a thread of its own while the car drives on). Shadow lanes run on
// threads of their own and are only scored: nothing they do reaches the car. Each lane has its
// own scorer (sim/slam_score.hpp).

#include <deque>
#include <filesystem>
#include <functional>
#include <future>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "sim/perception_runner.hpp"
#include "sim/scenario.hpp"
#include "sim/slam_score.hpp"
#include "sim/vehicle_sensor_feed.hpp"
#include "sim/vehicle_sim.hpp"
#include "sim/worker_thread.hpp"
#include "slam/backend.hpp"
#include "slam/frontend/lidar_cone_detector.hpp"
#include "slam/odometry.hpp"
#include "tracks/track.hpp"

namespace conesim::sim {

class SlamRunner {
 public:
  /// The driving back-end and the shadows of the scenario, each starting at the true start
  /// pose (the map frame), with the layout as prior map for skidpad.
  SlamRunner(const Scenario& scenario, const tracks::Track& track, const VehicleSim& car);
  ~SlamRunner();

  /// Samples the vehicle sensors due at t.
  void step(core::TimeUs t, const VehicleSim& car);

  /// Whether step(t) reads the IMU: the physics step ending at t must compute the sensors.
  bool imu_due(core::TimeUs t) const { return feed_.imu_due(t); }

  /// Runs every lane on a cone frame delivered at time now (true pose at capture for the
  /// scoring): the driving lane at once, or with a SLAM latency on its thread, its estimate
  /// taking effect in catch_up() once the latency has passed; the shadows on their threads.
  void process(const DeliveredDetections& frame, core::TimeUs now);

  /// Whether a frame's input is final at time now: every vehicle sensor sample stamped up to
  /// the frame has arrived (the odometry process() would give it is the one it gets now).
  bool input_final(const DeliveredDetections& frame, core::TimeUs now) const;

  /// process(frame, tick) started ahead of the tick, on the lanes' threads, for a frame whose
  /// input is final: nothing else reaches SLAM before the tick (no process(), estimate_now()
  /// or odometry_pose_now() in between), so the update runs while the physics steps on and
  /// takes effect in catch_up(tick) exactly as if it had run there. One the run never reaches
  /// the tick of is dropped in finish().
  void process_ahead(const DeliveredDetections& frame, core::TimeUs tick);

  /// Takes in the driving updates whose latency has passed by time t, oldest first, and the
  /// shadow updates already done (call before process() and estimate_now() at each tick).
  void catch_up(core::TimeUs t);

  /// Takes in every update still running (at the end of a run, before metrics()).
  void finish();

  /// An interrupted run: drops the updates and scoring still queued on the lanes' threads, so
  /// that the run ends after the update in progress. Nothing may be read afterwards.
  void abandon();

  /// The driving estimate at time t: the back-end's, moved forward by the odometry since its
  /// last frame. With `motion`, also the odometry's motion at t for perception: the speed
  /// averaged over the last 0.1 s (a sweep; single encoder samples are coarse) and the yaw rate.
  core::Estimate estimate_now(core::TimeUs t, slam::frontend::SweepMotion* motion = nullptr) const;

  /// The pose the odometry alone gives at time t (dead reckoning from the start pose).
  core::Pose2 odometry_pose_now(core::TimeUs t) const;

  /// The latest frame's observations expressed in the vehicle frame at `now` (an estimate
  /// from estimate_now).
  core::ConeObservations observations_at(const core::Pose2& now) const;

  /// The driving back-end's figures (slam.<name> of metrics.json, docs/metrics.md).
  nlohmann::json metrics() const;
  /// Every lane's figures by lane name, the driving one included.
  nlohmann::json all_metrics() const;

  /// The lanes' names, the driving one first.
  std::vector<std::string> lane_names() const;
  /// The driving lane's name.
  std::string name() const;

  /// A shadow lane's estimated pose at each time: its latest update stamped no later, carried
  /// forward by the odometry (`odometry` the odometry_pose_now of each time). Call after
  /// finish().
  std::vector<core::Pose2> lane_poses(size_t lane, const std::vector<core::TimeUs>& t,
                                      const std::vector<core::Pose2>& odometry) const;

  /// Writes each lane's map, map error and trajectory figures into the run directory: the
  /// driving lane's as map.csv, map_error.csv and slam_*.png, a shadow's as
  /// slam_<name>_map.csv, slam_<name>_map_error.csv and slam_<name>_*.png,
  /// and slam_lanes.png with every lane's map error over distance on one plot.
  void write_report(const std::filesystem::path& dir) const;

  /// Why a plug-in back-end cannot go on (it threw or returned NaN in an update taken in by
  /// now), naming it; empty while all is well. The run ends with this as its DNF reason.
  const std::string& failure() const { return failure_; }

  /// What the faults did to the vehicle sensors (IMU bias steps, wheel slip).
  const FaultCounts& fault_counts() const { return feed_.fault_counts(); }
  /// Frames delivered after a frame stamped later (out-of-order delivery): dropped, as the
  /// odometry cannot go back to their stamp.
  int frames_out_of_order() const { return frames_out_of_order_; }

  /// The driving lane's scorer (tests).
  const SlamScorer& scorer() const;

  /// Called on the run's thread with each lane's estimate as it takes effect (the lane's name,
  /// the frame's stamp): a replay recorder keeps the map growing from it. Unset: nothing.
  using MapObserver =
      std::function<void(const std::string& lane, core::TimeUs stamp, const core::Estimate&)>;
  void set_map_observer(MapObserver observer) { map_observer_ = std::move(observer); }

 private:
  struct Lane;
  struct UpdateResult;
  void take_in(Lane& lane, DeliveredDetections frame, UpdateResult update);
  // waits until every lane's thread has run what was posted (the scorers are up to date)
  void wait_for_lanes() const;
  // the odometry carried forward from the last frame to time t (estimate_now and
  // odometry_pose_now at the same tick share it)
  struct Forward {
    core::TimeUs t = -1;
    slam::OdometryDelta delta;
    double speed_mps = 0.0;
    double mean_speed_mps = 0.0;
    double yaw_rate_rps = 0.0;
  };
  const Forward& forward(core::TimeUs t) const;
  // the lanes' common input for a frame (takes the odometry up to the frame's stamp)
  slam::SlamInput next_input(const DeliveredDetections& frame);
  // runs every lane on the input: the driving lane at once when it has no latency and the
  // tick is now, otherwise on the lanes' threads, taking effect at tick (plus the latency)
  void post(const DeliveredDetections& frame, const slam::SlamInput& input, core::TimeUs tick,
            bool ahead);

  const tracks::Track& track_;
  VehicleSensorFeed feed_;
  slam::Odometry odometry_;
  // dead reckoning at each frame's stamp: the pose the odometry alone gives (the last frame's
  // only without shadow lanes)
  std::deque<std::pair<core::TimeUs, core::Pose2>> frame_odometry_;
  core::Pose2 start_pose_;
  core::TimeUs latency_us_ = 0;
  core::Estimate last_estimate_;
  core::ConeObservations last_observations_;
  core::Pose2 last_frame_pose_;
  std::string failure_;
  MapObserver map_observer_;
  // the newest frame stamp processed, and the frames dropped for coming after a newer one
  core::TimeUs last_frame_stamp_ = -1;
  int frames_out_of_order_ = 0;
  // whether a frame comes after a newer one (then it is counted and dropped)
  bool out_of_order(const DeliveredDetections& frame);
  // the last tick catch_up() ran at: an update processed ahead for a later tick never took
  // effect
  core::TimeUs last_tick_us_ = -1;
  // forward(t)'s last result; cleared when a sample or a frame changes the odometry's input
  mutable Forward forward_;
  // the driving lane first; each lane's jobs use its back-end, so the lanes (and their
  // threads) go before the members above
  std::vector<std::unique_ptr<Lane>> lanes_;
};

}  // namespace conesim::sim
