#include "sim/perception_runner.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <optional>
#include <stdexcept>

#include "core/clutter.hpp"
#include "sdk/builtin/lidar_frontend.hpp"
#include "sensors/lidar_config.hpp"

namespace conesim::sim {

namespace {

// the scorers look this far from the sensor, in 5 m bands
constexpr double kScoreBandM = 5.0;
constexpr double kScoreRangeM = 30.0;
// a cone that returned fewer points than this is beyond what a cone detector can find
constexpr int kMinReturns = 3;
// a camera's false detection this near an object's footprint is put down to the object (the
// scorers' matching cutoff)
constexpr double kClutterCutoffM = 1.0;

// the label more than half of a LiDAR cluster's points carry (a cone id, the ground or a
// clutter class), nullopt when none has a majority
std::optional<int> majority_label(const slam::frontend::LidarCone& cone,
                                  const core::PointCloudLabels& labels) {
  std::map<int, int> votes;
  for (int i : cone.point_indices) ++votes[labels.cone_id[static_cast<size_t>(i)]];
  int best = core::ObservationLabels::kFalsePositive;
  int best_votes = 0;
  for (const auto& [id, n] : votes)
    if (n > best_votes) best = id, best_votes = n;
  if (2 * best_votes <= static_cast<int>(cone.point_indices.size())) return std::nullopt;
  return best;
}

// the true cone a LiDAR cluster stands for: the label most of its points carry (-1 when most
// points are ground or clutter, or no cone has a majority)
int cluster_label(const slam::frontend::LidarCone& cone, const core::PointCloudLabels& labels) {
  const std::optional<int> best = majority_label(cone, labels);
  return best && *best >= 0 ? *best : core::ObservationLabels::kFalsePositive;
}

// a detector's detections over the run and those that clutter caused, by class, each with its
// share of all the detections (the precision that class cost)
nlohmann::json clutter_json(int64_t detections,
                            const std::array<int64_t, core::kClutterClassCount>& counts) {
  nlohmann::json by_class = nlohmann::json::object();
  for (core::ClutterClass c : core::kClutterClasses) {
    const int64_t n = counts[static_cast<size_t>(c)];
    by_class[std::string(core::to_string(c))] = {
        {"detections", n},
        {"share_of_detections",
         detections > 0 ? static_cast<double>(n) / static_cast<double>(detections) : 0.0}};
  }
  return {{"detections", detections}, {"by_class", by_class}};
}

}  // namespace

LidarSweepOutcome judge_lidar_sweep(const sensors::LidarScan& scan,
                                    const slam::frontend::LidarDetections& detections,
                                    const tracks::Track& track,
                                    const std::function<bool(int)>& is_knocked) {
  LidarSweepOutcome out;
  std::vector<bool> found(static_cast<size_t>(track.next_id()), false);
  for (const auto& cone : detections.cones) {
    const int id = cluster_label(cone, scan.labels);
    out.detection_cone.push_back(id >= 0 ? id : -1);
    if (id >= 0 && static_cast<size_t>(id) < found.size()) found[static_cast<size_t>(id)] = true;
  }
  std::vector<int> returns(found.size(), 0);
  for (int id : scan.labels.cone_id)
    if (id >= 0 && static_cast<size_t>(id) < returns.size()) ++returns[static_cast<size_t>(id)];
  const core::Pose2 sensor = scan.labels.sensor_pose_end.planar();
  for (const tracks::Cone& c : track.cones) {
    const auto i = static_cast<size_t>(c.id);
    if (found[i] || returns[i] < kMinReturns || (is_knocked && is_knocked(c.id))) continue;
    if (sensor.inverse_transform(c.position).norm() > kScoreRangeM) continue;
    out.missed.push_back(c.id);
  }
  return out;
}

core::Pose2 motion_over(const slam::frontend::SweepMotion& m, double dt) {
  return slam::frontend::motion_over(m.speed_mps, m.yaw_rate_rps, dt);
}

PerceptionView perception_view(const Scenario& s) {
  PerceptionView v;
  // a perception plug-in sees with the sensors it is given, the LiDAR first
  const bool plugin_lidar = s.perception_plugin && s.perception_plugin->lidar;
  const bool plugin_camera = s.perception_plugin && !s.perception_plugin->lidar;
  if (s.perception == "lidar" || s.perception == "fused" || plugin_lidar) {
    // the farthest ground distance at which two rings still hit a small cone between 5 cm and
    // its top, from the mount's height (a level mount)
    const sensors::LidarConfig lidar = s.sensors.lidar_config();
    const double height_m = lidar.mount.position.z();
    const double cone_m = core::cone_size(core::ConeClass::kBlue).height_m;
    double visible = 0.0;
    for (double d = 1.0; d <= 30.0; d += 0.1) {
      int rings = 0;
      for (double e : lidar.elevations_deg) {
        const double z = height_m + d * std::tan(e * std::numbers::pi / 180.0);
        if (z >= 0.05 && z <= cone_m) ++rings;
      }
      if (rings >= 2) visible = d;
    }
    v.sensor_x_m = lidar.mount.position.x();
    v.min_range_m = 1.0;
    v.max_range_m = std::min(visible, 15.0);
    v.fov_deg = 360.0;
    return v;
  }
  if (s.perception == "stereo" || plugin_camera) {
    v.sensor_x_m = s.sensors.camera.mount_x_m;
    v.min_range_m = 2.0;
    v.max_range_m = 12.0;
    v.fov_deg = s.sensors.camera.horizontal_fov_deg;
    return v;
  }
  const auto& cs = s.sensors.cone_sensor;
  v.sensor_x_m = cs.mount_x_m;
  v.min_range_m = cs.min_range_m;
  v.max_range_m = cs.max_range_m;
  v.fov_deg = cs.fov_deg;
  return v;
}

PerceptionRunner::PerceptionRunner(const Scenario& s, const tracks::Track& track,
                                   const core::Pose3& lidar_mount)
    : track_(track), mode_(s.perception), tracker_(slam::frontend::TrackerConfig{}) {
  lidar_xy_ = lidar_mount.position.head<2>();
  lidar_mount_ = lidar_mount;
  score_clutter_ = s.clutter.objects_per_100m > 0.0 || s.clutter.grass_edge;
  if (s.perception_plugin) {
    // a plug-in in place of the detectors: given the sensors the scenario names, scored on
    // what it delivers (against the cones around the LiDAR, or in the camera's view)
    const PluginSpec& spec = *s.perception_plugin;
    uses_lidar_ = spec.lidar;
    uses_camera_ = spec.camera;
    const std::unique_ptr<RunInfoStorage> run =
        make_run_info(s, driver_vehicle(s.vehicle), core::Pose2{}, {});
    plugin_ = make_plugin_perception(spec, run->info);
    plugin_guard_ = std::make_unique<PluginGuard>(spec);
    plugin_sensor_xy_ = spec.lidar ? lidar_xy_ : core::Vec2(s.sensors.camera.mount_x_m, 0.0);
    plugin_half_fov_rad_ =
        spec.lidar ? std::numbers::pi
                   : 0.5 * s.sensors.camera.horizontal_fov_deg * std::numbers::pi / 180.0;
    // (one given the camera alone is scored as the stereo front-end is, from its first pair)
    if (spec.lidar)
      delivered_score_ =
          std::make_unique<PerceptionScorer>(plugin_sensor_xy_, kScoreBandM, kScoreRangeM);
    return;
  }
  const bool lidar = mode_ == "lidar" || mode_ == "fused";
  const bool camera = mode_ == "stereo" || mode_ == "fused";
  if (!lidar && !camera)
    throw std::invalid_argument("perception: raw-data perception is lidar, stereo or fused, not " +
                                mode_);
  uses_lidar_ = lidar;
  uses_camera_ = camera;
  if (lidar) {
    lidar_detector_ = std::make_unique<slam::frontend::LidarConeDetector>(
        // (the scenario's LiDAR: its beam pattern, noise and spot, as a team calibrates them)
        sdk_bridge::lidar_detector_config(s.sensors.lidar_config()),
        lidar_mount);
    lidar_score_ = std::make_unique<PerceptionScorer>(lidar_xy_, kScoreBandM, kScoreRangeM);
    lidar_returned_score_ =
        std::make_unique<PerceptionScorer>(lidar_xy_, kScoreBandM, kScoreRangeM);
  }
  if (camera) {
    stereo_detector_ = std::make_unique<slam::frontend::StereoConeDetector>(
        slam::frontend::StereoDetectorConfig{});
  }
  if (lidar)
    delivered_score_ = std::make_unique<PerceptionScorer>(lidar_xy_, kScoreBandM, kScoreRangeM);
}

PerceptionRunner::~PerceptionRunner() {
  // a plug-in whose call was left running is kept for good
  if (plugin_guard_) keep_if_abandoned(*plugin_guard_, plugin_);
}

void PerceptionRunner::set_scenery(const std::vector<tracks::SceneryObject>& scenery) {
  scenery_ = scenery;
  off_track_cones_.clear();
  for (const tracks::SceneryObject& o : scenery_)
    if (o.cls == core::ClutterClass::kSpareCone) off_track_cones_.push_back(o.pose.position());
}

std::vector<OffTrackConeInView> PerceptionRunner::off_track_in_view(
    const core::Pose2& true_pose) const {
  std::vector<OffTrackConeInView> out;
  for (size_t k = 0; k < off_track_cones_.size(); ++k) {
    const core::Vec2 local = true_pose.inverse_transform(off_track_cones_[k]);
    if (local.norm() > kScoreRangeM + kClutterCutoffM + 2.0) continue;
    out.push_back({core::ObservationLabels::off_track_cone(static_cast<int>(k)), local});
  }
  return out;
}

std::vector<TrueConeInView> PerceptionRunner::truth_in_view(
    const core::Pose2& true_pose, const core::Vec2& sensor, double half_fov_rad,
    const std::function<bool(int)>& is_knocked) const {
  std::vector<TrueConeInView> out;
  for (const tracks::Cone& c : track_.cones) {
    if (is_knocked && is_knocked(c.id)) continue;
    const core::Vec2 local = true_pose.inverse_transform(c.position);
    const core::Vec2 from_sensor = local - sensor;
    if (from_sensor.norm() > kScoreRangeM) continue;
    if (std::abs(std::atan2(from_sensor.y(), from_sensor.x())) > half_fov_rad) continue;
    out.push_back({c.id, c.cls, local});
  }
  return out;
}

core::ConeObservations PerceptionRunner::track(const core::ConeObservations& frame,
                                               const slam::frontend::SweepMotion& motion) {
  const double dt = tracker_stamp_ ? core::to_seconds(frame.stamp - *tracker_stamp_) : 0.0;
  tracker_stamp_ = frame.stamp;
  return tracker_.update(frame, motion_over(motion, dt));
}

DeliveredDetections PerceptionRunner::on_lidar(const sensors::LidarScan& scan,
                                               const slam::frontend::LidarDetections& detections,
                                               const slam::frontend::SweepMotion& motion,
                                               const core::Pose2& true_pose,
                                               const std::function<bool(int)>& is_knocked) {
  // the LiDAR alone, scored against the true cones all round
  const auto truth = truth_in_view(true_pose, lidar_xy_, std::numbers::pi, is_knocked);
  const core::ConeObservations raw = detections.observations();
  const std::vector<OffTrackConeInView> off_track = off_track_in_view(true_pose);
  lidar_score_->add_frame(raw, truth, off_track);
  // and against the cones that returned enough points to be found at all
  std::vector<int> returns(static_cast<size_t>(track_.next_id()), 0);
  for (int id : scan.labels.cone_id)
    if (id >= 0) ++returns[static_cast<size_t>(id)];
  std::vector<TrueConeInView> returned;
  for (const TrueConeInView& c : truth)
    if (returns[static_cast<size_t>(c.id)] >= kMinReturns) returned.push_back(c);
  lidar_returned_score_->add_frame(raw, returned, off_track);
  // with scenery, the detections whose points lie mostly on a clutter object, by its class
  if (score_clutter_) {
    lidar_detections_ += static_cast<int64_t>(detections.cones.size());
    for (const auto& cone : detections.cones)
      if (const std::optional<int> label = majority_label(cone, scan.labels))
        if (const auto cls = core::clutter_of_label(*label))
          ++clutter_detections_[static_cast<size_t>(*cls)];
  }

  // fused: colours from the latest stereo pair, moved into this sweep's frame by the odometry
  core::ConeObservations frame = raw;
  std::vector<int> labels;
  if (mode_ == "fused") {
    core::Pose2 camera_in_lidar;
    if (latest_stereo_)
      camera_in_lidar =
          motion_over(motion_, core::to_seconds(latest_stereo_->stamp - detections.stamp));
    frame = slam::frontend::fuse(fusion_, detections, latest_stereo_, intrinsics_, left_in_vehicle_,
                                 camera_in_lidar);
    frame.stamp = detections.stamp;
  } else {
    // a cluster on a spare cone: that cone's label (the nearest spare cone to the detection)
    for (const auto& cone : detections.cones) {
      const std::optional<int> majority = majority_label(cone, scan.labels);
      const bool spare =
          majority && core::clutter_of_label(*majority) == core::ClutterClass::kSpareCone;
      labels.push_back(spare ? off_track_label_near(off_track, cone.observation.position,
                                                    kClutterCutoffM)
                             : cluster_label(cone, scan.labels));
    }
  }

  // tracked ids and colour votes, then the score of what SLAM receives
  frame = track(frame, motion);
  const std::vector<int> matched = delivered_score_->add_frame(frame, truth, off_track);
  DeliveredDetections out;
  out.observations = std::move(frame);
  // the point labels are exact for LiDAR clusters; fused frames are labelled by the match
  out.labels.cone_id = labels.size() == out.observations.cones.size() ? labels : matched;
  out.capture_pose = true_pose;
  return out;
}

std::optional<DeliveredDetections> PerceptionRunner::on_stereo(
    const core::StereoFrame& frame, const slam::frontend::StereoDetections& detections,
    const core::Pose2& true_pose, const std::function<bool(int)>& is_knocked) {
  // the camera alone, scored against the true cones in its field of view
  intrinsics_ = frame.intrinsics;
  left_in_vehicle_ = frame.left_in_vehicle;
  const core::Vec2 camera_xy = frame.left_in_vehicle.position.head<2>();
  if (!stereo_score_)
    stereo_score_ = std::make_unique<PerceptionScorer>(camera_xy, kScoreBandM, kScoreRangeM);
  if (mode_ == "stereo" && !delivered_score_)
    delivered_score_ = std::make_unique<PerceptionScorer>(camera_xy, kScoreBandM, kScoreRangeM);
  // a stereo pair measures a cone only where both images hold all of it: the true cones in
  // view are those wholly inside the left and the right camera's field of view
  const double half_fov = std::atan2(frame.intrinsics.cx, frame.intrinsics.fx);
  const auto in_left = in_left_image(frame, true_pose, is_knocked);
  std::vector<TrueConeInView> truth;
  std::vector<core::Vec2> partial;
  for (const TrueConeInView& c : in_left) {
    bool whole = true;
    for (const core::Pose3* camera : {&frame.left_in_vehicle, &frame.right_in_vehicle}) {
      const core::Vec2 v = c.position - camera->position.head<2>();
      const double half_width = std::atan2(0.5 * core::cone_size(c.cls).base_m, v.norm());
      whole = whole && v.x() > 0.0 && std::abs(std::atan2(v.y(), v.x())) + half_width <= half_fov;
    }
    if (whole)
      truth.push_back(c);
    else
      partial.push_back(c.position);
  }
  // a cone cut by an image border is neither to be found nor a false detection (as KITTI's
  // DontCare regions): detections within 1 m of one are left out of the camera's own score
  core::ConeObservations scored = detections.observations();
  std::erase_if(scored.cones, [&partial](const core::ConeObservation& o) {
    return std::any_of(partial.begin(), partial.end(),
                       [&o](const core::Vec2& p) { return (o.position - p).norm() < 1.0; });
  });
  const std::vector<OffTrackConeInView> off_track = off_track_in_view(true_pose);
  const std::vector<int> stereo_matches = stereo_score_->add_frame(scored, truth, off_track);
  // with scenery, each false detection within the scorer's range is put down to the clutter
  // object it lies on (within the matching cutoff of the object's footprint), if any
  if (score_clutter_)
    for (size_t i = 0; i < scored.cones.size(); ++i) {
      const core::Vec2 at = scored.cones[i].position;
      if ((at - camera_xy).norm() > kScoreRangeM) continue;
      ++stereo_detections_;
      if (stereo_matches[i] != core::ObservationLabels::kFalsePositive) continue;
      ++stereo_false_positives_;
      const core::Vec2 in_track = true_pose.transform(at);
      for (const tracks::SceneryObject& o : scenery_)
        if ((in_track - o.pose.position()).norm() <= o.radius_m + kClutterCutoffM) {
          ++stereo_clutter_detections_[static_cast<size_t>(o.cls)];
          break;
        }
    }
  if (mode_ == "fused") {
    latest_stereo_ = detections;
    return std::nullopt;
  }

  // stereo alone drives SLAM
  core::ConeObservations tracked = track(detections.observations(), motion_);
  tracked.stamp = detections.stamp;
  DeliveredDetections out;
  // (what SLAM receives is labelled against every cone in the left image)
  out.labels.cone_id = delivered_score_->add_frame(tracked, in_left, off_track);
  out.observations = std::move(tracked);
  out.capture_pose = true_pose;
  return out;
}

core::ConeObservations PerceptionRunner::plugin_lidar(
    const core::PointCloud& cloud, core::TimeUs end,
    const slam::frontend::SweepMotion& motion) const {
  std::vector<sdk::LidarPoint> points;
  sdk::LidarSweep sweep;
  sweep.stamp_us = cloud.stamp;
  sweep.end_us = end;
  sweep.points = to_sdk(cloud, points);
  sweep.sensor_in_vehicle = to_sdk(lidar_mount_);
  const sdk::ConeFrame frame = plugin_guard_->call("on_lidar", [&] {
    return plugin_.object->on_lidar(sweep, {motion.speed_mps, motion.yaw_rate_rps});
  });
  core::ConeObservations out = from_sdk(frame);
  for (const core::ConeObservation& o : out.cones) {
    plugin_guard_->check_finite("a cone's x_m", o.position.x());
    plugin_guard_->check_finite("a cone's y_m", o.position.y());
  }
  // a frame is in the vehicle frame at the sweep's end
  if (out.stamp >= 0) out.stamp = end;
  return out;
}

core::ConeObservations PerceptionRunner::plugin_stereo(const core::StereoFrame& f) const {
  const sdk::StereoFrame frame = to_sdk(f);
  const sdk::ConeFrame cones = plugin_guard_->call("on_stereo", [&] {
    return plugin_.object->on_stereo(frame, {motion_.speed_mps, motion_.yaw_rate_rps});
  });
  core::ConeObservations out = from_sdk(cones);
  for (const core::ConeObservation& o : out.cones) {
    plugin_guard_->check_finite("a cone's x_m", o.position.x());
    plugin_guard_->check_finite("a cone's y_m", o.position.y());
  }
  if (out.stamp >= 0) out.stamp = f.stamp;
  return out;
}

std::vector<TrueConeInView> PerceptionRunner::in_left_image(
    const core::StereoFrame& frame, const core::Pose2& true_pose,
    const std::function<bool(int)>& is_knocked) const {
  const double half_fov = std::atan2(frame.intrinsics.cx, frame.intrinsics.fx);
  return truth_in_view(true_pose, frame.left_in_vehicle.position.head<2>(), half_fov, is_knocked);
}

std::optional<DeliveredDetections> PerceptionRunner::on_plugin_frame(
    core::ConeObservations frame, const core::Pose2& true_pose,
    const std::function<bool(int)>& is_knocked, const core::StereoFrame* pair) {
  if (frame.stamp < 0) return std::nullopt;
  // the cones around the LiDAR; a pair's frame against every cone in the left image, from the
  // left camera (as the stereo front-end's)
  if (pair && !delivered_score_)
    delivered_score_ = std::make_unique<PerceptionScorer>(pair->left_in_vehicle.position.head<2>(),
                                                          kScoreBandM, kScoreRangeM);
  const auto truth =
      pair ? in_left_image(*pair, true_pose, is_knocked)
           : truth_in_view(true_pose, plugin_sensor_xy_, plugin_half_fov_rad_, is_knocked);
  DeliveredDetections out;
  out.labels.cone_id = delivered_score_->add_frame(frame, truth, off_track_in_view(true_pose));
  out.observations = std::move(frame);
  out.capture_pose = true_pose;
  return out;
}

nlohmann::json PerceptionRunner::metrics() const {
  nlohmann::json m = delivered_score_ ? delivered_score_->metrics() : nlohmann::json::object();
  m["mode"] = mode_;
  if (lidar_score_) m["lidar"] = lidar_score_->metrics();
  if (lidar_returned_score_) m["lidar_returned_cones"] = lidar_returned_score_->metrics();
  // what fooled each detector: its detections on (LiDAR) or near (camera) each clutter class
  if (score_clutter_ && lidar_score_)
    m["lidar_clutter"] = clutter_json(lidar_detections_, clutter_detections_);
  if (score_clutter_ && stereo_score_) {
    m["stereo_clutter"] = clutter_json(stereo_detections_, stereo_clutter_detections_);
    m["stereo_clutter"]["false_positives"] = stereo_false_positives_;
  }
  if (stereo_score_) m["stereo"] = stereo_score_->metrics();
  return m;
}

void PerceptionRunner::write_plot(const std::filesystem::path& png) const {
  if (delivered_score_) delivered_score_->write_bands_plot(png);
}

}  // namespace conesim::sim
