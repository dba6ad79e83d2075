#pragma once
// SLAM in the loop (`slam: graph`): the vehicle sensors feed the odometry on their schedules,
// each delivered cone frame runs one backend update, and the driver gets the backend's estimate
// carried forward to the present with the odometry since. With `slam_latency_s` > 0 an update
// takes that long on the sim clock: it runs on a thread of its own while the car drives on, and
// its estimate reaches the driver at the first tick after the latency. Everything the backend
// does is scored against ground truth here, in the harness: map, trajectory, associations, loop
// closures, update time.

#include <array>
#include <deque>
#include <filesystem>
#include <future>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <vector>

#include "sensors/vehicle_sensors.hpp"
#include "sim/perception_runner.hpp"
#include "sim/scenario.hpp"
#include "sim/sensor_rig.hpp"
#include "sim/vehicle_sim.hpp"
#include "sim/worker_thread.hpp"
#include "slam/backends/graph_slam.hpp"
#include "slam/frontend/lidar_cone_detector.hpp"
#include "slam/odometry.hpp"
#include "tracks/track.hpp"

namespace conesim::sim {

class SlamRunner {
 public:
  /// A backend starting at the true start pose (the map frame, ARCHITECTURE decision 6), with
  /// the layout as prior map for skidpad.
  SlamRunner(const Scenario& scenario, const tracks::Track& track, const VehicleSim& car);

  /// Samples the vehicle sensors due at t.
  void step(core::TimeUs t, const VehicleSim& car);

  /// Runs the backend on a cone frame delivered at time now (true pose at capture for the
  /// scoring): at once, or, with a SLAM latency, on the SLAM thread, its estimate taking effect
  /// in catch_up() once the latency has passed.
  void process(const DeliveredDetections& frame, core::TimeUs now);

  /// Takes in the updates whose latency has passed by time t, oldest first (call before
  /// process() and estimate_now() at each tick).
  void catch_up(core::TimeUs t);

  /// Takes in every update still running (at the end of a run, before metrics()).
  void finish();

  /// The estimate at time t: the backend's, moved forward by the odometry since its last frame.
  /// With `motion`, also the odometry's motion at t for perception: the speed averaged over the
  /// last 0.1 s (a sweep; single encoder samples are coarse) and the yaw rate.
  core::Estimate estimate_now(core::TimeUs t,
                              slam::frontend::SweepMotion* motion = nullptr) const;

  /// The latest frame's observations expressed in the vehicle frame at `now` (an estimate
  /// from estimate_now).
  core::ConeObservations observations_at(const core::Pose2& now) const;

  /// The backend's figures for metrics.json (keys of ARCHITECTURE.md under slam.<name>). A
  /// figure with nothing to measure is null, not 0: map_rmse_m when no landmark matched a true
  /// cone, ate_rmse_m without an update, da_correct_fraction without an association.
  /// map_missed counts the true cones that were within the perception's range and field of
  /// view of the true pose at some moment of the run (checked every 50 ms of sim time) and that
  /// no map landmark was matched to (one to one within 1 m); map_cones_in_view counts them all.
  nlohmann::json metrics() const;

  /// An estimated map cone and the true cone it stands for (-1: spurious).
  struct MapMatch {
    core::MapCone estimate;
    int true_cone_id = -1;
    double error_m = 0.0;
  };

  /// The final map matched one to one to the true cones within the 1 m cut-off, no alignment:
  /// the most pairs, then the least total distance (Hungarian, sim/evaluation.hpp).
  std::vector<MapMatch> match_map() const;

  /// The map error at one moment of the run: the backend's map then, matched to the true cones
  /// observed until then. RMSE overall and per class of the true cone (blue, yellow,
  /// orange_small, orange_big); NaN where no cone of that class was matched.
  struct MapErrorSnapshot {
    double distance_m = 0.0;
    int matched = 0;
    std::array<double, 5> rmse_m{};
  };

  /// How often the map error is taken, in distance driven.
  static constexpr double kMapSnapshotEveryM = 10.0;

  /// The map error every kMapSnapshotEveryM of distance driven, in order.
  const std::vector<MapErrorSnapshot>& map_error_over_distance() const {
    return map_error_over_distance_;
  }

  /// Writes map.csv, map_error.csv and the map, map-error and trajectory figures into the run
  /// directory (report.html, written by sim/report from metrics.json, shows them).
  void write_report(const std::filesystem::path& dir) const;

  std::string name() const { return backend_->name(); }

 private:
  struct VehicleSample;
  // what an update leaves for the harness: the estimate after it and what it did
  struct UpdateResult {
    core::Estimate estimate;
    std::vector<slam::Association> associations;
    int loop_closures = 0;
    double wall_ms = 0.0;
    double cpu_ms = 0.0;
  };
  // an update running on the SLAM thread (or done), and when its estimate takes effect
  struct PendingUpdate {
    core::TimeUs due_us;
    DeliveredDetections frame;
    // the odometry of the update's input: the motion from the previous frame to this one
    core::Pose2 odometry_delta;
    std::future<UpdateResult> result;
  };
  // one backend update, timed on the thread that runs it
  UpdateResult run_update(const slam::SlamInput& input);
  // the harness's side of an update: the estimate the driver sees, and the scoring
  void take_in(const DeliveredDetections& frame, const UpdateResult& update);
  void feed_until(slam::Odometry& odometry, core::TimeUs stamp,
                  std::deque<VehicleSample>* queue) const;
  void snapshot_map_error(double distance_m, const core::Estimate& estimate);
  // marks the true cones within the perception's range and field of view from a true pose
  void note_cones_in_view(const core::Pose2& pose);
  const tracks::Cone& true_cone(int id) const { return track_.cones[cone_index_[id]]; }

  const tracks::Track& track_;
  std::unique_ptr<slam::Backend> backend_;
  slam::Odometry odometry_;
  sensors::Imu imu_;
  sensors::WheelEncoders wheels_;
  sensors::SteeringSensor steering_;

  // samples delivered (latency passed) but not yet fed, in stamp order
  struct VehicleSample {
    core::TimeUs stamp;
    int kind;  // 0 imu, 1 wheels, 2 steering
    core::ImuSample imu;
    core::WheelSpeeds wheels;
    core::SteeringSample steering;
  };
  std::deque<std::pair<core::TimeUs, VehicleSample>> in_flight_;
  std::deque<VehicleSample> delivered_;
  core::TimeUs now_ = 0;

  // the SLAM latency; the thread and the updates in flight on it when it is > 0
  core::TimeUs latency_us_ = 0;
  std::deque<PendingUpdate> pending_;

  core::Estimate last_estimate_;
  core::ConeObservations last_observations_;
  core::Pose2 last_frame_pose_;

  // scoring
  std::vector<double> update_ms_;
  // the same in the thread's CPU time, which other processes on the machine do not inflate
  std::vector<double> update_cpu_ms_;
  std::vector<double> position_error2_;
  std::vector<double> yaw_error2_;
  std::vector<core::Pose2> true_path_;
  std::vector<core::Pose2> estimated_path_;
  std::vector<core::Vec2> wrong_association_places_;
  std::vector<double> true_odometer_;
  int da_correct_ = 0;
  int da_wrong_ = 0;
  int loop_closures_ = 0;
  int false_loop_closures_ = 0;
  /// Each loop closure: when, after how far, where the car truly was and thought it was.
  nlohmann::json loop_closure_events_ = nlohmann::json::array();
  // true cone ids seen by each landmark (by landmark id), for its majority identity
  std::map<int, std::map<int, int>> landmark_votes_;
  std::vector<char> cone_observed_;
  // the perception's range and field of view, and the true cones that were in it at some
  // moment of the run (map_missed counts those the map has no landmark for)
  PerceptionView view_;
  std::vector<char> cone_in_view_;
  // index into track_.cones by cone id
  std::vector<int> cone_index_;
  double next_map_snapshot_m_ = 0.0;
  std::vector<MapErrorSnapshot> map_error_over_distance_;
  // last member: its jobs use the backend, so it stops before the members above go
  std::unique_ptr<WorkerThread> slam_thread_;
};

}  // namespace conesim::sim
