#pragma once
// The sensors mounted on the car during a run: the cone sensor, the LiDAR and the stereo
// camera, each on its own schedule on the sim clock, with their dumps. The run loop calls
// step() after every physics step and takes the delivered cone detections.

#include <atomic>
#include <deque>
#include <filesystem>
#include <functional>
#include <future>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "core/measurements.hpp"
#include "core/rng.hpp"
#include "sensors/cone_sensor.hpp"
#include "sensors/lidar.hpp"
#include "sensors/pose_history.hpp"
#include "sensors/stereo_camera.hpp"
#include "sim/faults.hpp"
#include "sim/perception_runner.hpp"
#include "sim/referee.hpp"
#include "sim/scenario.hpp"
#include "sim/sensor_tap.hpp"
#include "sim/vehicle_sim.hpp"
#include "sim/worker_thread.hpp"

namespace conesim::sim {

/// What to write under images/ and how often (every Nth frame of each sensor).
struct DumpOptions {
  /// Any of "lidar", "camera", "detections". Dumping a sensor switches it on.
  std::set<std::string> sensors;
  /// Every Nth frame of each sensor: every frame only when asked (a dumped frame costs a PNG
  /// through gnuplot or a file write; docs/review.md measures it).
  int every = 10;
  /// The review images through gnuplot (slow, so only for dumped frames): the LiDAR's
  /// bird's-eye view per sweep and the camera's left image with its boxes labelled.
  bool review_png = true;
};

/// Counters for metrics.json.
struct SensorRigStats {
  int lidar_scans = 0;
  /// Sweeps a fault lost before perception (counted in lidar_scans too).
  int lidar_sweeps_lost = 0;
  int64_t lidar_points = 0;
  /// Returns too weak to be detected (the LiDAR's detection_range_10pct_m), all sweeps.
  int64_t lidar_returns_faded = 0;
  int camera_frames = 0;
  int cone_frames = 0;
  double lidar_ms_total = 0.0;
  double camera_ms_total = 0.0;
  /// Time spent in the cone detectors, milliseconds.
  double lidar_detect_ms_total = 0.0;
  double stereo_detect_ms_total = 0.0;
};

/// A box in the left camera image, pixels (x right, y down).
struct CameraBox {
  float x0 = 0.f, y0 = 0.f, x1 = 0.f, y1 = 0.f;
  core::ConeClass cls = core::ConeClass::kUnknown;
  /// A detection: the tracker's id (-1 none); a true box: the cone's id in the run's track.
  int id = -1;
  /// From the left camera, m.
  float range_m = 0.f;
};

/// One stereo pair as the replay records it (sim/replay.hpp): the left image as the perception
/// got it (after the camera's faults), the stereo detector's boxes (none when the perception
/// does not run it) and the true boxes (the review image's, occlusion applied), at capture time.
struct CameraReplayFrame {
  core::TimeUs t = 0;
  const core::RgbImage* left = nullptr;
  std::vector<CameraBox> detected;
  std::vector<CameraBox> truth;
};

/// A recorder of labelled sensor data (`conesim dataset`, sim/dataset.hpp): it gets the frames
/// it asks for with their exact labels, on the run's thread. Having one switches on the camera,
/// and the LiDAR when it wants sweeps; it changes nothing else of the run.
class LabelledDataSink {
 public:
  virtual ~LabelledDataSink() = default;
  /// True when the stereo pair rendered at sim time t is wanted (the rig then draws its
  /// segmentation too).
  virtual bool wants_camera(core::TimeUs t) = 0;
  /// A wanted pair as rendered (before the camera's faults), the true poses of both cameras,
  /// and what each pixel of the left image shows.
  virtual void on_camera(core::TimeUs t, const core::StereoFrame& frame,
                         const core::StereoLabels& poses,
                         const sensors::SegmentationImage& segmentation) = 0;
  /// True when LiDAR sweeps are wanted.
  virtual bool wants_lidar() const = 0;
  /// Each LiDAR sweep that was not lost (after its faults): points in the sensor frame, a label
  /// per point and the sensor's true pose at its start and end; end_us: its last column.
  virtual void on_lidar(core::TimeUs end_us, const sensors::LidarScan& scan) = 0;
};

class SensorRig {
 public:
  /// Sets up the sensors the scenario, the dumps and the tap ask for. Throws
  /// std::invalid_argument for a sensor configuration that fails validation. tap: an observer
  /// of the raw LiDAR sweeps and stereo pairs (null for none).
  SensorRig(const Scenario& scenario, const tracks::Track& track, const VehicleSim& car,
            const DumpOptions& dump, const std::filesystem::path& run_dir,
            SensorTap* tap = nullptr, LabelledDataSink* labelled = nullptr);
  ~SensorRig();

  /// Runs what is due at sim time t (after the physics step that reached t).
  void step(core::TimeUs t, const VehicleSim& car, const Referee& referee);

  /// The vehicle's motion by the autonomy's estimate (raw-data perception de-skews and tracks
  /// with it; ignored otherwise).
  void set_motion(const slam::frontend::SweepMotion& motion) {
    if (perception_) perception_->set_motion(motion);
    motion_ = motion;
  }

  /// Hands a camera frame to `observer` at most once per `period_us` (the first pair, then the
  /// first one a period later, ...); never switches the camera on: a run without one calls
  /// nothing.
  void set_camera_observer(core::TimeUs period_us,
                           std::function<void(const CameraReplayFrame&)> observer) {
    camera_observer_period_us_ = period_us;
    camera_observer_ = std::move(observer);
  }

  /// The raw-data perception (`perception: lidar | stereo | fused`), null otherwise.
  const PerceptionRunner* perception() const { return perception_.get(); }
  /// The scenery and clutter the LiDAR and the camera see (world.clutter; empty at density 0).
  const std::vector<tracks::SceneryObject>& scenery() const { return scenery_; }

  /// The cone detection frames whose latency has passed by time t, oldest first.
  std::optional<DeliveredDetections> take_detections(core::TimeUs t);
  /// The frame take_detections(t) would return next, without taking it (null if none; before
  /// the cone tracker has run on it).
  const DeliveredDetections* next_detections(core::TimeUs t) const {
    return cone_queue_.empty() || cone_queue_.front().first > t ? nullptr
                                                                : &cone_queue_.front().second;
  }

  bool cone_sensor_on() const { return cone_sensor_ != nullptr; }
  bool lidar_on() const { return lidar_ != nullptr; }
  bool camera_on() const { return camera_ != nullptr; }
  /// Counters; call finish() first so that the sweep in flight is counted.
  const SensorRigStats& stats() const { return stats_; }
  /// What each of the scenario's faults did to the LiDAR, the camera and the delivery of the
  /// frames (call finish() first).
  const FaultCounts& fault_counts() const { return fault_counts_; }

  /// Why a perception plug-in cannot go on (it threw, returned NaN or overran its budget on a
  /// frame collected by now), naming it; empty while all is well.
  const std::string& failure() const { return failure_; }

  /// Waits for the LiDAR sweep still computing on the second core and dumps it.
  void finish();

 private:
  struct SweepPart;
  struct SweepInProgress;
  void cast_columns(core::TimeUs t);
  // queues the columns [begin, end) of the sweep being cast as its next part
  void post_part(int begin, int end);
  void end_sweep();
  void restart_sweep();
  sensors::PoseHistory pose_window(core::TimeUs from, core::TimeUs to) const;
  void collect_sweep();
  void dump_sweep(int index, const sensors::LidarScan& scan,
                  const std::optional<slam::frontend::LidarDetections>& detections);
  void render_camera(core::TimeUs t, const VehicleSim& car, const Referee& referee);
  void sense_cones(core::TimeUs t, const VehicleSim& car, const Referee& referee);
  void sync_knocked_cones(const Referee& referee);
  // queues a frame for SLAM, due at `due_us`, late by the delay jitter's draw (source: 0 LiDAR,
  // 1 camera, 2 cone sensor)
  void enqueue(core::TimeUs due_us, DeliveredDetections frame, int source);
  // the camera's faults on the frame just rendered
  void apply_camera_faults(core::TimeUs t);

  const tracks::Track& track_;
  DumpOptions dump_;
  std::filesystem::path run_dir_;

  const Referee* referee_ = nullptr;
  std::unique_ptr<PerceptionRunner> perception_;
  SensorTap* tap_ = nullptr;
  LabelledDataSink* labelled_ = nullptr;
  sensors::SegmentationImage segmentation_;
  // the LiDAR's mount, and the tap's point buffer (reused from sweep to sweep)
  core::Pose3 lidar_mount_;
  std::vector<sdk::LidarPoint> tap_points_;
  // the sweeps delivered so far that the tap could have had (SensorTapKinds::lidar_every)
  int64_t tap_lidar_sweeps_ = 0;

  std::unique_ptr<sensors::ConeSensor> cone_sensor_;
  // the tracker on cone-sensor frames (`sensors.cone_sensor.track`), null when off, with the
  // motion it predicts by and the stamp of its last frame
  std::unique_ptr<slam::frontend::ConeTracker> cone_tracker_;
  slam::frontend::SweepMotion motion_;
  std::optional<core::TimeUs> tracker_stamp_;
  core::TimeUs cone_period_us_ = 0;
  core::TimeUs cone_latency_us_ = 0;
  std::deque<std::pair<core::TimeUs, DeliveredDetections>> cone_queue_;

  // the scenery and clutter beside the track (world.clutter)
  std::vector<tracks::SceneryObject> scenery_;
  std::unique_ptr<sensors::Lidar> lidar_;
  sensors::PoseHistory poses_;
  core::Rng lidar_rng_;
  core::TimeUs sweep_start_ = 0;
  // the sweep being cast: the worker casts its columns a part at a time as their poses arrive
  std::shared_ptr<SweepInProgress> casting_;
  // columns of it handed to the worker
  int columns_posted_ = 0;
  // the sweep that has ended, finishing and detecting on the worker (one at a time)
  struct SweepResult {
    sensors::LidarScan scan;
    std::optional<slam::frontend::LidarDetections> detections;
    double cast_ms = 0.0;
    double detect_ms = 0.0;
    // a perception plug-in's cones, or why it failed
    std::optional<core::ConeObservations> plugin_frame;
    std::string plugin_failure;
    // the sweep's end and the autonomy's motion then (a plug-in called at collection)
    core::TimeUs end_us = 0;
    slam::frontend::SweepMotion motion;
    // the faults: the sweep lost before perception, and what they did to it
    bool lost = false;
    FaultCounts fault_counts;
    // runs the LiDAR cone detector on the sweep (its end and motion), timed
    void detect_with(const slam::frontend::LidarConeDetector& detector);
  };
  // the sweep of its parts once cast, in column order, and the time they took
  static sensors::LidarScan join_parts(const std::vector<std::shared_ptr<SweepPart>>& parts,
                                       double& cast_ms);
  std::future<SweepResult> pending_scan_;
  // set by the thread that runs the pending sweep's cone detector (end_sweep())
  std::shared_ptr<std::atomic<bool>> pending_detect_claim_;
  // its parts (the loop casts those the worker has not come to when it collects the sweep)
  std::vector<std::shared_ptr<SweepPart>> pending_parts_;
  // when the sweep in flight reaches SLAM (its end plus the perception latency)
  core::TimeUs pending_delivery_us_ = 0;
  core::TimeUs lidar_latency_us_ = 0;

  std::unique_ptr<sensors::StereoCamera> camera_;
  core::TimeUs camera_period_us_ = 0;
  core::TimeUs camera_latency_us_ = 0;
  bool with_depth_ = false;
  core::StereoFrame frame_;
  core::StereoLabels frame_labels_;

  // the scenario's faults, what they did, and the camera's last frame before a freeze
  FaultInjector faults_;
  FaultCounts fault_counts_;
  bool jitter_ = false;
  bool freezes_ = false;
  std::optional<core::StereoFrame> last_good_frame_;
  // the replay's camera frames: how often, and when the next one is due
  std::function<void(const CameraReplayFrame&)> camera_observer_;
  core::TimeUs camera_observer_period_us_ = 0;
  core::TimeUs next_camera_observed_us_ = 0;

  size_t knocked_seen_ = 0;
  std::string failure_;
  SensorRigStats stats_;
  // the LiDAR's thread; last member: its jobs use the members above, so it stops before them
  std::unique_ptr<WorkerThread> worker_;
};

}  // namespace conesim::sim
