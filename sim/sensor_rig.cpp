#include "sim/sensor_rig.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <functional>
#include <set>
#include <sstream>
#include <stdexcept>

#include "core/clutter.hpp"
#include "core/cone.hpp"
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
constexpr uint64_t kCameraNoiseStream = 103;
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
  text += "# .PCD v0.7 - conesim LiDAR sweep (label: true cone id, -1 ground, -2 and below clutter)\n";
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

// a cone class as the review images name it, and its colour there
const char* class_name(core::ConeClass c) {
  switch (c) {
    case core::ConeClass::kBlue:
      return "blue";
    case core::ConeClass::kYellow:
      return "yellow";
    case core::ConeClass::kOrangeSmall:
      return "orange";
    case core::ConeClass::kOrangeBig:
      return "big orange";
    case core::ConeClass::kUnknown:
      break;
  }
  return "unknown";
}

int class_rgb(core::ConeClass c) {
  switch (c) {
    case core::ConeClass::kBlue:
      return 0x3c78ff;
    case core::ConeClass::kYellow:
      return 0xffe600;
    case core::ConeClass::kOrangeSmall:
      return 0xff8c00;
    case core::ConeClass::kOrangeBig:
      return 0xff3c00;
    case core::ConeClass::kUnknown:
      break;
  }
  return 0xffffff;
}

// A true cone's box in the left image: the bounding box of its base circle and apex projected
// through the pinhole, clipped to the image, and how much of it no nearer cone hides.
struct TrueBox {
  int id = -1;
  core::ConeClass cls = core::ConeClass::kUnknown;
  double range_m = 0.0;
  double depth_m = 0.0;
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  double visible = 1.0;
};

// A cone counts as seen when at least this much of its box is in the image and unhidden.
constexpr double kMinVisibleFraction = 0.3;

std::vector<TrueBox> true_boxes(const core::StereoFrame& frame, const core::Pose3& left_in_track,
                                const tracks::Track& track,
                                const std::function<bool(int)>& is_knocked) {
  const auto& k = frame.intrinsics;
  const Eigen::Quaterniond to_camera = left_in_track.orientation.conjugate();
  std::vector<TrueBox> boxes;
  for (const tracks::Cone& c : track.cones) {
    if (is_knocked(c.id)) continue;
    const core::ConeSize size = core::cone_size(c.cls);
    const Eigen::Vector3d base(c.position.x(), c.position.y(), 0.0);
    const Eigen::Vector3d centre = to_camera * (base - left_in_track.position);
    if (centre.z() < 0.5 || centre.norm() > 40.0) continue;
    TrueBox b{c.id, c.cls, (c.position - left_in_track.position.head<2>()).norm(), centre.z(),
              1e9, 1e9, -1e9, -1e9, 1.0};
    bool behind = false;
    for (int i = 0; i <= 8; ++i) {
      // eight points round the base, then the apex
      const double a = i * 2.0 * M_PI / 8.0;
      const Eigen::Vector3d offset =
          i == 8 ? Eigen::Vector3d(0, 0, size.height_m)
                 : Eigen::Vector3d(0.5 * size.base_m * std::cos(a), 0.5 * size.base_m * std::sin(a), 0.0);
      const Eigen::Vector3d p = base + offset;
      const Eigen::Vector3d q = to_camera * (p - left_in_track.position);
      if (q.z() <= 0.05) {
        behind = true;
        break;
      }
      // through the lens, as the image is drawn
      const Eigen::Vector2d uv = k.pixel_of({q.x() / q.z(), q.y() / q.z()});
      b.x0 = std::min(b.x0, uv.x()), b.x1 = std::max(b.x1, uv.x());
      b.y0 = std::min(b.y0, uv.y()), b.y1 = std::max(b.y1, uv.y());
    }
    if (behind || b.x1 < 0 || b.y1 < 0 || b.x0 >= k.width_px || b.y0 >= k.height_px) continue;
    boxes.push_back(b);
  }
  // occlusion, nearest first: the part of each box inside the image that no nearer box covers
  std::sort(boxes.begin(), boxes.end(),
            [](const TrueBox& a, const TrueBox& b) { return a.depth_m < b.depth_m; });
  std::vector<uint8_t> covered(static_cast<size_t>(k.width_px) * k.height_px, 0);
  for (TrueBox& b : boxes) {
    const int x0 = static_cast<int>(std::floor(b.x0)), x1 = static_cast<int>(std::ceil(b.x1));
    const int y0 = static_cast<int>(std::floor(b.y0)), y1 = static_cast<int>(std::ceil(b.y1));
    int64_t total = 0, seen = 0;
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        ++total;
        if (x < 0 || y < 0 || x >= k.width_px || y >= k.height_px) continue;
        uint8_t& cell = covered[static_cast<size_t>(y) * k.width_px + x];
        if (!cell) ++seen;
        cell = 1;
      }
    b.visible = total > 0 ? static_cast<double>(seen) / total : 0.0;
    b.x0 = std::max(0.0, b.x0), b.y0 = std::max(0.0, b.y0);
    b.x1 = std::min(k.width_px - 1.0, b.x1), b.y1 = std::min(k.height_px - 1.0, b.y1);
  }
  std::erase_if(boxes, [](const TrueBox& b) { return b.visible < kMinVisibleFraction; });
  return boxes;
}

// True boxes farther than this carry no label in the camera review image (their box is drawn).
constexpr double kLabelledTrueRangeM = 20.0;
// The camera review image is drawn at twice the camera's size, so that its labels can be read.
constexpr int kCameraReviewScale = 2;

// gnuplot's text in single quotes: a quote doubled
std::string quoted(const std::string& text) {
  std::string out = "'";
  for (char c : text) out += c == '\'' ? std::string("''") : std::string(1, c);
  return out + "'";
}

// The camera review image: the raw left image, the detected boxes in their class colour
// (solid) labelled with class, track id and range above, the true boxes (dashed magenta)
// labelled with class and range below, and a legend.
// A box of the pinhole view (the stereo detector undistorts the images before it looks) where
// the image, drawn through the lens, shows it: the bounding box of points along its edges.
std::array<double, 4> box_in_image(const core::CameraIntrinsics& k, double x0, double y0,
                                   double x1, double y1) {
  if (!k.distorted()) return {x0, y0, x1, y1};
  std::array<double, 4> out = {1e18, 1e18, -1e18, -1e18};
  for (int i = 0; i <= 8; ++i)
    for (int side = 0; side < 4; ++side) {
      const double t = i / 8.0;
      const double u = side == 0 ? x0 : side == 1 ? x1 : x0 + t * (x1 - x0);
      const double v = side == 2 ? y0 : side == 3 ? y1 : y0 + t * (y1 - y0);
      const Eigen::Vector2d p = k.pixel_of({(u - k.cx) / k.fx, (v - k.cy) / k.fy});
      out = {std::min(out[0], p.x()), std::min(out[1], p.y()), std::max(out[2], p.x()),
             std::max(out[3], p.y())};
    }
  return out;
}

void render_camera_review(const fs::path& raw_png, const fs::path& out_png,
                          const core::CameraIntrinsics& k, const std::vector<TrueBox>& truth,
                          const slam::frontend::StereoDetections* detections,
                          const std::vector<int>& track_ids, const core::Vec2& camera_xy) {
  const int width = k.width_px, height = k.height_px;
  // a box as four edges (x, y, dx, dy, colour) in gnuplot's axes: y up from the bottom
  auto edges = [height](PlotData& d, double x0, double y0, double x1, double y1, int rgb) {
    const double top = height - y0, bottom = height - y1;
    d.rows.push_back({x0, top, x1 - x0, 0.0, double(rgb)});
    d.rows.push_back({x0, bottom, x1 - x0, 0.0, double(rgb)});
    d.rows.push_back({x0, bottom, 0.0, top - bottom, double(rgb)});
    d.rows.push_back({x1, bottom, 0.0, top - bottom, double(rgb)});
  };
  PlotData true_edges{"truth", {}}, found_edges{"detected", {}};
  std::ostringstream labels;
  char text[96];
  for (const TrueBox& b : truth) {
    edges(true_edges, b.x0, b.y0, b.x1, b.y1, 0xff40ff);
    // far boxes are small and crowd each other: only the near ones are labelled
    if (b.range_m > kLabelledTrueRangeM) continue;
    std::snprintf(text, sizeof(text), "true %s %.1f m", class_name(b.cls), b.range_m);
    labels << "set label " << quoted(text) << " at " << b.x0 << "," << height - b.y1 - 2
           << " left offset 0,-0.6 font ',8' tc rgb '#ff40ff' front noenhanced\n";
  }
  if (detections)
    for (size_t i = 0; i < detections->cones.size(); ++i) {
      const auto& c = detections->cones[i];
      const int rgb = class_rgb(c.observation.cls);
      const auto [x0, y0, x1, y1] =
          box_in_image(k, c.box.x, c.box.y, c.box.x + c.box.width, c.box.y + c.box.height);
      edges(found_edges, x0, y0, x1, y1, rgb);
      const int id = i < track_ids.size() ? track_ids[i] : -1;
      const double range = (c.observation.position - camera_xy).norm();
      if (id >= 0)
        std::snprintf(text, sizeof(text), "%s #%d %.1f m", class_name(c.observation.cls), id,
                      range);
      else
        std::snprintf(text, sizeof(text), "%s %.1f m", class_name(c.observation.cls), range);
      char colour[16];
      std::snprintf(colour, sizeof(colour), "#%06x", rgb);
      labels << "set label " << quoted(text) << " at " << x0 << "," << height - y0 + 2
             << " left offset 0,0.6 font ',9' tc rgb '" << colour << "' front noenhanced\n";
    }
  std::ostringstream script;
  script << "set margins 0,0,0,0\nunset border\nunset tics\nset xrange [0:" << width
         << "]\nset yrange [0:" << height << "]\n"
         << "set key top right opaque box tc rgb '#000000' font ',9' samplen 3\n"
         << labels.str() << "plot " << quoted(raw_png.string())
         << " binary filetype=png with rgbimage notitle, "
            "$detected using 1:2:3:4:5 with vectors nohead lw 2 lc rgb variable "
            "title 'detected: class #track-id range (solid, class colour)', "
            "$truth using 1:2:3:4 with vectors nohead lw 1.5 dt 2 lc rgb '#ff40ff' "
            "title 'true: projected from the track, hidden by nearer cones left out (dashed magenta)'\n";
  for (PlotData* d : {&true_edges, &found_edges})
    if (d->rows.empty()) d->rows.push_back({-1e6, -1e6, 0.0, 0.0, 0.0});
  render_png(script.str(), {found_edges, true_edges}, out_png, kCameraReviewScale * width,
             kCameraReviewScale * height);
}

// the LiDAR review image: a square plot of +-30 m at a fixed place in the picture (so a pixel
// can be found from a position: the sidecar gives the box), the legend to its right
constexpr double kReviewRangeM = 30.0;
constexpr std::array<int, 2> kReviewImagePx{1140, 800};
constexpr std::array<int, 4> kReviewPlotPx{60, 40, 780, 760};

std::string lidar_review_script(int index, bool with_detections, bool with_clutter) {
  auto screen_x = [](int px) { return std::to_string(px / double(kReviewImagePx[0])); };
  auto screen_y = [](int px) { return std::to_string(1.0 - px / double(kReviewImagePx[1])); };
  const std::string range = std::to_string(kReviewRangeM);
  std::string s = "set title 'LiDAR sweep " + std::to_string(index) +
                  ": sensor frame, x forward, y left [m]'\n"
                  "set lmargin at screen " + screen_x(kReviewPlotPx[0]) +
                  "\nset rmargin at screen " + screen_x(kReviewPlotPx[2]) +
                  "\nset tmargin at screen " + screen_y(kReviewPlotPx[1]) +
                  "\nset bmargin at screen " + screen_y(kReviewPlotPx[3]) + "\n" +
                  "set xrange [-" + range + ":" + range + "]\nset yrange [-" + range + ":" +
                  range + "]\nset grid\nset key at screen " + screen_x(kReviewPlotPx[2] + 16) +
                  ", screen " + screen_y(kReviewPlotPx[1]) + " left top Left reverse box\n";
  if (!with_detections) s += "set label 1 'no detector ran on this sweep' at graph 0.02, graph 0.97\n";
  s += "plot $ground using 1:2 with points pt 7 ps 0.12 lc rgb '#c8c8c8' title 'ground returns', "
       "$returns using 1:2 with points pt 7 ps 0.2 lc rgb '#404040' title 'cone returns', ";
  if (with_clutter)
    s += "$clutter using 1:2 with points pt 7 ps 0.2 lc rgb '#8b4513' title 'clutter returns', ";
  s += "$blue using 1:2 with points pt 7 ps 1.3 lc rgb '#1f4fff' title 'blue cone (true)', "
       "$yellow using 1:2 with points pt 7 ps 1.3 lc rgb '#e8c000' title 'yellow cone (true)', "
       "$orange using 1:2 with points pt 7 ps 1.3 lc rgb '#ff8c00' title 'orange cone (true)', "
       "$big_orange using 1:2 with points pt 7 ps 2.0 lc rgb '#b04000' "
       "title 'big orange cone (true)'";
  if (with_detections)
    s += ", $found using 1:2 with points pt 6 ps 2.6 lw 2 lc rgb '#00b000' "
         "title 'detection: found'"
         ", $missed using 1:2 with points pt 2 ps 3.0 lw 3 lc rgb '#ff0000' "
         "title 'missed (>= 3 returns, not detected)'"
         ", $false_positive using 1:2 with points pt 4 ps 2.6 lw 2 lc rgb '#e000e0' "
         "title 'detection: false positive'";
  return s + "\n";
}

// the data blocks in the order the script plots them; an empty block gets one row far outside
// the plot so that its legend entry still shows
std::vector<PlotData> lidar_review_data(const PlotData& ground, const PlotData& returns,
                                        const std::array<PlotData, 4>& by_class,
                                        const PlotData& found, const PlotData& missed,
                                        const PlotData& false_positive,
                                        const PlotData& clutter) {
  std::vector<PlotData> data{ground, returns};
  if (!clutter.rows.empty()) data.push_back(clutter);
  data.insert(data.end(), by_class.begin(), by_class.end());
  data.insert(data.end(), {found, missed, false_positive});
  for (PlotData& d : data)
    if (d.rows.empty()) d.rows.push_back({1e6, 1e6});
  return data;
}

}  // namespace

// A part of a LiDAR sweep (a run of columns), cast on whichever thread claims it first: the
// worker as the parts are queued, or the loop when it needs the sweep before the worker has come
// to the part. Its noise comes from the sweep's seed and the part's index alone, so the points
// are the same whichever thread casts it.
struct SensorRig::SweepPart {
  // the sweep's start and noise seed, the part's index in it and its columns [begin, end)
  TimeUs start = 0;
  uint64_t sweep_seed = 0;
  int index = 0, begin = 0, end = 0;
  sensors::PoseHistory window;
  std::atomic<bool> claimed{false};
  std::atomic<bool> done{false};
  sensors::LidarScan scan;
  double cast_ms = 0.0;
  std::exception_ptr error;

  // casts the part unless another thread has claimed it
  void cast(const sensors::Lidar& lidar) {
    if (claimed.exchange(true)) return;
    const auto t0 = clock::now();
    try {
      core::Rng rng(core::derive_seed(sweep_seed, static_cast<uint64_t>(index)));
      sensors::LidarNoise noise(rng);
      lidar.sweep_columns(start, begin, end, window, noise, scan);
    } catch (...) {
      error = std::current_exception();
    }
    cast_ms = ms_between(t0, clock::now());
    done.store(true);
    done.notify_all();
  }

  // waits until the part is cast (by whichever thread), rethrowing its error
  void wait() const {
    done.wait(false);
    if (error) std::rethrow_exception(error);
  }
};

// A LiDAR sweep being cast a part at a time as its columns fire (the loop's alone; the parts are
// shared with the threads that cast them).
struct SensorRig::SweepInProgress {
  explicit SweepInProgress(uint64_t seed_) : seed(seed_) {}
  // the noise's seed (part k draws from derive_seed(seed, k))
  uint64_t seed;
  std::vector<std::shared_ptr<SweepPart>> parts;
};

sensors::LidarScan SensorRig::join_parts(const std::vector<std::shared_ptr<SweepPart>>& parts,
                                         double& cast_ms) {
  for (const auto& part : parts) part->wait();
  sensors::LidarScan scan = std::move(parts.front()->scan);  // (room for the whole sweep)
  cast_ms = parts.front()->cast_ms;
  for (size_t k = 1; k < parts.size(); ++k) {
    const sensors::LidarScan& piece = parts[k]->scan;
    scan.cloud.points.insert(scan.cloud.points.end(), piece.cloud.points.begin(),
                             piece.cloud.points.end());
    scan.labels.cone_id.insert(scan.labels.cone_id.end(), piece.labels.cone_id.begin(),
                               piece.labels.cone_id.end());
    scan.labels.sensor_pose_end = piece.labels.sensor_pose_end;
    scan.stats += piece.stats;
    cast_ms += parts[k]->cast_ms;
  }
  return scan;
}

SensorRig::SensorRig(const Scenario& s, const tracks::Track& track, const VehicleSim& car,
                     const DumpOptions& dump, const fs::path& run_dir, SensorTap* tap,
                     LabelledDataSink* labelled)
    : track_(track),
      dump_(dump),
      run_dir_(run_dir),
      tap_(tap),
      labelled_(labelled),
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

  // the scenery the LiDAR and the camera see (nothing at density 0), from its own stream
  scenery_ = tracks::place_scenery(track, s.clutter, s.seed);
  tracks::lay_on_ground(scenery_, car.ground());

  // raw-data perception switches on the sensors it needs
  const bool raw_lidar = s.perception == "lidar" || s.perception == "fused";
  const bool raw_camera = s.perception == "stereo" || s.perception == "fused";
  const bool tap_lidar = (tap_ && tap_->kinds().lidar) || (labelled_ && labelled_->wants_lidar());
  const bool tap_camera = (tap_ && tap_->kinds().camera) || labelled_;

  // the LiDAR sweeps from the first step on
  if (s.sensors.lidar_enabled || raw_lidar || tap_lidar || dump_.sensors.count("lidar")) {
    const sensors::LidarConfig config = s.sensors.lidar_config();
    lidar_mount_ = config.mount;
    lidar_ = std::make_unique<sensors::Lidar>(config, track, scenery_, car.ground());
    poses_ = sensors::PoseHistory(2 * config.sweep_period_us());
    poses_.push(0, car.vehicle_pose3());
    lidar_latency_us_ = core::from_seconds(s.sensors.lidar_latency_s);
    casting_ = std::make_shared<SweepInProgress>(lidar_rng_());
    worker_ = std::make_unique<WorkerThread>();
  }

  // the stereo camera
  if (s.sensors.camera_enabled || raw_camera || tap_camera || dump_.sensors.count("camera")) {
    if (const std::string e = s.sensors.camera.validate(); !e.empty())
      throw std::invalid_argument("sensors.camera." + e);
    sensors::StereoCameraConfig camera = s.sensors.camera;
    camera.noise_seed = core::derive_seed(s.seed, kCameraNoiseStream);
    camera_ = std::make_unique<sensors::StereoCamera>(camera, car.model(), track, scenery_,
                                                      car.ground());
    camera_period_us_ = core::from_seconds(1.0 / s.sensors.camera_rate_hz);
    with_depth_ = s.sensors.camera_depth;
    camera_latency_us_ = core::from_seconds(s.sensors.camera_latency_s);
  }
  if (raw_lidar || raw_camera || s.perception_plugin)
    perception_ = std::make_unique<PerceptionRunner>(
        s, track, lidar_ ? lidar_->config().mount : core::Pose3{});
  if (perception_) perception_->set_scenery(scenery_);

  // the dump folders
  for (const std::string& name : dump_.sensors) {
    if (name == "camera") {
      fs::create_directories(run_dir_ / "images/camera/left");
      fs::create_directories(run_dir_ / "images/camera/right");
      fs::create_directories(run_dir_ / "images/camera/review");
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
    post_part(columns_posted_, end);
    columns_posted_ = end;
  }
}

void SensorRig::post_part(int begin, int end) {
  auto part = std::make_shared<SweepPart>();
  part->start = sweep_start_;
  part->sweep_seed = casting_->seed;
  part->index = static_cast<int>(casting_->parts.size());
  part->begin = begin;
  part->end = end;
  part->window = pose_window(lidar_->column_time(sweep_start_, begin),
                             lidar_->column_time(sweep_start_, end - 1));
  casting_->parts.push_back(part);
  worker_->post([this, part] { part->cast(*lidar_); });
}

void SensorRig::end_sweep() {
  // one sweep at a time: the previous one is collected first
  if (pending_scan_.valid()) collect_sweep();
  const TimeUs start = sweep_start_;
  const TimeUs end = lidar_->sweep_end(start);
  const int columns = lidar_->config().columns;
  pending_delivery_us_ = end + lidar_latency_us_;
  // the last part, then the sweep: cast on the worker unless the loop collects it first
  post_part(columns_posted_, columns);
  pending_parts_ = casting_->parts;
  // the last part, then the cone detector, with the motion the autonomy estimates now
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
  // the detector runs on whichever thread comes to it first: the worker once the sweep is cast,
  // or the loop when it collects the sweep before then (the worker then goes on to the next
  // sweep's parts); the detections are the same either way
  pending_detect_claim_ = std::make_shared<std::atomic<bool>>(false);
  pending_scan_ = worker_->post([this, sweep = casting_, detector, plugin, motion, end, index,
                                 claim = pending_detect_claim_] {
    SweepResult r;
    r.scan = join_parts(sweep->parts, r.cast_ms);
    r.end_us = end;
    r.motion = motion;
    r.fault_counts = faults_.zero_counts();
    // the faults: a lost sweep never reaches perception; dropout and blind sectors take
    // points before the detector sees them
    if (!faults_.empty()) {
      r.lost = faults_.lidar_sweep_lost(index, end, r.fault_counts);
      if (r.lost) return r;
      faults_.apply_lidar(r.scan.cloud, r.scan.labels, r.fault_counts);
    }
    if (detector && !claim->exchange(true)) r.detect_with(*detector);
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
  casting_ = std::make_shared<SweepInProgress>(lidar_rng_());
  columns_posted_ = 0;
}

void SensorRig::restart_sweep() {
  // the worker is idle: the sweep being cast is dropped and its noise drawn again (the same
  // seed); a part that failed says so
  for (const auto& part : casting_->parts) part->wait();
  casting_ = std::make_shared<SweepInProgress>(casting_->seed);
  columns_posted_ = 0;
}

void SensorRig::SweepResult::detect_with(const slam::frontend::LidarConeDetector& detector) {
  const auto t0 = clock::now();
  detections = detector.detect(scan.cloud, motion, end_us);
  detect_ms = ms_between(t0, clock::now());
}

void SensorRig::collect_sweep() {
  // the parts the worker has not come to are cast here (the loop would wait for them anyway)
  for (const auto& part : pending_parts_) part->cast(*lidar_);
  pending_parts_.clear();
  const bool detect_here = pending_detect_claim_ && !pending_detect_claim_->exchange(true);
  pending_detect_claim_.reset();
  SweepResult result = pending_scan_.get();
  const sensors::LidarScan& scan = result.scan;
  stats_.lidar_ms_total += result.cast_ms;
  const int index = stats_.lidar_scans++;
  stats_.lidar_points += static_cast<int64_t>(scan.cloud.points.size());
  stats_.lidar_returns_faded += scan.stats.faded;
  fault_counts_.add(result.fault_counts);
  if (result.lost) {
    ++stats_.lidar_sweeps_lost;
    return;
  }
  if (labelled_ && labelled_->wants_lidar()) labelled_->on_lidar(result.end_us, scan);
  const slam::frontend::LidarConeDetector* detector =
      perception_ ? perception_->lidar_detector() : nullptr;
  if (detect_here && detector) result.detect_with(*detector);

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
  // the detector's cones, in the sensor frame at the sweep's end, each judged against the true
  // cones (found, false positive) and the cones it missed
  std::optional<LidarSweepOutcome> outcome;
  if (detections) {
    outcome = judge_lidar_sweep(scan, *detections, track_, [this](int id) {
      return referee_ && referee_->is_knocked(id);
    });
    nlohmann::json cones = nlohmann::json::array();
    for (size_t i = 0; i < detections->cones.size(); ++i) {
      const auto& c = detections->cones[i];
      const int truth = outcome->detection_cone[i];
      cones.push_back({{"x_sensor", c.centre_sensor.x()},
                       {"y_sensor", c.centre_sensor.y()},
                       {"x_vehicle", c.observation.position.x()},
                       {"y_vehicle", c.observation.position.y()},
                       {"class", std::string(core::to_string(c.observation.cls))},
                       {"points", c.points},
                       {"height_m", c.height_m},
                       {"true_cone_id", truth < 0 ? nlohmann::json(-1)
                                                  : nlohmann::json(track_.file_id(truth))}});
    }
    with_detections["detections"] = cones;
    with_detections["detections_stamp_us"] = detections->stamp;
  }
  // the true cones near the sensor, in the sensor frame, and which were missed
  const core::Pose2 sensor = scan.labels.sensor_pose_end.planar();
  const std::set<int> missed =
      outcome ? std::set<int>(outcome->missed.begin(), outcome->missed.end()) : std::set<int>{};
  nlohmann::json missed_json = nlohmann::json::array();
  std::array<PlotData, 4> by_class{PlotData{"blue", {}}, PlotData{"yellow", {}},
                                   PlotData{"orange", {}}, PlotData{"big_orange", {}}};
  PlotData missed_xy{"missed", {}};
  for (const tracks::Cone& c : track_.cones) {
    if (referee_ && referee_->is_knocked(c.id)) continue;
    const core::Vec2 p = sensor.inverse_transform(c.position);
    if (std::abs(p.x()) > kReviewRangeM || std::abs(p.y()) > kReviewRangeM) continue;
    const auto k = static_cast<size_t>(c.cls);
    if (k < by_class.size()) by_class[k].rows.push_back({p.x(), p.y()});
    if (!missed.count(c.id)) continue;
    missed_xy.rows.push_back({p.x(), p.y()});
    missed_json.push_back(
        {{"true_cone_id", track_.file_id(c.id)}, {"x_sensor", p.x()}, {"y_sensor", p.y()}});
  }
  if (outcome) with_detections["missed"] = missed_json;
  with_detections["review_png"] = {
      {"plot_px_left_top_right_bottom",
       {kReviewPlotPx[0], kReviewPlotPx[1], kReviewPlotPx[2], kReviewPlotPx[3]}},
      {"range_m", kReviewRangeM},
      {"frame", "sensor frame at the sweep's end: x right in the image, y up"}};
  write_text(dir / frame_name(index, "json"), json_text(with_detections, 2) + "\n");
  if (dump_.review_png) {
    PlotData returns{"returns", {}}, ground{"ground", {}}, found{"found", {}},
        false_positive{"false_positive", {}}, clutter{"clutter", {}};
    for (size_t i = 0; i < scan.cloud.points.size(); ++i) {
      const auto& p = scan.cloud.points[i];
      if (std::abs(p.x) > kReviewRangeM || std::abs(p.y) > kReviewRangeM) continue;
      const int label = scan.labels.cone_id[i];
      (label >= 0 ? returns : core::clutter_of_label(label) ? clutter : ground)
          .rows.push_back({p.x, p.y});
    }
    if (detections)
      for (size_t i = 0; i < detections->cones.size(); ++i)
        (outcome->detection_cone[i] >= 0 ? found : false_positive)
            .rows.push_back({detections->cones[i].centre_sensor.x(),
                             detections->cones[i].centre_sensor.y()});
    render_png(lidar_review_script(index, detections.has_value(), !clutter.rows.empty()),
               lidar_review_data(ground, returns, by_class, found, missed_xy, false_positive,
                                 clutter),
               dir / frame_name(index, "png"), kReviewImagePx[0], kReviewImagePx[1]);
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
  // a recorder of labelled data gets the pair as rendered, with its segmentation
  if (labelled_ && labelled_->wants_camera(t)) {
    camera_->render_segmentation(segmentation_);
    labelled_->on_camera(t, frame_, frame_labels_, segmentation_);
  }
  if (!faults_.empty()) apply_camera_faults(t);
  // the tap gets the pair as the perception does (after the camera's faults)
  if (tap_ && tap_->kinds().camera) tap_->on_stereo(t + camera_latency_us_, to_sdk(frame_));

  // the stereo cone detector on the pair; its cones reach SLAM after the latency
  std::optional<slam::frontend::StereoDetections> detections;
  std::vector<int> track_ids;  // the tracker's id of each detection (stereo perception)
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
    if (d) {
      for (const core::ConeObservation& o : d->observations.cones) track_ids.push_back(o.track_id);
      enqueue(t + camera_latency_us_, std::move(*d), 1);
    }
  }

  // the replay's frame: the left image with the detected and the true boxes
  if (camera_observer_ && t >= next_camera_observed_us_) {
    next_camera_observed_us_ = t + std::max<TimeUs>(1, camera_observer_period_us_);
    CameraReplayFrame rec;
    rec.t = t;
    rec.left = &frame_.left;
    const core::Vec2 camera_xy = frame_.left_in_vehicle.position.head<2>();
    if (detections)
      for (size_t i = 0; i < detections->cones.size(); ++i) {
        const auto& c = detections->cones[i];
        rec.detected.push_back({static_cast<float>(c.box.x), static_cast<float>(c.box.y),
                                static_cast<float>(c.box.x + c.box.width),
                                static_cast<float>(c.box.y + c.box.height), c.observation.cls,
                                i < track_ids.size() ? track_ids[i] : -1,
                                static_cast<float>((c.observation.position - camera_xy).norm())});
      }
    for (const TrueBox& b : true_boxes(frame_, frame_labels_.left_in_track, track_,
                                       [&referee](int id) { return referee.is_knocked(id); }))
      rec.truth.push_back({static_cast<float>(b.x0), static_cast<float>(b.y0),
                           static_cast<float>(b.x1), static_cast<float>(b.y1), b.cls, b.id,
                           static_cast<float>(b.range_m)});
    camera_observer_(rec);
  }

  // the dump: left and right PNG and a sidecar with the calibration and the true poses
  if (!dump_.sensors.count("camera") || index % dump_.every != 0) return;
  const fs::path dir = run_dir_ / "images/camera";
  // the raw pair as rendered; the review image beside it draws the boxes on the left one
  for (const auto& [side, image] : {std::pair{"left", &frame_.left}, {"right", &frame_.right}}) {
    const std::string error =
        sensors::write_png((dir / side / frame_name(index, "png")).string(), *image);
    if (!error.empty()) throw std::runtime_error(error);
  }
  const std::vector<TrueBox> truth =
      true_boxes(frame_, frame_labels_.left_in_track, track_,
                 [&referee](int id) { return referee.is_knocked(id); });
  if (dump_.review_png)
    render_camera_review(dir / "left" / frame_name(index, "png"),
                         dir / "review" / frame_name(index, "png"), frame_.intrinsics, truth,
                         detections ? &*detections : nullptr,
                         track_ids, frame_.left_in_vehicle.position.head<2>());
  const auto& k = frame_.intrinsics;
  const nlohmann::json sidecar = {{"stamp_us", t},
                                  {"intrinsics",
                                   {{"width_px", k.width_px},
                                    {"height_px", k.height_px},
                                    {"fx", k.fx},
                                    {"fy", k.fy},
                                    {"cx", k.cx},
                                    {"cy", k.cy},
                                    {"distortion", k.distortion}}},
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
    for (const auto& c : detections->cones) {
      // the box in the image as written (the detector's own is in the undistorted view)
      const auto [x0, y0, x1, y1] =
          box_in_image(k, c.box.x, c.box.y, c.box.x + c.box.width, c.box.y + c.box.height);
      cones.push_back({{"box_xywh", {x0, y0, x1 - x0, y1 - y0}},
                       {"class", std::string(core::to_string(c.observation.cls))},
                       {"x_vehicle", c.observation.position.x()},
                       {"y_vehicle", c.observation.position.y()},
                       {"disparity_px", c.disparity_px},
                       {"depth_m", c.depth_m}});
    }
    with_detections["detections"] = cones;
  }
  nlohmann::json true_json = nlohmann::json::array();
  for (const TrueBox& b : truth)
    true_json.push_back({{"true_cone_id", track_.file_id(b.id)},
                         {"class", std::string(core::to_string(b.cls))},
                         {"box_x0y0x1y1", {b.x0, b.y0, b.x1, b.y1}},
                         {"range_m", b.range_m},
                         {"visible_fraction", b.visible}});
  with_detections["true_boxes"] = true_json;
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
