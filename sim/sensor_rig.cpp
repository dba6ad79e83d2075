#include "sim/sensor_rig.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <set>
#include <stdexcept>

#include "sensors/png_writer.hpp"
#include "sim/gnuplot.hpp"
#include "sim/json_text.hpp"

namespace conesim::sim {

namespace fs = std::filesystem;
using core::TimeUs;

namespace {

// independent noise streams per sensor, derived from the scenario seed
constexpr uint64_t kConeSensorStream = 101;
constexpr uint64_t kLidarStream = 102;
// a LiDAR sweep goes to the worker in parts of this many column blocks (128 columns, 7 ms of
// a 10 Hz sweep of 1800 columns), each as soon as the poses reach its last column
constexpr int kBlocksPerPart = 4;
// the spacing of the poses handed to the worker: the physics step
constexpr TimeUs kPoseStepUs = 1000;

using clock = std::chrono::steady_clock;

double ms_between(clock::time_point from, clock::time_point to) {
  return std::chrono::duration<double, std::milli>(to - from).count();
}

std::string frame_name(int index, const char* ext) {
  char name[32];
  std::snprintf(name, sizeof(name), "%06d.%s", index, ext);
  return name;
}

nlohmann::json pose3_json(const core::Pose3& p) {
  return {{"position", {p.position.x(), p.position.y(), p.position.z()}},
          {"orientation_wxyz",
           {p.orientation.w(), p.orientation.x(), p.orientation.y(), p.orientation.z()}}};
}

nlohmann::json pose2_json(const core::Pose2& p) {
  return {{"x", p.x}, {"y", p.y}, {"yaw", p.yaw}};
}

void write_text(const fs::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary);
  out << text;
  if (!out) throw std::runtime_error(file.string() + ": cannot write");
}

// an ASCII PCD (v0.7) with the fields x y z intensity ring time label
void write_pcd(const fs::path& file, const core::PointCloud& cloud,
               const core::PointCloudLabels& labels) {
  std::string text;
  text.reserve(cloud.points.size() * 48 + 256);
  const size_t n = cloud.points.size();
  text += "# .PCD v0.7 - conesim LiDAR sweep (label: true cone id, -1 ground)\n";
  text += "VERSION 0.7\nFIELDS x y z intensity ring time label\n";
  text += "SIZE 4 4 4 4 2 4 4\nTYPE F F F F U F I\nCOUNT 1 1 1 1 1 1 1\n";
  text += "WIDTH " + std::to_string(n) + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n";
  text += "POINTS " + std::to_string(n) + "\nDATA ascii\n";
  char row[160];
  for (size_t i = 0; i < n; ++i) {
    const auto& p = cloud.points[i];
    std::snprintf(row, sizeof(row), "%.4f %.4f %.4f %.1f %u %.6f %d\n", p.x, p.y, p.z, p.intensity,
                  static_cast<unsigned>(p.ring), p.time_offset_s, labels.cone_id[i]);
    text += row;
  }
  write_text(file, text);
}

// draws each detected cone's box (two pixels wide) in its class colour
void draw_boxes(const slam::frontend::StereoDetections& detections, core::RgbImage& image) {
  auto colour = [](core::ConeClass c) -> std::array<uint8_t, 3> {
    switch (c) {
      case core::ConeClass::kBlue:
        return {40, 90, 255};
      case core::ConeClass::kYellow:
        return {255, 230, 0};
      case core::ConeClass::kOrangeSmall:
        return {255, 120, 0};
      case core::ConeClass::kOrangeBig:
        return {255, 0, 160};
      case core::ConeClass::kUnknown:
        break;
    }
    return {255, 255, 255};
  };
  auto put = [&image](int x, int y, const std::array<uint8_t, 3>& rgb) {
    if (x < 0 || y < 0 || x >= image.width_px || y >= image.height_px) return;
    const size_t i = 3 * (static_cast<size_t>(y) * image.width_px + x);
    image.rgb[i] = rgb[0], image.rgb[i + 1] = rgb[1], image.rgb[i + 2] = rgb[2];
  };
  for (const auto& cone : detections.cones) {
    const auto rgb = colour(cone.observation.cls);
    const auto& b = cone.box;
    for (int k = 0; k < 2; ++k) {
      for (int x = b.x - k; x <= b.x + b.width + k; ++x) {
        put(x, b.y - k, rgb);
        put(x, b.y + b.height + k, rgb);
      }
      for (int y = b.y - k; y <= b.y + b.height + k; ++y) {
        put(b.x - k, y, rgb);
        put(b.x + b.width + k, y, rgb);
      }
    }
  }
}

}  // namespace

// A LiDAR sweep being cast on the worker a part at a time: the worker's alone while parts of
// it are queued.
struct SensorRig::SweepInProgress {
  sensors::LidarScan scan;
  // the noise, started at the sweep's first column, and the generator as it was then (a cone
  // knocked over during the sweep makes it start again)
  std::optional<sensors::LidarNoise> noise;
  core::Rng rng_at_start;
  double cast_ms = 0.0;

  // casts the columns [begin, end) (on the worker)
  void cast(const sensors::Lidar& lidar, core::Rng& rng, TimeUs start, int begin, int end,
            const sensors::PoseHistory& poses) {
    const auto t0 = clock::now();
    if (begin == 0) {
      rng_at_start = rng;
      noise.emplace(rng);
    }
    if (!noise) throw std::logic_error("lidar sweep: a part was cast before the sweep's start");
    lidar.sweep_columns(start, begin, end, poses, *noise, scan);
    cast_ms += ms_between(t0, clock::now());
  }
};

SensorRig::SensorRig(const Scenario& s, const tracks::Track& track, const VehicleSim& car,
                     const DumpOptions& dump, const fs::path& run_dir, SensorTap* tap)
    : track_(track),
      dump_(dump),
      run_dir_(run_dir),
      tap_(tap),
      lidar_rng_(core::derive_seed(s.seed, kLidarStream)),
      faults_(s.faults, s.seed),
      fault_counts_(faults_.zero_counts()) {
  for (const Fault& f : s.faults) {
    jitter_ = jitter_ || f.kind == FaultKind::kDelayJitter;
    freezes_ = freezes_ || f.kind == FaultKind::kCameraFrozen;
  }
  // the cone sensor: the perception of `perception: cone_sensor`, or dumped
  if (s.perception == "cone_sensor" || dump_.sensors.count("detections")) {
    if (const std::string e = s.sensors.cone_sensor.validate(); !e.empty())
      throw std::invalid_argument("sensors." + e);
    cone_sensor_ = std::make_unique<sensors::ConeSensor>(
        s.sensors.cone_sensor, core::derive_seed(s.seed, kConeSensorStream));
    cone_period_us_ = s.sensors.cone_sensor.timing.period_us();
    if (s.sensors.cone_sensor_track)
      cone_tracker_ =
          std::make_unique<slam::frontend::ConeTracker>(slam::frontend::TrackerConfig{});
    cone_latency_us_ = s.sensors.cone_sensor.timing.latency_us();
  }

  // raw-data perception switches on the sensors it needs
  const bool raw_lidar = s.perception == "lidar" || s.perception == "fused";
  const bool raw_camera = s.perception == "stereo" || s.perception == "fused";
  const bool tap_lidar = tap_ && tap_->kinds().lidar;
  const bool tap_camera = tap_ && tap_->kinds().camera;

  // the LiDAR sweeps from the first step on
  if (s.sensors.lidar_enabled || raw_lidar || tap_lidar || dump_.sensors.count("lidar")) {
    auto config = sensors::lidar_preset(s.sensors.lidar_model);
    const auto mount = sensors::lidar_mount_preset(s.sensors.lidar_mount);
    if (!config)
      throw std::invalid_argument("sensors.lidar.model: unknown model " + s.sensors.lidar_model);
    if (!mount)
      throw std::invalid_argument("sensors.lidar.mount: unknown mount " + s.sensors.lidar_mount);
    config->mount = *mount;
    lidar_mount_ = *mount;
    lidar_ = std::make_unique<sensors::Lidar>(*config, track);
    poses_ = sensors::PoseHistory(2 * config->sweep_period_us());
    poses_.push(0, car.vehicle_pose3());
    lidar_latency_us_ = core::from_seconds(s.sensors.lidar_latency_s);
    casting_ = std::make_shared<SweepInProgress>();
    worker_ = std::make_unique<WorkerThread>();
  }

  // the stereo camera
  if (s.sensors.camera_enabled || raw_camera || tap_camera || dump_.sensors.count("camera")) {
    if (const std::string e = s.sensors.camera.validate(); !e.empty())
      throw std::invalid_argument("sensors.camera." + e);
    camera_ = std::make_unique<sensors::StereoCamera>(s.sensors.camera, car.model(), track);
    camera_period_us_ = core::from_seconds(1.0 / s.sensors.camera_rate_hz);
    with_depth_ = s.sensors.camera_depth;
    camera_latency_us_ = core::from_seconds(s.sensors.camera_latency_s);
  }
  if (raw_lidar || raw_camera || s.perception_plugin)
    perception_ = std::make_unique<PerceptionRunner>(
        s, track, lidar_ ? lidar_->config().mount : core::Pose3{});

  // the dump folders
  for (const std::string& name : dump_.sensors) {
    if (name == "camera") {
      fs::create_directories(run_dir_ / "images/camera/left");
      fs::create_directories(run_dir_ / "images/camera/right");
    } else {
      fs::create_directories(run_dir_ / "images" / name);
    }
  }
}

// the worker runs what is queued before it stops, and stops before the members its jobs use
SensorRig::~SensorRig() = default;

void SensorRig::finish() {
  if (pending_scan_.valid()) collect_sweep();
}

void SensorRig::sync_knocked_cones(const Referee& referee) {
  // a knocked cone leaves the LiDAR scene (the camera and cone sensor ask the referee)
  const auto& hit = referee.result().cones_hit;
  if (knocked_seen_ == hit.size()) return;
  // the scene must not change under a sweep in flight: the worker finishes what it has, the
  // sweep that has ended is collected, and the one being cast starts again without the cone
  if (worker_) worker_->wait_idle();
  if (pending_scan_.valid()) collect_sweep();
  for (; knocked_seen_ < hit.size(); ++knocked_seen_)
    if (lidar_) lidar_->set_cone_present(hit[knocked_seen_], false);
  if (lidar_) restart_sweep();
}

void SensorRig::step(TimeUs t, const VehicleSim& car, const Referee& referee) {
  referee_ = &referee;
  sync_knocked_cones(referee);
  if (lidar_) {
    poses_.push(t, car.vehicle_pose3());
    // a sweep whose cones SLAM (or whose points the tap) waits for is collected when its
    // latency has passed; a sweep only recorded goes on computing until the next one starts
    if (pending_scan_.valid() &&
        ((perception_ && perception_->uses_lidar()) || (tap_ && tap_->kinds().lidar)) &&
        t >= pending_delivery_us_)
      collect_sweep();
    if (t > lidar_->sweep_end(sweep_start_))
      end_sweep();
    else
      cast_columns(t);
  }
  if (camera_ && t % camera_period_us_ == 0) render_camera(t, car, referee);
  if (cone_sensor_ && t % cone_period_us_ == 0) sense_cones(t, car, referee);
}

sensors::PoseHistory SensorRig::pose_window(TimeUs from, TimeUs to) const {
  // the poses of the physics steps around [from, to] (the history changes while the worker
  // casts, so it gets a copy)
  sensors::PoseHistory window(2 * lidar_->config().sweep_period_us());
  TimeUs t = sweep_start_ + (from - sweep_start_) / kPoseStepUs * kPoseStepUs;
  for (;; t += kPoseStepUs) {
    window.push(t, poses_.at(std::min(t, poses_.newest())));
    if (t >= to) break;
  }
  return window;
}

void SensorRig::cast_columns(TimeUs t) {
  // the next parts whose last column has fired; the sweep's last part goes with its end
  const int columns = lidar_->config().columns;
  const int part = kBlocksPerPart * lidar_->column_block();
  for (int end = columns_posted_ + part; end < columns; end += part) {
    if (lidar_->column_time(sweep_start_, end - 1) > t) return;
    const int begin = columns_posted_;
    const TimeUs start = sweep_start_;
    posted_parts_.push_back(
        worker_->post([this, sweep = casting_, start, begin, end,
                       window = pose_window(lidar_->column_time(start, begin),
                                            lidar_->column_time(start, end - 1))] {
          sweep->cast(*lidar_, lidar_rng_, start, begin, end, window);
        }));
    columns_posted_ = end;
  }
}

void SensorRig::end_sweep() {
  // one sweep at a time: the previous one is collected first
  if (pending_scan_.valid()) collect_sweep();
  const TimeUs start = sweep_start_;
  const TimeUs end = lidar_->sweep_end(start);
  const int begin = columns_posted_;
  const int columns = lidar_->config().columns;
  pending_delivery_us_ = end + lidar_latency_us_;
  pending_parts_ = std::move(posted_parts_);
  posted_parts_.clear();
  // the last part, then the cone detector on the same thread, with the motion the autonomy
  // estimates now
  const slam::frontend::LidarConeDetector* detector =
      perception_ ? perception_->lidar_detector() : nullptr;
  // or a perception plug-in in its place: on the worker when it has only the LiDAR; one with
  // the camera too is called here at collection, in order with its stereo calls (determinism)
  const bool plugin_lidar = perception_ && perception_->is_plugin() && perception_->uses_lidar();
  const PerceptionRunner* plugin =
      plugin_lidar && !perception_->uses_camera() ? perception_.get() : nullptr;
  const slam::frontend::SweepMotion motion =
      perception_ ? perception_->motion() : slam::frontend::SweepMotion{};
  const int64_t index = start / lidar_->config().sweep_period_us();
  pending_scan_ =
      worker_->post([this, sweep = casting_, start, begin, columns, detector, plugin, motion, end,
                     index, window = pose_window(lidar_->column_time(start, begin), end)] {
        sweep->cast(*lidar_, lidar_rng_, start, begin, columns, window);
        SweepResult r{std::move(sweep->scan),
                      std::nullopt,
                      sweep->cast_ms,
                      0.0,
                      std::nullopt,
                      {},
                      end,
                      motion,
                      false,
                      faults_.zero_counts()};
        // the faults: a lost sweep never reaches perception; dropout and blind sectors take
        // points before the detector sees them
        if (!faults_.empty()) {
          r.lost = faults_.lidar_sweep_lost(index, end, r.fault_counts);
          if (r.lost) return r;
          faults_.apply_lidar(r.scan.cloud, r.scan.labels, r.fault_counts);
        }
        if (detector) {
          const auto t0 = clock::now();
          r.detections = detector->detect(r.scan.cloud, motion, end);
          r.detect_ms = ms_between(t0, clock::now());
        }
        if (plugin) {
          const auto t0 = clock::now();
          try {
            r.plugin_frame = plugin->plugin_lidar(r.scan.cloud, end, motion);
          } catch (const PluginFailure& e) {
            r.plugin_failure = e.what();
          }
          r.detect_ms = ms_between(t0, clock::now());
        }
        return r;
      });

  // the next sweep
  sweep_start_ += lidar_->config().sweep_period_us();
  casting_ = std::make_shared<SweepInProgress>();
  columns_posted_ = 0;
}

void SensorRig::restart_sweep() {
  // the worker is idle: the sweep being cast is dropped and its noise drawn again
  for (std::future<void>& part : posted_parts_) part.get();
  posted_parts_.clear();
  if (columns_posted_ > 0) lidar_rng_ = casting_->rng_at_start;
  casting_ = std::make_shared<SweepInProgress>();
  columns_posted_ = 0;
}

void SensorRig::collect_sweep() {
  for (std::future<void>& part : pending_parts_) part.get();
  pending_parts_.clear();
  SweepResult result = pending_scan_.get();
  const sensors::LidarScan& scan = result.scan;
  stats_.lidar_ms_total += result.cast_ms;
  const int index = stats_.lidar_scans++;
  stats_.lidar_points += static_cast<int64_t>(scan.cloud.points.size());
  fault_counts_.add(result.fault_counts);
  if (result.lost) {
    ++stats_.lidar_sweeps_lost;
    return;
  }

  // the tap gets the sweep as a perception plug-in does, when its latency has passed
  if (tap_ && tap_->kinds().lidar &&
      tap_lidar_sweeps_++ % std::max(1, tap_->kinds().lidar_every) == 0) {
    sdk::LidarSweep sweep;
    sweep.stamp_us = scan.cloud.stamp;
    sweep.end_us = result.end_us;
    sweep.points = to_sdk(scan.cloud, tap_points_);
    sweep.sensor_in_vehicle = to_sdk(lidar_mount_);
    tap_->on_lidar(pending_delivery_us_, sweep,
                   tap_->kinds().lidar_labels ? &scan.labels.cone_id : nullptr);
  }
  // a plug-in with the camera too sees the sweep now, between its stereo frames
  if (perception_ && perception_->is_plugin() && perception_->uses_lidar() &&
      perception_->uses_camera()) {
    const auto t0 = clock::now();
    try {
      result.plugin_frame = perception_->plugin_lidar(scan.cloud, result.end_us, result.motion);
    } catch (const PluginFailure& e) {
      result.plugin_failure = e.what();
    }
    result.detect_ms = ms_between(t0, clock::now());
  }
  // a plug-in's cones likewise, scored on what it delivers; its failure ends the run
  if (!result.plugin_failure.empty() && failure_.empty()) failure_ = result.plugin_failure;
  if (result.plugin_frame && referee_) {
    stats_.lidar_detect_ms_total += result.detect_ms;
    const Referee& referee = *referee_;
    auto d = perception_->on_plugin_frame(
        *result.plugin_frame,
        poses_.at(result.plugin_frame->stamp >= 0 ? result.plugin_frame->stamp : poses_.newest())
            .planar(),
        [&referee](int id) { return referee.is_knocked(id); });
    if (d) enqueue(pending_delivery_us_, std::move(*d), 0);
  }
  // the sweep's cones go to SLAM once the perception latency has passed
  if (result.detections && referee_) {
    stats_.lidar_detect_ms_total += result.detect_ms;
    const Referee& referee = *referee_;
    DeliveredDetections d = perception_->on_lidar(
        scan, *result.detections, result.motion, poses_.at(result.detections->stamp).planar(),
        [&referee](int id) { return referee.is_knocked(id); });
    enqueue(pending_delivery_us_, std::move(d), 0);
  }
  if (dump_.sensors.count("lidar") && index % dump_.every == 0)
    dump_sweep(index, scan, result.detections);
}

void SensorRig::dump_sweep(int index, const sensors::LidarScan& scan,
                           const std::optional<slam::frontend::LidarDetections>& detections) {
  // the dump: PCD, sidecar and a top-down picture
  const fs::path dir = run_dir_ / "images/lidar";
  write_pcd(dir / frame_name(index, "pcd"), scan.cloud, scan.labels);
  const nlohmann::json sidecar = {
      {"stamp_us", scan.cloud.stamp},
      {"sweep_period_us", lidar_->config().sweep_period_us()},
      {"model", lidar_->config().model},
      {"points", scan.cloud.points.size()},
      {"sensor_in_vehicle", pose3_json(lidar_->config().mount)},
      {"sensor_in_track_at_start", pose3_json(scan.labels.sensor_pose_start)},
      {"sensor_in_track_at_end", pose3_json(scan.labels.sensor_pose_end)},
      {"true_sensor_pose_at_start", pose2_json(scan.labels.sensor_pose_start.planar())}};
  nlohmann::json with_detections = sidecar;
  // the PCD labels are the track's cone numbers: the id the track file gave each one beside
  std::set<int> labels(scan.labels.cone_id.begin(), scan.labels.cone_id.end());
  nlohmann::json cone_ids = nlohmann::json::object();
  for (int label : labels)
    if (label >= 0) cone_ids[std::to_string(label)] = track_.file_id(label);
  with_detections["label_cone_ids"] = cone_ids;
  // the detector's cones, in the sensor frame at the sweep's end
  PlotData found{"detections", {}};
  if (detections) {
    nlohmann::json cones = nlohmann::json::array();
    for (const auto& c : detections->cones) {
      cones.push_back({{"x_sensor", c.centre_sensor.x()},
                       {"y_sensor", c.centre_sensor.y()},
                       {"x_vehicle", c.observation.position.x()},
                       {"y_vehicle", c.observation.position.y()},
                       {"class", std::string(core::to_string(c.observation.cls))},
                       {"points", c.points},
                       {"height_m", c.height_m}});
      found.rows.push_back({c.centre_sensor.x(), c.centre_sensor.y(),
                            static_cast<double>(static_cast<int>(c.observation.cls))});
    }
    with_detections["detections"] = cones;
    with_detections["detections_stamp_us"] = detections->stamp;
  }
  write_text(dir / frame_name(index, "json"), json_text(with_detections, 2) + "\n");
  if (dump_.lidar_png) {
    PlotData cones{"cones", {}}, ground{"ground", {}};
    for (size_t i = 0; i < scan.cloud.points.size(); ++i) {
      const auto& p = scan.cloud.points[i];
      if (std::hypot(p.x, p.y) > 30.0) continue;
      (scan.labels.cone_id[i] >= 0 ? cones : ground).rows.push_back({p.x, p.y, p.intensity});
    }
    const std::string script =
        "set title 'LiDAR sweep " + std::to_string(index) +
        " (sensor frame, within 30 m; colour = intensity)'\n"
        "set size ratio -1\nset xrange [-30:30]\nset yrange [-30:30]\nset grid\n"
        "set palette defined (0 '#101060', 60 '#3060ff', 130 '#ffd000', 255 '#ffffff')\n"
        "set cbrange [0:255]\nset xlabel 'x [m]'\nset ylabel 'y [m]'\n"
        "plot $ground using 1:2 with dots lc rgb '#b0b0b0' title 'ground', "
        "$cones using 1:2:3 with points pt 7 ps 0.4 palette title 'cone returns'" +
        std::string(found.rows.empty()
                        ? ""
                        : ", $detections using 1:2 with points pt 6 ps 2.2 lw 2 lc rgb "
                          "'#e00000' title 'detected cones'") +
        "\n";
    if (cones.rows.empty()) cones.rows.push_back({0.0, 0.0, 0.0});
    if (ground.rows.empty()) ground.rows.push_back({0.0, 0.0, 0.0});
    std::vector<PlotData> data{ground, cones};
    if (!found.rows.empty()) data.push_back(found);
    render_png(script, data, dir / frame_name(index, "png"), 900, 900);
  }
}

void SensorRig::render_camera(TimeUs t, const VehicleSim& car, const Referee& referee) {
  using clock = std::chrono::steady_clock;
  const auto start = clock::now();
  camera_->render(
      car.data(), car.vehicle_pose3(), t, [&referee](int id) { return referee.is_knocked(id); },
      with_depth_, frame_, frame_labels_);
  stats_.camera_ms_total += std::chrono::duration<double, std::milli>(clock::now() - start).count();
  const int index = stats_.camera_frames++;
  if (!faults_.empty()) apply_camera_faults(t);
  // the tap gets the pair as the perception does (after the camera's faults)
  if (tap_ && tap_->kinds().camera) tap_->on_stereo(t + camera_latency_us_, to_sdk(frame_));

  // the stereo cone detector on the pair; its cones reach SLAM after the latency
  std::optional<slam::frontend::StereoDetections> detections;
  if (perception_ && perception_->is_plugin() && perception_->uses_camera()) {
    // a perception plug-in: its cones of the pair reach SLAM after the camera latency, unless
    // it also takes the LiDAR (then its sweeps deliver, and it fuses the pairs itself)
    const auto t0 = clock::now();
    try {
      core::ConeObservations cones = perception_->plugin_stereo(frame_);
      stats_.stereo_detect_ms_total +=
          std::chrono::duration<double, std::milli>(clock::now() - t0).count();
      if (!perception_->uses_lidar()) {
        auto d = perception_->on_plugin_frame(
            std::move(cones), car.truth().pose,
            [&referee](int id) { return referee.is_knocked(id); }, &frame_);
        if (d) enqueue(t + camera_latency_us_, std::move(*d), 1);
      }
    } catch (const PluginFailure& e) {
      if (failure_.empty()) failure_ = e.what();
    }
  } else if (perception_ && perception_->uses_camera()) {
    const auto t0 = clock::now();
    detections = perception_->stereo_detector()->detect(frame_);
    stats_.stereo_detect_ms_total +=
        std::chrono::duration<double, std::milli>(clock::now() - t0).count();
    detections->stamp = t;
    auto d = perception_->on_stereo(frame_, *detections, car.truth().pose,
                                    [&referee](int id) { return referee.is_knocked(id); });
    if (d) enqueue(t + camera_latency_us_, std::move(*d), 1);
  }

  // the dump: left and right PNG and a sidecar with the calibration and the true poses
  if (!dump_.sensors.count("camera") || index % dump_.every != 0) return;
  const fs::path dir = run_dir_ / "images/camera";
  // the detections drawn on the left image, boxes in their class colour
  core::RgbImage left = frame_.left;
  if (detections) draw_boxes(*detections, left);
  for (const auto& [side, image] : {std::pair{"left", &left}, {"right", &frame_.right}}) {
    const std::string error =
        sensors::write_png((dir / side / frame_name(index, "png")).string(), *image);
    if (!error.empty()) throw std::runtime_error(error);
  }
  const auto& k = frame_.intrinsics;
  const nlohmann::json sidecar = {{"stamp_us", t},
                                  {"intrinsics",
                                   {{"width_px", k.width_px},
                                    {"height_px", k.height_px},
                                    {"fx", k.fx},
                                    {"fy", k.fy},
                                    {"cx", k.cx},
                                    {"cy", k.cy}}},
                                  {"baseline_m", frame_.baseline_m},
                                  {"left_in_vehicle", pose3_json(frame_.left_in_vehicle)},
                                  {"right_in_vehicle", pose3_json(frame_.right_in_vehicle)},
                                  {"left_in_track", pose3_json(frame_labels_.left_in_track)},
                                  {"right_in_track", pose3_json(frame_labels_.right_in_track)},
                                  {"true_vehicle_pose", pose2_json(car.truth().pose)},
                                  {"camera_frame", "x right, y down, z forward (OpenCV)"}};
  nlohmann::json with_detections = sidecar;
  if (detections) {
    nlohmann::json cones = nlohmann::json::array();
    for (const auto& c : detections->cones)
      cones.push_back({{"box_xywh", {c.box.x, c.box.y, c.box.width, c.box.height}},
                       {"class", std::string(core::to_string(c.observation.cls))},
                       {"x_vehicle", c.observation.position.x()},
                       {"y_vehicle", c.observation.position.y()},
                       {"disparity_px", c.disparity_px},
                       {"depth_m", c.depth_m}});
    with_detections["detections"] = cones;
  }
  write_text(dir / frame_name(index, "json"), json_text(with_detections, 2) + "\n");
}

void SensorRig::sense_cones(TimeUs t, const VehicleSim& car, const Referee& referee) {
  const core::Pose2 pose = car.truth().pose;
  auto [obs, labels] =
      cone_sensor_->sample(track_, pose, t, [&referee](int id) { return referee.is_knocked(id); });
  const int index = stats_.cone_frames++;
  if (dump_.sensors.count("detections") && index % dump_.every == 0) {
    nlohmann::json cones = nlohmann::json::array();
    for (size_t i = 0; i < obs.cones.size(); ++i) {
      const auto& o = obs.cones[i];
      cones.push_back({{"x", o.position.x()},
                       {"y", o.position.y()},
                       {"class", std::string(core::to_string(o.cls))},
                       {"covariance", {o.covariance(0, 0), o.covariance(0, 1), o.covariance(1, 1)}},
                       {"true_cone_id", labels.cone_id[i] < 0
                                            ? nlohmann::json(labels.cone_id[i])
                                            : nlohmann::json(track_.file_id(labels.cone_id[i]))}});
    }
    const nlohmann::json frame = {{"stamp_us", t},
                                  {"delivered_us", t + cone_latency_us_},
                                  {"true_vehicle_pose", pose2_json(pose)},
                                  {"frame", "vehicle (rear axle centre), x forward, y left"},
                                  {"cones", cones}};
    write_text(run_dir_ / "images/detections" / frame_name(index, "json"), json_text(frame, 1) + "\n");
  }
  enqueue(t + cone_latency_us_, {std::move(obs), std::move(labels), pose}, 2);
}

void SensorRig::enqueue(TimeUs due_us, DeliveredDetections frame, int source) {
  if (!jitter_) {
    cone_queue_.push_back({due_us, std::move(frame)});
    return;
  }
  // late by the jitter; in delivery order (a frame that overtakes another goes before it)
  const TimeUs previous = cone_queue_.empty() ? 0 : cone_queue_.back().first;
  const TimeUs at =
      faults_.delivery_us(frame.observations.stamp, due_us, previous, source, fault_counts_);
  auto it = cone_queue_.end();
  while (it != cone_queue_.begin() && std::prev(it)->first > at) --it;
  cone_queue_.insert(it, {at, std::move(frame)});
}

void SensorRig::apply_camera_faults(TimeUs t) {
  // a black frame; a frozen one repeats the last frame before the freeze (black before any)
  if (faults_.camera_black(t, fault_counts_)) {
    std::fill(frame_.left.rgb.begin(), frame_.left.rgb.end(), uint8_t{0});
    std::fill(frame_.right.rgb.begin(), frame_.right.rgb.end(), uint8_t{0});
    std::fill(frame_.left_depth_m.begin(), frame_.left_depth_m.end(), 0.0f);
    return;
  }
  if (faults_.camera_frozen(t, fault_counts_)) {
    if (last_good_frame_) {
      frame_.left = last_good_frame_->left;
      frame_.right = last_good_frame_->right;
      frame_.left_depth_m = last_good_frame_->left_depth_m;
    } else {
      std::fill(frame_.left.rgb.begin(), frame_.left.rgb.end(), uint8_t{0});
      std::fill(frame_.right.rgb.begin(), frame_.right.rgb.end(), uint8_t{0});
    }
    return;
  }
  if (freezes_) last_good_frame_ = frame_;
}

std::optional<DeliveredDetections> SensorRig::take_detections(TimeUs t) {
  if (cone_queue_.empty() || cone_queue_.front().first > t) return std::nullopt;
  DeliveredDetections d = std::move(cone_queue_.front().second);
  cone_queue_.pop_front();
  if (cone_tracker_) {
    // track ids across frames, predicted with the autonomy's motion since the last frame
    const double dt_s =
        tracker_stamp_ ? core::to_seconds(d.observations.stamp - *tracker_stamp_) : 0.0;
    tracker_stamp_ = d.observations.stamp;
    const TimeUs stamp = d.observations.stamp;
    d.observations = cone_tracker_->update(d.observations, motion_over(motion_, dt_s));
    d.observations.stamp = stamp;
  }
  return d;
}

}  // namespace conesim::sim
