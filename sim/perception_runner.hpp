#pragma once
// Raw-data perception in the loop (`perception: lidar | stereo | fused`): the cone detectors of
// slam/frontend run on each LiDAR sweep and stereo pair, fusion colours the LiDAR cones from
// the camera, the tracker gives stable ids, and each frame is scored against the labels (the
// point labels of the sweep, the true cones in view) before it goes to SLAM and the driver.

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/clutter.hpp"
#include "core/measurements.hpp"
#include "sensors/lidar.hpp"
#include "sim/autonomy.hpp"
#include "sim/evaluation.hpp"
#include "sim/scenario.hpp"
#include "slam/frontend/cone_tracker.hpp"
#include "slam/frontend/fusion.hpp"
#include "slam/frontend/lidar_cone_detector.hpp"
#include "slam/frontend/stereo_cone_detector.hpp"
#include "tracks/scenery.hpp"
#include "tracks/track.hpp"

namespace conesim::sim {

/// A cone detection frame delivered to the autonomy, with its labels.
struct DeliveredDetections {
  core::ConeObservations observations;
  core::ObservationLabels labels;
  /// True vehicle pose at the capture time (for the oracle map of `slam: none`).
  core::Pose2 capture_pose;
};

/// How one LiDAR sweep's detections fared against the true cones (what the review image of a
/// dumped sweep draws), judged as the perception scorer of "cones that returned points" does.
struct LidarSweepOutcome {
  /// Per detection, the true cone most of its points hit; -1 a false positive (mostly ground,
  /// or no cone has a majority).
  std::vector<int> detection_cone;
  /// The true cones standing within 30 m of the sensor (all round) that returned at least 3
  /// points in this sweep and that no detection stands for.
  std::vector<int> missed;
};

/// Judges a sweep's detections with its point labels; the sensor's place is the sweep's end.
LidarSweepOutcome judge_lidar_sweep(const sensors::LidarScan& scan,
                                    const slam::frontend::LidarDetections& detections,
                                    const tracks::Track& track,
                                    const std::function<bool(int)>& is_knocked);

/// Where a scenario's perception sees cones reliably: the sensor's place on the car, its field
/// of view and the ranges within which a standing cone is detected.
struct PerceptionView {
  double sensor_x_m = 0.0;
  double min_range_m = 0.0;
  double max_range_m = 0.0;
  double fov_deg = 360.0;
};

/// The view of the scenario's perception: the cone sensor's configuration; for a LiDAR, the
/// range up to which at least two rings hit a small cone (a VLP-16 on the front wing sees small
/// cones only within about 9 m: its rings are 2 degrees apart); for the camera, its horizontal
/// field of view out to the stereo detector's range.
PerceptionView perception_view(const Scenario& scenario);

/// Where the vehicle frame dt seconds later lies in the vehicle frame now, moving at the
/// motion's constant speed and yaw rate (the chord of the arc).
core::Pose2 motion_over(const slam::frontend::SweepMotion& motion, double dt);

/// Turns LiDAR sweeps and stereo pairs into cone frames for SLAM, and scores them.
class PerceptionRunner {
 public:
  /// Sets up the detectors the scenario's perception needs. lidar_mount: the LiDAR's pose in
  /// the vehicle frame (for `lidar` and `fused`).
  PerceptionRunner(const Scenario& scenario, const tracks::Track& track,
                   const core::Pose3& lidar_mount);

  bool uses_lidar() const { return uses_lidar_; }
  bool uses_camera() const { return uses_camera_; }
  /// True for a perception plug-in (`autonomy.perception: plugin:PATH`): it takes the place of
  /// the detectors, the fusion and the tracker.
  bool is_plugin() const { return plugin_.object != nullptr; }

  /// The plug-in's cones of one sweep (points in the sensor frame), in the vehicle frame at
  /// `end` (the sweep's end); stamp -1 when it delivers none. May run on the sweep's worker
  /// thread. Throws PluginFailure.
  core::ConeObservations plugin_lidar(const core::PointCloud& cloud, core::TimeUs end,
                                      const slam::frontend::SweepMotion& motion) const;
  /// The plug-in's cones of one stereo pair; stamp -1 for none. Throws PluginFailure.
  core::ConeObservations plugin_stereo(const core::StereoFrame& frame) const;
  /// A plug-in's frame scored against the true cones around the LiDAR, or with `pair` (a
  /// plug-in given the camera alone) in the left image's field of view from the left camera, as
  /// the stereo front-end's frames are, and labelled by the match; nullopt for no frame.
  std::optional<DeliveredDetections> on_plugin_frame(core::ConeObservations frame,
                                                     const core::Pose2& true_pose,
                                                     const std::function<bool(int)>& is_knocked,
                                                     const core::StereoFrame* pair = nullptr);
  /// The LiDAR detector (const: it may run on the sweep's worker thread); null when unused.
  const slam::frontend::LidarConeDetector* lidar_detector() const { return lidar_detector_.get(); }
  /// The stereo detector; null when unused.
  const slam::frontend::StereoConeDetector* stereo_detector() const {
    return stereo_detector_.get();
  }

  /// The vehicle's motion by the autonomy's own estimate (for de-skew and tracking).
  void set_motion(const slam::frontend::SweepMotion& motion) { motion_ = motion; }
  const slam::frontend::SweepMotion& motion() const { return motion_; }

  /// One sweep's detections: scored, fused with the latest stereo result (`fused`), tracked
  /// with the motion the detector de-skewed with (the autonomy's at the sweep's end, as a
  /// perception plug-in gets it). true_pose: the vehicle pose at the detections' stamp.
  /// Returns the frame for SLAM.
  DeliveredDetections on_lidar(const sensors::LidarScan& scan,
                               const slam::frontend::LidarDetections& detections,
                               const slam::frontend::SweepMotion& motion,
                               const core::Pose2& true_pose,
                               const std::function<bool(int)>& is_knocked);

  /// One stereo pair's detections: scored; for `stereo` tracked and returned for SLAM, for
  /// `fused` kept for the next sweep.
  std::optional<DeliveredDetections> on_stereo(const core::StereoFrame& frame,
                                               const slam::frontend::StereoDetections& detections,
                                               const core::Pose2& true_pose,
                                               const std::function<bool(int)>& is_knocked);

  /// metrics.json's `perception` (the scorer of the frames SLAM receives), with per-sensor
  /// figures under `lidar` and `stereo` when both run.
  nlohmann::json metrics() const;

  /// The scenery beside the track (world.clutter): the camera's false detections near an
  /// object are put down to its class; the spare cones standing off the track are cones that
  /// are not the track's (found, they are no false detection; see OffTrackConeInView).
  void set_scenery(const std::vector<tracks::SceneryObject>& scenery);

  ~PerceptionRunner();

  /// The range-band figure (recall, precision, colour, RMSE per 5 m band) as a PNG.
  void write_plot(const std::filesystem::path& png) const;

 private:
  // the true cones standing within the scorer's range and the sensor's field of view
  std::vector<TrueConeInView> truth_in_view(const core::Pose2& true_pose, const core::Vec2& sensor,
                                            double half_fov_rad,
                                            const std::function<bool(int)>& is_knocked) const;
  // the true cones in the left image's field of view, from the left camera
  std::vector<TrueConeInView> in_left_image(const core::StereoFrame& frame,
                                            const core::Pose2& true_pose,
                                            const std::function<bool(int)>& is_knocked) const;
  // the spare cones standing off the track within the scorer's range (and its cut-off), in the
  // vehicle frame at true_pose
  std::vector<OffTrackConeInView> off_track_in_view(const core::Pose2& true_pose) const;
  // the tracker's step, with the motion since its previous frame
  core::ConeObservations track(const core::ConeObservations& frame,
                               const slam::frontend::SweepMotion& motion);

  const tracks::Track& track_;
  std::string mode_;
  bool uses_lidar_ = false;
  bool uses_camera_ = false;
  // a perception plug-in, under its guard, and where its frames are scored from
  PluginInstance<sdk::Perception> plugin_;
  std::unique_ptr<PluginGuard> plugin_guard_;
  core::Pose3 lidar_mount_;
  core::Vec2 plugin_sensor_xy_ = core::Vec2::Zero();
  double plugin_half_fov_rad_ = 0.0;
  std::unique_ptr<slam::frontend::LidarConeDetector> lidar_detector_;
  std::unique_ptr<slam::frontend::StereoConeDetector> stereo_detector_;
  slam::frontend::FusionConfig fusion_;
  slam::frontend::ConeTracker tracker_;
  std::optional<core::TimeUs> tracker_stamp_;
  slam::frontend::SweepMotion motion_;
  core::Vec2 lidar_xy_ = core::Vec2::Zero();
  // the latest stereo result, for fusion
  std::optional<slam::frontend::StereoDetections> latest_stereo_;
  core::CameraIntrinsics intrinsics_;
  core::Pose3 left_in_vehicle_;
  // scorers: what SLAM receives, and each sensor's own detections
  std::unique_ptr<PerceptionScorer> delivered_score_;
  std::unique_ptr<PerceptionScorer> lidar_score_;
  // the LiDAR against only the cones its beams returned from (the detector's own share)
  std::unique_ptr<PerceptionScorer> lidar_returned_score_;
  std::unique_ptr<PerceptionScorer> stereo_score_;
  // with scenery (world.clutter): the LiDAR's detections, and those on each clutter class
  bool score_clutter_ = false;
  int64_t lidar_detections_ = 0;
  std::array<int64_t, core::kClutterClassCount> clutter_detections_{};
  // the camera's detections within the scorer's range, its false ones, and those near each
  // clutter class
  int64_t stereo_detections_ = 0;
  int64_t stereo_false_positives_ = 0;
  std::array<int64_t, core::kClutterClassCount> stereo_clutter_detections_{};
  std::vector<tracks::SceneryObject> scenery_;
  // the spare cones standing off the track (track frame), k-th labelled off_track_cone(k)
  std::vector<core::Vec2> off_track_cones_;
};

}  // namespace conesim::sim
