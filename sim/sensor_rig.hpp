#pragma once
// The sensors mounted on the car during a run: the cone sensor, the LiDAR and the stereo
// camera, each on its own schedule on the sim clock, with their dumps. The run loop calls
// step() after every physics step and takes the delivered cone detections.

#include <deque>
#include <future>
#include <filesystem>
#include <memory>
#include <optional>
#include <set>
#include <string>

#include "core/measurements.hpp"
#include "core/rng.hpp"
#include "sensors/cone_sensor.hpp"
#include "sensors/lidar.hpp"
#include "sensors/pose_history.hpp"
#include "sensors/stereo_camera.hpp"
#include "sim/perception_runner.hpp"
#include "sim/referee.hpp"
#include "sim/scenario.hpp"
#include "sim/vehicle_sim.hpp"

namespace conesim::sim {

/// What to write under images/ and how often (every Nth frame of each sensor).
struct DumpOptions {
  /// Any of "lidar", "camera", "detections". Dumping a sensor switches it on.
  std::set<std::string> sensors;
  int every = 1;
  /// Top-down PNG per LiDAR scan (gnuplot; slow, so only for dumped scans).
  bool lidar_png = true;
};

/// Counters for metrics.json.
struct SensorRigStats {
  int lidar_scans = 0;
  int64_t lidar_points = 0;
  int camera_frames = 0;
  int cone_frames = 0;
  double lidar_ms_total = 0.0;
  double camera_ms_total = 0.0;
  /// Time spent in the cone detectors, milliseconds.
  double lidar_detect_ms_total = 0.0;
  double stereo_detect_ms_total = 0.0;
};

class SensorRig {
 public:
  /// Sets up the sensors the scenario and the dumps ask for. Throws std::invalid_argument for
  /// a sensor configuration that fails validation.
  SensorRig(const Scenario& scenario, const tracks::Track& track, const VehicleSim& car,
            const DumpOptions& dump, const std::filesystem::path& run_dir);
  ~SensorRig();

  /// Runs what is due at sim time t (after the physics step that reached t).
  void step(core::TimeUs t, const VehicleSim& car, const Referee& referee);

  /// The vehicle's motion by the autonomy's estimate (raw-data perception de-skews and tracks
  /// with it; ignored otherwise).
  void set_motion(const slam::frontend::SweepMotion& motion) {
    if (perception_) perception_->set_motion(motion);
  }

  /// The raw-data perception (`perception: lidar | stereo | fused`), null otherwise.
  const PerceptionRunner* perception() const { return perception_.get(); }

  /// The cone detection frames whose latency has passed by time t, oldest first.
  std::optional<DeliveredDetections> take_detections(core::TimeUs t);

  bool cone_sensor_on() const { return cone_sensor_ != nullptr; }
  bool lidar_on() const { return lidar_ != nullptr; }
  bool camera_on() const { return camera_ != nullptr; }
  /// Counters; call finish() first so that the sweep in flight is counted.
  const SensorRigStats& stats() const { return stats_; }

  /// Waits for the LiDAR sweep still computing on the second core and dumps it.
  void finish();

 private:
  void start_sweep();
  void collect_sweep();
  void dump_sweep(int index, const sensors::LidarScan& scan,
                  const std::optional<slam::frontend::LidarDetections>& detections);
  void render_camera(core::TimeUs t, const VehicleSim& car, const Referee& referee);
  void sense_cones(core::TimeUs t, const VehicleSim& car, const Referee& referee);
  void sync_knocked_cones(const Referee& referee);

  const tracks::Track& track_;
  DumpOptions dump_;
  std::filesystem::path run_dir_;

  const Referee* referee_ = nullptr;
  std::unique_ptr<PerceptionRunner> perception_;

  std::unique_ptr<sensors::ConeSensor> cone_sensor_;
  core::TimeUs cone_period_us_ = 0;
  core::TimeUs cone_latency_us_ = 0;
  std::deque<std::pair<core::TimeUs, DeliveredDetections>> cone_queue_;

  std::unique_ptr<sensors::Lidar> lidar_;
  sensors::PoseHistory poses_;
  core::Rng lidar_rng_;
  core::TimeUs sweep_start_ = 0;
  // the sweep computing on another thread while the physics goes on (one at a time, in order,
  // so the noise sequence and the results are the same as sequential sweeps)
  struct SweepResult {
    sensors::LidarScan scan;
    std::optional<slam::frontend::LidarDetections> detections;
  };
  std::future<SweepResult> pending_scan_;
  // when the sweep in flight reaches SLAM (its end plus the perception latency)
  core::TimeUs pending_delivery_us_ = 0;
  core::TimeUs lidar_latency_us_ = 0;
  double pending_ms_ = 0.0;
  double pending_detect_ms_ = 0.0;

  std::unique_ptr<sensors::StereoCamera> camera_;
  core::TimeUs camera_period_us_ = 0;
  core::TimeUs camera_latency_us_ = 0;
  bool with_depth_ = false;
  core::StereoFrame frame_;
  core::StereoLabels frame_labels_;

  size_t knocked_seen_ = 0;
  SensorRigStats stats_;
};

}  // namespace conesim::sim
