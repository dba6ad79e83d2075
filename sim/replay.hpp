#pragma once
// The 3D replay of a run (issue 16, docs/replay.md). A run with --replay records what the page
// needs beyond the folder's own files (trajectory.csv, track.csv, metrics.json) into replay.bin
// while it drives: a few LiDAR sweeps a second, thinned and quantised to centimetres, and each
// SLAM lane's map as it grows. `conesim view RUN_DIR` turns the folder into replay.html: one
// self-contained page (three.js and the data inlined) that opens from disk.

#include <cstdint>
#include <deque>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/autonomy_types.hpp"
#include "core/geometry.hpp"
#include "sim/sensor_tap.hpp"
#include "tracks/track.hpp"

namespace conesim::sim {

struct DeliveredDetections;
struct CameraReplayFrame;

inline constexpr const char* kReplayLogFile = "replay.bin";
inline constexpr const char* kReplayPageFile = "replay.html";

/// How much of the run the recorder keeps.
struct ReplayRecordSettings {
  /// LiDAR sweeps kept per sim second (every Nth sweep of the sensor).
  double lidar_rate_hz = 2.0;
  /// Points farther than this from the car are dropped, m.
  double lidar_range_m = 40.0;
  /// At most this many points of a sweep are kept: every cone point, then ground points thinned
  /// evenly to fill the rest.
  int max_points_per_sweep = 3000;
  /// Map snapshots per sim second and lane (the last one of a lane is always kept).
  double map_rate_hz = 2.0;
  /// Camera frames kept per sim second (when the run has the stereo camera anyway), the left
  /// image scaled down to this width (its aspect kept) and JPEG-compressed at this quality.
  double camera_rate_hz = 4.0;
  int camera_width_px = 320;
  int camera_jpeg_quality = 70;
};

/// Records a run for its replay: a sensor tap for the LiDAR (it asks for the sweeps only when
/// the run has a LiDAR anyway), a map observer for SLAM, and the true pose at each trajectory
/// row (to put each point where the car was when it was fired). Writes RUN_DIR/replay.bin
/// through a partial file renamed in finish(); a run that does not finish leaves none.
class ReplayRecorder : public SensorTap {
 public:
  /// lidar_sweep_hz: the sensor's sweep rate, 0 without a LiDAR.
  ReplayRecorder(const std::filesystem::path& run_dir, const tracks::Track& track,
                 double lidar_sweep_hz, const ReplayRecordSettings& settings = {});
  ~ReplayRecorder() override;
  ReplayRecorder(const ReplayRecorder&) = delete;
  ReplayRecorder& operator=(const ReplayRecorder&) = delete;

  /// The car's true pose (rear axle) at time t, in time order.
  void on_pose(core::TimeUs t, const core::Pose2& pose);
  void on_lidar(core::TimeUs delivered_us, const sdk::LidarSweep& sweep,
                const std::vector<int>* labels) override;
  /// A cone detection frame as the autonomy gets it: each detection's true cone (-1: a false
  /// positive) and where it was put, for colouring the points by outcome.
  void on_detections(const DeliveredDetections& frame);
  /// A camera frame (SensorRig::set_camera_observer, at settings().camera_rate_hz): the left
  /// image scaled down and JPEG-compressed, its boxes scaled with it.
  void on_camera(const CameraReplayFrame& frame);
  /// A SLAM lane's estimate taking effect (SlamRunner::set_map_observer).
  void on_map(const std::string& lane, core::TimeUs stamp, const core::Estimate& estimate);
  /// Writes each lane's last map and renames the log into place.
  void finish();

  int sweeps_recorded() const { return sweeps_; }
  int camera_frames_recorded() const { return camera_frames_; }
  const ReplayRecordSettings& settings() const { return settings_; }

 private:
  core::Pose2 pose_at(core::TimeUs t) const;
  void write_map(const std::string& lane, double t_s, const std::vector<core::MapCone>& map);
  void write_record(uint8_t type, const std::string& payload);

  std::filesystem::path file_, partial_;
  std::ofstream out_;
  bool done_ = false;
  ReplayRecordSettings settings_;
  // each cone's class by its id (for the points' labels)
  std::vector<int8_t> cone_class_;
  std::deque<std::pair<core::TimeUs, core::Pose2>> poses_;
  int sweeps_ = 0;
  int camera_frames_ = 0;
  struct LaneMaps {
    core::TimeUs last_written_us = -1;
    double last_t_s = 0.0;
    std::vector<core::MapCone> last;
    bool unwritten = false;
  };
  std::map<std::string, LaneMaps> lanes_;
};

/// A replay.bin as read back.
struct ReplayLog {
  struct Sweep {
    double t_s = 0.0;
    float origin_x = 0.f, origin_y = 0.f;
    /// x, y, z in cm from the origin (z from the ground), three per point.
    std::vector<int16_t> xyz_cm;
    std::vector<uint8_t> intensity;
    /// 0 ground, 1 + core::ConeClass of the cone the point hit.
    std::vector<uint8_t> label;
    /// The id of the cone the point hit in the run's track, -1 ground.
    std::vector<int16_t> cone;
  };
  struct Detections {
    double t_s = 0.0;
    /// Each detection's true cone id (-1 a false positive) and its place in the track frame.
    std::vector<int32_t> cone;
    std::vector<float> xy;
  };
  struct MapSnapshot {
    double t_s = 0.0;
    std::vector<float> xy;
    std::vector<uint8_t> cls;
  };
  struct CameraFrame {
    /// Capture time (the pair's stamp), s.
    double t_s = 0.0;
    /// The JPEG's size, pixels.
    int width = 0, height = 0;
    std::string jpeg;
    struct Box {
      /// In the JPEG's pixels (x right, y down).
      float x0 = 0.f, y0 = 0.f, x1 = 0.f, y1 = 0.f;
      /// 1 + core::ConeClass.
      uint8_t cls = 0;
      /// A detection's track id (-1 none), a true box's cone id.
      int32_t id = -1;
      float range_m = 0.f;
    };
    std::vector<Box> detected, truth;
  };
  std::vector<Sweep> sweeps;
  std::vector<Detections> detections;
  /// The left camera's frames (runs with the stereo camera), in time order.
  std::vector<CameraFrame> camera;
  /// Each lane's snapshots in time order, lanes in the order they first appear.
  std::vector<std::pair<std::string, std::vector<MapSnapshot>>> maps;
};

/// Reads a replay.bin; core::InputError naming the file and the byte offset when it is not one.
ReplayLog read_replay_log(const std::filesystem::path& file);

/// trajectory.csv as the replay reads it: the columns it needs, by name.
struct RunTrajectory {
  /// The shadow SLAM lanes that have columns.
  std::vector<std::string> lanes;
  /// Per row: t, x, y, yaw, steer, est x, est y, est yaw, then x, y, yaw per shadow lane.
  std::vector<float> rows;
  size_t width = 0;
  size_t count = 0;
};

/// A run folder as `conesim view` reads it: metrics.json (its referee events checked),
/// trajectory.csv, track.csv and replay.bin when there. core::InputError naming the file when
/// the folder or one of the three is missing or not what it should be.
struct RunFolder {
  nlohmann::json metrics;
  RunTrajectory trajectory;
  tracks::Track track;
  std::optional<ReplayLog> log;
};
RunFolder read_run_folder(const std::filesystem::path& run_dir);

/// `conesim view RUN_DIR`: writes RUN_DIR/replay.html from trajectory.csv, track.csv,
/// metrics.json and, when there, replay.bin (the LiDAR and the growing maps). A folder without
/// one of the three is refused (core::InputError naming the file); the page goes in through a
/// partial file, so a failure leaves no replay.html that looks complete. three_js_dir: where
/// three.min.js and examples/js/controls/OrbitControls.js are (Debian's libjs-three).
std::filesystem::path write_replay_page(const std::filesystem::path& run_dir,
                                        const std::filesystem::path& three_js_dir);

/// Where Debian's libjs-three puts three.js (CONESIM_THREE_JS_DIR overrides it).
std::filesystem::path default_three_js_dir();

}  // namespace conesim::sim
