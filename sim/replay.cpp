#include "sim/replay.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

#include "core/error.hpp"
#include "sim/perception_runner.hpp"
#include "sim/sensor_rig.hpp"
#include "tracks/io.hpp"
#include "vehicle_models/vehicle_params.hpp"

namespace conesim::sim {

// the page's template (sim/replay_page.html, built into the binary by sim/CMakeLists.txt)
extern const char* const kReplayPageTemplate;

namespace fs = std::filesystem;
using core::TimeUs;

namespace {

// replay.bin: "CSRP", a uint32 version, then records: a uint8 type, a uint32 payload size and
// the payload, little-endian throughout (docs/replay.md). A new kind of record gets a new type
// and keeps the version: a reader skips the types it does not know, so older conesims still
// read a newer log (the version changes only when a known record's layout does)
constexpr char kMagic[4] = {'C', 'S', 'R', 'P'};
constexpr uint32_t kVersion = 1;
constexpr uint8_t kRecordSweep = 1;
constexpr uint8_t kRecordMap = 2;
constexpr uint8_t kRecordDetections = 3;
constexpr uint8_t kRecordCamera = 4;
// a camera record's box: float32 x0, y0, x1, y1, uint8 class, int32 id, float32 range
constexpr size_t kCameraBoxBytes = 25;

template <typename T>
void put(std::string& out, const T& v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof(T));
}
template <typename T>
void put_array(std::string& out, const std::vector<T>& v) {
  if (!v.empty()) out.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

// the class code of the log: 0 ground (or nothing), 1 + core::ConeClass
uint8_t class_code(core::ConeClass c) {
  return static_cast<uint8_t>(1 + static_cast<int>(c));
}

double lerp_angle(double a, double b, double s) {
  double d = std::remainder(b - a, 2.0 * M_PI);
  return a + s * d;
}

}  // namespace

ReplayRecorder::ReplayRecorder(const fs::path& run_dir, const tracks::Track& track,
                               double lidar_sweep_hz, const ReplayRecordSettings& settings)
    : SensorTap([&] {
        SensorTapKinds k;
        k.lidar = lidar_sweep_hz > 0.0 && settings.lidar_rate_hz > 0.0;
        k.lidar_labels = k.lidar;
        k.lidar_every =
            k.lidar ? std::max(
                          1, static_cast<int>(std::lround(lidar_sweep_hz / settings.lidar_rate_hz)))
                    : 1;
        return k;
      }()),
      file_(run_dir / kReplayLogFile),
      partial_(run_dir / (std::string(".partial-") + kReplayLogFile)),
      settings_(settings) {
  std::error_code ec;
  fs::remove(file_, ec);  // an earlier run's log would look like this run's
  out_.open(partial_, std::ios::binary);
  if (!out_) throw std::runtime_error(partial_.string() + ": cannot write");
  out_.write(kMagic, 4);
  out_.write(reinterpret_cast<const char*>(&kVersion), sizeof(kVersion));
  cone_class_.assign(static_cast<size_t>(track.next_id()), -1);
  for (const tracks::Cone& c : track.cones) cone_class_[c.id] = static_cast<int8_t>(c.cls);
}

ReplayRecorder::~ReplayRecorder() {
  if (done_) return;
  out_.close();
  std::error_code ec;
  fs::remove(partial_, ec);
}

void ReplayRecorder::on_pose(TimeUs t, const core::Pose2& pose) {
  poses_.emplace_back(t, pose);
  // a sweep reaches the tap a sweep and a latency after its first point: 2 s is plenty
  while (poses_.size() > 2 && poses_.front().first < t - 2'000'000) poses_.pop_front();
}

core::Pose2 ReplayRecorder::pose_at(TimeUs t) const {
  if (poses_.empty()) return {};
  if (t <= poses_.front().first) return poses_.front().second;
  if (t >= poses_.back().first) return poses_.back().second;
  const auto after = std::lower_bound(poses_.begin(), poses_.end(), t,
                                      [](const auto& p, TimeUs v) { return p.first < v; });
  const auto before = after - 1;
  const double s = static_cast<double>(t - before->first) /
                   static_cast<double>(std::max<TimeUs>(1, after->first - before->first));
  const core::Pose2& a = before->second;
  const core::Pose2& b = after->second;
  return {a.x + s * (b.x - a.x), a.y + s * (b.y - a.y), lerp_angle(a.yaw, b.yaw, s)};
}

void ReplayRecorder::write_record(uint8_t type, const std::string& payload) {
  const uint32_t size = static_cast<uint32_t>(payload.size());
  out_.put(static_cast<char>(type));
  out_.write(reinterpret_cast<const char*>(&size), sizeof(size));
  out_.write(payload.data(), static_cast<std::streamsize>(payload.size()));
}

void ReplayRecorder::on_lidar(TimeUs delivered_us, const sdk::LidarSweep& sweep,
                              const std::vector<int>* labels) {
  (void)delivered_us;
  const size_t n = sweep.points.size;
  if (n == 0) return;
  // the mount as a rotation and an offset (sensor frame -> vehicle frame)
  const sdk::Quaternion& q = sweep.sensor_in_vehicle.orientation;
  const Eigen::Quaterniond rot(q.w, q.x, q.y, q.z);
  const Eigen::Matrix3d r = rot.normalized().toRotationMatrix();
  const Eigen::Vector3d m(sweep.sensor_in_vehicle.position_m.x,
                          sweep.sensor_in_vehicle.position_m.y,
                          sweep.sensor_in_vehicle.position_m.z);
  const core::Pose2 centre = pose_at(sweep.end_us);
  const double range2 = settings_.lidar_range_m * settings_.lidar_range_m;

  // which points stay: every cone point in range, the ground thinned to fill the rest
  auto cone_of = [&](size_t i) -> int {
    if (!labels || i >= labels->size()) return -1;
    const int id = (*labels)[i];
    return id < 0 || id >= static_cast<int>(cone_class_.size()) || cone_class_[id] < 0 ? -1 : id;
  };
  auto label_of = [&](size_t i) -> uint8_t {
    const int id = cone_of(i);
    return id < 0 ? 0 : class_code(static_cast<core::ConeClass>(cone_class_[id]));
  };
  std::vector<uint32_t> cone_points, ground_points;
  for (size_t i = 0; i < n; ++i) {
    const sdk::LidarPoint& p = sweep.points.data[i];
    const double d2 = static_cast<double>(p.x_m) * p.x_m + static_cast<double>(p.y_m) * p.y_m;
    if (!(d2 <= range2)) continue;
    (label_of(i) ? cone_points : ground_points).push_back(static_cast<uint32_t>(i));
  }
  const size_t budget = static_cast<size_t>(std::max(0, settings_.max_points_per_sweep));
  if (cone_points.size() > budget) cone_points.resize(budget);
  std::vector<uint32_t> kept = cone_points;
  const size_t room = budget - kept.size();
  if (room > 0 && !ground_points.empty()) {
    const double stride = std::max(1.0, static_cast<double>(ground_points.size()) / room);
    for (double k = 0.0; k < ground_points.size() && kept.size() < budget; k += stride)
      kept.push_back(ground_points[static_cast<size_t>(k)]);
  }

  std::vector<int16_t> xyz;
  std::vector<uint8_t> intensity, label;
  std::vector<int16_t> cone;
  xyz.reserve(3 * kept.size());
  intensity.reserve(kept.size());
  label.reserve(kept.size());
  auto cm = [](double v) {
    return static_cast<int16_t>(std::clamp(std::lround(v * 100.0), -32767L, 32767L));
  };
  for (uint32_t i : kept) {
    const sdk::LidarPoint& p = sweep.points.data[i];
    const Eigen::Vector3d v = r * Eigen::Vector3d(p.x_m, p.y_m, p.z_m) + m;
    // where the car was when the point was fired
    const core::Pose2 at =
        pose_at(sweep.stamp_us + static_cast<TimeUs>(std::lround(p.time_offset_s * 1e6)));
    const core::Vec2 w = at.transform({v.x(), v.y()});
    xyz.push_back(cm(w.x() - centre.x));
    xyz.push_back(cm(w.y() - centre.y));
    xyz.push_back(cm(v.z()));
    intensity.push_back(static_cast<uint8_t>(std::clamp(p.intensity, 0.f, 255.f)));
    label.push_back(label_of(i));
    const int id = cone_of(i);
    cone.push_back(static_cast<int16_t>(id <= 32767 ? id : -1));
  }
  std::string payload;
  put(payload, core::to_seconds(sweep.end_us));
  put(payload, static_cast<float>(centre.x));
  put(payload, static_cast<float>(centre.y));
  put(payload, static_cast<uint32_t>(kept.size()));
  put_array(payload, xyz);
  put_array(payload, intensity);
  put_array(payload, label);
  put_array(payload, cone);
  write_record(kRecordSweep, payload);
  ++sweeps_;
}

void ReplayRecorder::on_detections(const DeliveredDetections& frame) {
  const auto& cones = frame.observations.cones;
  std::string payload;
  put(payload, core::to_seconds(frame.observations.stamp));
  put(payload, static_cast<uint32_t>(cones.size()));
  for (size_t i = 0; i < cones.size(); ++i)
    put(payload,
        static_cast<int32_t>(i < frame.labels.cone_id.size() ? frame.labels.cone_id[i] : -1));
  for (const core::ConeObservation& o : cones) {
    const core::Vec2 w = frame.capture_pose.transform(o.position);
    put(payload, static_cast<float>(w.x()));
    put(payload, static_cast<float>(w.y()));
  }
  write_record(kRecordDetections, payload);
}

void ReplayRecorder::on_camera(const CameraReplayFrame& frame) {
  const core::RgbImage* left = frame.left;
  if (!left || left->width_px <= 0 || left->height_px <= 0 ||
      left->rgb.size() < 3 * static_cast<size_t>(left->width_px) * left->height_px)
    return;
  const int width = std::clamp(settings_.camera_width_px, 16, left->width_px);
  const int height =
      std::max(1, static_cast<int>(std::lround(double(left->height_px) * width / left->width_px)));
  const cv::Mat rgb(left->height_px, left->width_px, CV_8UC3,
                    const_cast<uint8_t*>(left->rgb.data()));
  cv::Mat small, bgr;
  cv::resize(rgb, small, cv::Size(width, height), 0, 0, cv::INTER_AREA);
  cv::cvtColor(small, bgr, cv::COLOR_RGB2BGR);
  std::vector<uchar> jpeg;
  cv::imencode(".jpg", bgr, jpeg,
               {cv::IMWRITE_JPEG_QUALITY, std::clamp(settings_.camera_jpeg_quality, 1, 100)});
  const double sx = double(width) / left->width_px, sy = double(height) / left->height_px;
  std::string payload;
  put(payload, core::to_seconds(frame.t));
  put(payload, static_cast<uint16_t>(width));
  put(payload, static_cast<uint16_t>(height));
  put(payload, static_cast<uint32_t>(jpeg.size()));
  put_array(payload, jpeg);
  for (const std::vector<CameraBox>* boxes : {&frame.detected, &frame.truth}) {
    put(payload, static_cast<uint32_t>(boxes->size()));
    for (const CameraBox& b : *boxes) {
      put(payload, static_cast<float>(b.x0 * sx));
      put(payload, static_cast<float>(b.y0 * sy));
      put(payload, static_cast<float>(b.x1 * sx));
      put(payload, static_cast<float>(b.y1 * sy));
      put(payload, class_code(b.cls));
      put(payload, static_cast<int32_t>(b.id));
      put(payload, b.range_m);
    }
  }
  write_record(kRecordCamera, payload);
  ++camera_frames_;
}

void ReplayRecorder::write_map(const std::string& lane, double t_s,
                               const std::vector<core::MapCone>& map) {
  std::string payload;
  put(payload, t_s);
  put(payload, static_cast<uint8_t>(std::min<size_t>(lane.size(), 255)));
  payload.append(lane.substr(0, 255));
  put(payload, static_cast<uint32_t>(map.size()));
  for (const core::MapCone& c : map) {
    put(payload, static_cast<float>(c.position.x()));
    put(payload, static_cast<float>(c.position.y()));
  }
  for (const core::MapCone& c : map) put(payload, class_code(c.cls));
  write_record(kRecordMap, payload);
}

void ReplayRecorder::on_map(const std::string& lane, TimeUs stamp, const core::Estimate& estimate) {
  LaneMaps& l = lanes_[lane];
  const TimeUs period = core::from_seconds(1.0 / std::max(1e-3, settings_.map_rate_hz));
  if (l.last_written_us < 0 || stamp >= l.last_written_us + period) {
    write_map(lane, core::to_seconds(stamp), estimate.map);
    l.last_written_us = stamp;
    l.unwritten = false;
  } else {
    l.last = estimate.map;
    l.last_t_s = core::to_seconds(stamp);
    l.unwritten = true;
  }
}

void ReplayRecorder::finish() {
  for (auto& [lane, l] : lanes_)
    if (l.unwritten) write_map(lane, l.last_t_s, l.last);
  out_.close();
  if (!out_) throw std::runtime_error(partial_.string() + ": cannot write");
  fs::rename(partial_, file_);
  done_ = true;
}

// ---- reading the log back

ReplayLog read_replay_log(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw core::InputError(file.string(), 0, "cannot read");
  const std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  size_t at = 0;
  auto fail = [&](const std::string& why) -> void {
    throw core::InputError(file.string(), 0,
                           "not a replay log written by `conesim run --replay`: " + why +
                               " at byte " + std::to_string(at));
  };
  auto take = [&](void* dst, size_t bytes, size_t end) {
    if (bytes > end - at) fail("truncated record");
    if (bytes == 0) return;  // an empty list's data() may be null, which memcpy must not get
    std::memcpy(dst, data.data() + at, bytes);
    at += bytes;
  };
  if (data.size() < 8 || std::memcmp(data.data(), kMagic, 4) != 0) fail("no CSRP header");
  uint32_t version = 0;
  at = 4;
  take(&version, 4, data.size());
  if (version != kVersion)
    fail("version " + std::to_string(version) + " (this conesim reads " + std::to_string(kVersion) +
         ")");
  ReplayLog log;
  while (at < data.size()) {
    uint8_t type = 0;
    uint32_t size = 0;
    take(&type, 1, data.size());
    take(&size, 4, data.size());
    if (size > data.size() - at) fail("a record longer than the file");
    const size_t end = at + size;
    if (type == kRecordSweep) {
      ReplayLog::Sweep s;
      uint32_t n = 0;
      take(&s.t_s, 8, end);
      take(&s.origin_x, 4, end);
      take(&s.origin_y, 4, end);
      take(&n, 4, end);
      if (static_cast<uint64_t>(n) * 10 != end - at) fail("a sweep whose size does not match");
      s.xyz_cm.resize(3 * static_cast<size_t>(n));
      s.intensity.resize(n);
      s.label.resize(n);
      s.cone.resize(n);
      take(s.xyz_cm.data(), 6 * static_cast<size_t>(n), end);
      take(s.intensity.data(), n, end);
      take(s.label.data(), n, end);
      take(s.cone.data(), 2 * static_cast<size_t>(n), end);
      if (!std::isfinite(s.t_s)) fail("a sweep time that is not a number");
      log.sweeps.push_back(std::move(s));
    } else if (type == kRecordDetections) {
      ReplayLog::Detections d;
      uint32_t n = 0;
      take(&d.t_s, 8, end);
      take(&n, 4, end);
      if (static_cast<uint64_t>(n) * 12 != end - at) fail("detections whose size does not match");
      d.cone.resize(n);
      d.xy.resize(2 * static_cast<size_t>(n));
      take(d.cone.data(), 4 * static_cast<size_t>(n), end);
      take(d.xy.data(), 8 * static_cast<size_t>(n), end);
      if (!std::isfinite(d.t_s)) fail("a detection time that is not a number");
      log.detections.push_back(std::move(d));
    } else if (type == kRecordMap) {
      ReplayLog::MapSnapshot m;
      uint8_t name_size = 0;
      uint32_t n = 0;
      take(&m.t_s, 8, end);
      take(&name_size, 1, end);
      std::string lane(name_size, '\0');
      take(lane.data(), name_size, end);
      take(&n, 4, end);
      if (static_cast<uint64_t>(n) * 9 != end - at) fail("a map whose size does not match");
      m.xy.resize(2 * static_cast<size_t>(n));
      m.cls.resize(n);
      take(m.xy.data(), 8 * static_cast<size_t>(n), end);
      take(m.cls.data(), n, end);
      if (!std::isfinite(m.t_s)) fail("a map time that is not a number");
      auto it = std::find_if(log.maps.begin(), log.maps.end(),
                             [&](const auto& l) { return l.first == lane; });
      if (it == log.maps.end()) it = log.maps.insert(log.maps.end(), {lane, {}});
      it->second.push_back(std::move(m));
    } else if (type == kRecordCamera) {
      ReplayLog::CameraFrame c;
      uint16_t width = 0, height = 0;
      uint32_t bytes = 0;
      take(&c.t_s, 8, end);
      take(&width, 2, end);
      take(&height, 2, end);
      take(&bytes, 4, end);
      if (bytes > end - at) fail("a camera image longer than its record");
      c.width = width, c.height = height;
      c.jpeg.assign(data.data() + at, bytes);
      at += bytes;
      for (std::vector<ReplayLog::CameraFrame::Box>* boxes : {&c.detected, &c.truth}) {
        uint32_t n = 0;
        take(&n, 4, end);
        if (static_cast<uint64_t>(n) * kCameraBoxBytes > end - at)
          fail("camera boxes longer than their record");
        boxes->resize(n);
        for (ReplayLog::CameraFrame::Box& b : *boxes) {
          take(&b.x0, 4, end);
          take(&b.y0, 4, end);
          take(&b.x1, 4, end);
          take(&b.y1, 4, end);
          take(&b.cls, 1, end);
          take(&b.id, 4, end);
          take(&b.range_m, 4, end);
        }
      }
      if (at != end) fail("a camera frame whose size does not match");
      if (!std::isfinite(c.t_s) || width == 0 || height == 0 || bytes == 0)
        fail("a camera frame without a time or an image");
      log.camera.push_back(std::move(c));
    } else {
      at = end;  // a record of a later version: skipped
    }
    at = end;
  }
  for (auto& [lane, snaps] : log.maps)
    std::stable_sort(snaps.begin(), snaps.end(),
                     [](const auto& a, const auto& b) { return a.t_s < b.t_s; });
  std::stable_sort(log.sweeps.begin(), log.sweeps.end(),
                   [](const auto& a, const auto& b) { return a.t_s < b.t_s; });
  std::stable_sort(log.detections.begin(), log.detections.end(),
                   [](const auto& a, const auto& b) { return a.t_s < b.t_s; });
  std::stable_sort(log.camera.begin(), log.camera.end(),
                   [](const auto& a, const auto& b) { return a.t_s < b.t_s; });
  return log;
}

// ---- the page

namespace {

std::string base64(const void* data, size_t size) {
  static const char* digits = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  const auto* p = static_cast<const unsigned char*>(data);
  std::string out;
  out.reserve((size + 2) / 3 * 4);
  size_t i = 0;
  for (; i + 2 < size; i += 3) {
    const uint32_t v = (p[i] << 16) | (p[i + 1] << 8) | p[i + 2];
    out += digits[v >> 18];
    out += digits[(v >> 12) & 63];
    out += digits[(v >> 6) & 63];
    out += digits[v & 63];
  }
  if (i < size) {
    uint32_t v = p[i] << 16;
    if (i + 1 < size) v |= p[i + 1] << 8;
    out += digits[v >> 18];
    out += digits[(v >> 12) & 63];
    out += i + 1 < size ? digits[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

template <typename T>
std::string b64(const std::vector<T>& v) {
  return base64(v.data(), v.size() * sizeof(T));
}

std::string read_text(const fs::path& file, const std::string& what) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw core::InputError(file.string(), 0, "missing: " + what);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::vector<std::string> split(const std::string& line, char sep) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : line) {
    if (c == sep) {
      out.push_back(cur);
      cur.clear();
    } else if (c != '\r') {
      cur += c;
    }
  }
  out.push_back(cur);
  return out;
}

RunTrajectory read_trajectory(const fs::path& file, const std::vector<std::string>& shadows) {
  const std::string text =
      read_text(file,
                "the run's trajectory (t_s, x_m, y_m, yaw_rad, steer_rad, est_x_m, est_y_m, "
                "est_yaw_rad), which `conesim run` writes");
  std::istringstream in(text);
  std::string line;
  if (!std::getline(in, line))
    throw core::InputError(file.string(), 1, "empty: expected a header line (t_s,x_m,...)");
  const std::vector<std::string> header = split(line, ',');
  auto column = [&](const std::string& name) -> size_t {
    const auto it = std::find(header.begin(), header.end(), name);
    if (it == header.end())
      throw core::InputError(file.string(), 1, "no column " + name + " in the header");
    return static_cast<size_t>(it - header.begin());
  };
  std::vector<size_t> cols;
  for (const char* name :
       {"t_s", "x_m", "y_m", "yaw_rad", "steer_rad", "est_x_m", "est_y_m", "est_yaw_rad"})
    cols.push_back(column(name));
  RunTrajectory t;
  for (const std::string& lane : shadows) {
    if (std::find(header.begin(), header.end(), lane + "_x_m") == header.end()) continue;
    t.lanes.push_back(lane);
    for (const char* suffix : {"_x_m", "_y_m", "_yaw_rad"}) cols.push_back(column(lane + suffix));
  }
  t.width = cols.size();
  int line_no = 1;
  double last_t = -1e300;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line == "\r") continue;
    const std::vector<std::string> cells = split(line, ',');
    for (size_t c : cols) {
      if (c >= cells.size())
        throw core::InputError(file.string(), line_no,
                               "expected " + std::to_string(header.size()) + " columns, got " +
                                   std::to_string(cells.size()));
      char* end = nullptr;
      const double v = std::strtod(cells[c].c_str(), &end);
      if (cells[c].empty() || *end != '\0' || !std::isfinite(v))
        throw core::InputError(file.string(), line_no,
                               header[c] + ": expected a number, got '" + cells[c] + "'");
      if (c == cols[0]) {
        if (v < last_t) throw core::InputError(file.string(), line_no, "t_s goes back in time");
        last_t = v;
      }
      t.rows.push_back(static_cast<float>(v));
    }
    ++t.count;
  }
  if (t.count == 0) throw core::InputError(file.string(), 0, "no rows: the run drove nothing");
  return t;
}

}  // namespace

fs::path default_three_js_dir() {
  if (const char* env = std::getenv("CONESIM_THREE_JS_DIR"); env && *env) return env;
  return "/usr/share/javascript/three";
}

RunFolder read_run_folder(const fs::path& run_dir) {
  RunFolder run;
  std::error_code ec;
  if (!fs::is_directory(run_dir, ec))
    throw core::InputError(run_dir.string(), 0, "not a folder: expected a run folder");
  // metrics.json: the verdict and the referee's events
  const fs::path metrics_file = run_dir / "metrics.json";
  nlohmann::json& metrics = run.metrics;
  {
    const std::string text =
        read_text(metrics_file,
                  "the run's results with its referee events, which a finished `conesim "
                  "run` writes (a run without one did not finish)");
    try {
      metrics = nlohmann::json::parse(text);
    } catch (const nlohmann::json::parse_error& e) {
      throw core::InputError(metrics_file.string(), 0, std::string("not JSON: ") + e.what());
    }
    if (!metrics.is_object() || !metrics.contains("events") || !metrics["events"].is_array())
      throw core::InputError(metrics_file.string(), "events",
                             "expected an array of referee events (a run's metrics.json)");
    for (const auto& e : metrics["events"])
      if (!e.is_object() || !e.contains("t_s") || !e["t_s"].is_number() || !e.contains("kind") ||
          !e["kind"].is_string())
        throw core::InputError(metrics_file.string(), "events",
                               "expected each event to have a kind and a time t_s");
  }
  std::vector<std::string> shadows;
  if (metrics.contains("slam_shadows") && metrics["slam_shadows"].is_array())
    for (const auto& s : metrics["slam_shadows"])
      if (s.is_string()) shadows.push_back(s.get<std::string>());
  run.trajectory = read_trajectory(run_dir / "trajectory.csv", shadows);
  const fs::path track_file = run_dir / "track.csv";
  if (!fs::exists(track_file, ec))
    throw core::InputError(track_file.string(), 0,
                           "missing: the run's cones (EUFS CSV), which `conesim run` writes");
  run.track = tracks::read_track(track_file);
  if (fs::exists(run_dir / kReplayLogFile, ec))
    run.log = read_replay_log(run_dir / kReplayLogFile);
  return run;
}


fs::path write_replay_page(const fs::path& run_dir, const fs::path& three_js_dir) {
  const RunFolder run = read_run_folder(run_dir);
  const nlohmann::json& metrics = run.metrics;
  const RunTrajectory& traj = run.trajectory;
  const tracks::Track& track = run.track;
  const std::optional<ReplayLog>& log = run.log;
  std::error_code ec;

  const fs::path three_file = three_js_dir / "three.min.js";
  const fs::path orbit_file = three_js_dir / "examples/js/controls/OrbitControls.js";
  const std::string three_js =
      read_text(three_file, "three.js, from Debian's libjs-three (./conesim installs it)");
  const std::string orbit_js =
      read_text(orbit_file, "three.js's OrbitControls, from Debian's libjs-three");

  // the cones, and when each knocked one was hit (the referee's cone_hit events)
  std::vector<float> cone_xy, cone_hit;
  std::vector<uint8_t> cone_cls;
  for (const tracks::Cone& c : track.cones) {
    cone_xy.push_back(static_cast<float>(c.position.x()));
    cone_xy.push_back(static_cast<float>(c.position.y()));
    cone_cls.push_back(static_cast<uint8_t>(1 + static_cast<int>(c.cls)));
    cone_hit.push_back(-1.f);
    cone_hit.push_back(0.f);
  }
  for (const auto& e : metrics["events"]) {
    if (e["kind"] != "cone_hit") continue;
    // the cone by its file id, or else the nearest to where the event says it stood
    int best = -1;
    if (e.contains("cone_id") && e["cone_id"].is_number_unsigned())
      for (const tracks::Cone& c : track.cones)
        if (track.file_id(c.id) == e["cone_id"].get<uint64_t>()) best = c.id;
    if (best < 0 && e.contains("cone_x_m") && e.contains("cone_y_m")) {
      const core::Vec2 at(e["cone_x_m"].get<double>(), e["cone_y_m"].get<double>());
      double d_best = 0.5;
      for (const tracks::Cone& c : track.cones)
        if (const double d = (c.position - at).norm(); d < d_best) d_best = d, best = c.id;
    }
    if (best < 0) continue;
    size_t index = 0;
    while (index < track.cones.size() && track.cones[index].id != best) ++index;
    if (index == track.cones.size() || cone_hit[2 * index] >= 0.f) continue;
    // it falls away from the car
    const core::Vec2 car(e.value("x_m", 0.0), e.value("y_m", 0.0));
    const core::Vec2 away = track.cones[index].position - car;
    cone_hit[2 * index] = static_cast<float>(e["t_s"].get<double>());
    cone_hit[2 * index + 1] = static_cast<float>(std::atan2(away.y(), away.x()));
  }

  nlohmann::json blobs = {{"traj", b64(traj.rows)},
                          {"cone_xy", b64(cone_xy)},
                          {"cone_cls", b64(cone_cls)},
                          {"cone_hit", b64(cone_hit)}};
  nlohmann::json maps = nlohmann::json::array();
  size_t sweep_points = 0;
  if (log) {
    std::vector<float> t, origin;
    std::vector<uint32_t> offset{0};
    std::vector<int16_t> xyz;
    std::vector<uint8_t> intensity, label;
    std::vector<int16_t> cone;
    for (const ReplayLog::Sweep& s : log->sweeps) {
      cone.insert(cone.end(), s.cone.begin(), s.cone.end());
      t.push_back(static_cast<float>(s.t_s));
      origin.push_back(s.origin_x);
      origin.push_back(s.origin_y);
      xyz.insert(xyz.end(), s.xyz_cm.begin(), s.xyz_cm.end());
      intensity.insert(intensity.end(), s.intensity.begin(), s.intensity.end());
      label.insert(label.end(), s.label.begin(), s.label.end());
      offset.push_back(static_cast<uint32_t>(intensity.size()));
    }
    sweep_points = intensity.size();
    blobs["sweep_t"] = b64(t);
    blobs["sweep_origin"] = b64(origin);
    blobs["sweep_offset"] = b64(offset);
    blobs["sweep_xyz"] = b64(xyz);
    blobs["sweep_intensity"] = b64(intensity);
    blobs["sweep_label"] = b64(label);
    blobs["sweep_cone"] = b64(cone);
    std::vector<float> dt, dxy;
    std::vector<int32_t> dcone;
    std::vector<uint32_t> doff{0};
    for (const ReplayLog::Detections& d : log->detections) {
      dt.push_back(static_cast<float>(d.t_s));
      dcone.insert(dcone.end(), d.cone.begin(), d.cone.end());
      dxy.insert(dxy.end(), d.xy.begin(), d.xy.end());
      doff.push_back(static_cast<uint32_t>(dcone.size()));
    }
    blobs["det_t"] = b64(dt);
    blobs["det_offset"] = b64(doff);
    blobs["det_cone"] = b64(dcone);
    blobs["det_xy"] = b64(dxy);
    for (size_t k = 0; k < log->maps.size(); ++k) {
      const auto& [lane, snaps] = log->maps[k];
      std::vector<float> mt, xy;
      std::vector<uint32_t> moff{0};
      std::vector<uint8_t> cls;
      for (const ReplayLog::MapSnapshot& m : snaps) {
        mt.push_back(static_cast<float>(m.t_s));
        xy.insert(xy.end(), m.xy.begin(), m.xy.end());
        cls.insert(cls.end(), m.cls.begin(), m.cls.end());
        moff.push_back(static_cast<uint32_t>(cls.size()));
      }
      const std::string key = "map" + std::to_string(k);
      blobs[key + "_t"] = b64(mt);
      blobs[key + "_offset"] = b64(moff);
      blobs[key + "_xy"] = b64(xy);
      blobs[key + "_cls"] = b64(cls);
      maps.push_back({{"lane", lane}, {"key", key}, {"snapshots", snaps.size()}});
    }
  }
  // the left camera's frames: each JPEG as its own base64 string (the page shows it as a data
  // URL), the boxes of all frames in flat arrays, detected then true per frame
  nlohmann::json camera;  // null: no panel
  if (log && !log->camera.empty()) {
    std::vector<float> ct, box;
    std::vector<uint32_t> box_offset{0};
    std::vector<int32_t> box_id;
    std::vector<uint8_t> box_cls, box_truth;
    nlohmann::json jpegs = nlohmann::json::array();
    for (const ReplayLog::CameraFrame& f : log->camera) {
      ct.push_back(static_cast<float>(f.t_s));
      jpegs.push_back(base64(f.jpeg.data(), f.jpeg.size()));
      for (const auto* boxes : {&f.detected, &f.truth})
        for (const ReplayLog::CameraFrame::Box& b : *boxes) {
          box.insert(box.end(), {b.x0, b.y0, b.x1, b.y1, b.range_m});
          box_id.push_back(b.id);
          box_cls.push_back(b.cls);
          box_truth.push_back(boxes == &f.truth ? 1 : 0);
        }
      box_offset.push_back(static_cast<uint32_t>(box_id.size()));
    }
    const std::pair<const char*, std::string> arrays[] = {{"cam_t", b64(ct)},
                                                          {"cam_box_offset", b64(box_offset)},
                                                          {"cam_box", b64(box)},
                                                          {"cam_box_id", b64(box_id)},
                                                          {"cam_box_cls", b64(box_cls)},
                                                          {"cam_box_truth", b64(box_truth)}};
    for (const auto& array : arrays) blobs[array.first] = array.second;
    blobs["cam_jpeg"] = std::move(jpegs);
    camera = {{"frames", log->camera.size()},
              {"width", log->camera.front().width},
              {"height", log->camera.front().height}};
  }
  const vehicle_models::VehicleParams vp;
  nlohmann::json meta = {
      {"scenario", metrics.value("scenario", "")},
      {"event", metrics.value("event", "")},
      {"track", metrics.value("track", track.name)},
      {"seed", metrics.value("seed", nlohmann::json())},
      {"completed", metrics.value("completed", false)},
      {"dnf_reason", metrics.value("dnf_reason", "")},
      {"laps", metrics.value("laps", 0)},
      {"final_time_s", metrics.value("final_time_s", nlohmann::json())},
      {"slam_driving", metrics.value("slam_driving", "none")},
      {"events", metrics["events"]},
      {"traj_width", traj.width},
      {"traj_rows", traj.count},
      {"shadow_lanes", traj.lanes},
      {"cones", track.cones.size()},
      {"maps", maps},
      {"sweeps", log ? log->sweeps.size() : 0},
      {"sweep_points", sweep_points},
      {"has_log", log.has_value()},
      {"camera", camera},
      {"vehicle",
       {{"length_m", vp.length_m},
        {"width_m", vp.width_m},
        {"front_m", vp.front_overhang_from_rear_axle_m},
        {"wheelbase_m", vp.wheelbase_m},
        {"track_m", vp.track_m},
        {"wheel_radius_m", vp.wheel_radius_m},
        {"wheel_width_m", vp.wheel_width_m}}},
  };
  std::string data = nlohmann::json({{"meta", meta}, {"blobs", blobs}})
                         .dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  // nothing inside the script element may close it
  for (size_t p = 0; (p = data.find("</", p)) != std::string::npos; p += 3)
    data.replace(p, 2, "<\\/");

  std::string page = kReplayPageTemplate;
  auto fill = [&page](const std::string& mark, const std::string& with) {
    const size_t at = page.find(mark);
    if (at == std::string::npos) throw std::logic_error("replay page template lacks " + mark);
    page.replace(at, mark.size(), with);
  };
  // in the order they stand in the page: what is put in is never searched again
  fill("/*@THREE_JS@*/", three_js);
  fill("/*@ORBIT_CONTROLS@*/", orbit_js);
  const size_t data_mark = page.find("@REPLAY_DATA@");
  if (data_mark == std::string::npos) throw std::logic_error("replay page template lacks data");
  page.replace(data_mark, std::string("@REPLAY_DATA@").size(), data);

  const fs::path out = run_dir / kReplayPageFile;
  const fs::path partial = run_dir / (std::string(".partial-") + kReplayPageFile);
  {
    std::ofstream f(partial, std::ios::binary);
    f << page;
    f.close();
    if (!f) {
      fs::remove(partial, ec);
      throw core::InputError(out.string(), 0, "cannot write");
    }
  }
  fs::rename(partial, out);
  return out;
}

}  // namespace conesim::sim
