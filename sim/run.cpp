#include "sim/run.hpp"

#include <fcntl.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>

#include "control/drivability.hpp"
#include "control/driver.hpp"
#include "control/racing_line.hpp"
#include "core/error.hpp"
#include "laptime/qss.hpp"
#include "sensors/lidar_config.hpp"
#include "sim/autonomy.hpp"
#include "sim/interrupt.hpp"
#include "sim/json_text.hpp"
#include "sim/lap_time_report.hpp"
#include "sim/replay.hpp"
#include "sim/report.hpp"
#include "sim/slam_runner.hpp"
#include "sim/track_commands.hpp"
#include "sim/vehicle_sensor_feed.hpp"
#include "sim/vehicle_sim.hpp"
#include "tracks/fsg_layouts.hpp"
#include "tracks/io.hpp"
#include "tracks/rules.hpp"

namespace conesim::sim {

namespace fs = std::filesystem;
using core::TimeUs;

namespace {

// a run never goes on longer than the longest event limit plus this margin, sim seconds
constexpr double kHardStopMarginS = 60.0;
// rows of trajectory.csv per sim second
constexpr double kTrajectoryRateHz = 20.0;
// how often the replay recorder takes the true pose, sim us
constexpr core::TimeUs kReplayPosePeriodUs = 10'000;

// rounds to a decimal step (0.1, 0.001) so the JSON shows the short form of the number
double round_to(double v, double step) {
  const double per_unit = std::round(1.0 / step);
  return std::round(v * per_unit) / per_unit;
}

// writes text to a file all at once: a temporary file renamed into place
void write_file_atomically(const fs::path& file, const std::string& text) {
  const fs::path partial = file.parent_path() / (".partial-" + file.filename().string());
  {
    std::ofstream out(partial, std::ios::binary);
    out << text;
    if (!out) throw std::runtime_error(partial.string() + ": cannot write");
  }
  fs::rename(partial, file);
}

// trajectory.csv as the run goes: without shadow back-ends each row goes straight into a
// partial file, renamed into place at the end, so that a long run holds none of them; with
// shadows the rows wait in memory for the shadows' columns, which come after the run. A run
// that does not finish leaves no partial file behind.
class TrajectoryFile {
 public:
  TrajectoryFile(const fs::path& file, const std::string& header, bool streamed)
      : file_(file), partial_(file.parent_path() / (".partial-" + file.filename().string())) {
    if (streamed) {
      out_.open(partial_, std::ios::binary);
      if (!out_) throw std::runtime_error(partial_.string() + ": cannot write");
    }
    add(header);
  }
  TrajectoryFile(const TrajectoryFile&) = delete;
  TrajectoryFile& operator=(const TrajectoryFile&) = delete;
  ~TrajectoryFile() {
    if (done_) return;
    out_.close();
    std::error_code ec;
    fs::remove(partial_, ec);
  }

  // one row without its line end
  void add(const std::string& row) {
    if (out_.is_open())
      out_ << row << '\n';
    else
      rows_.push_back(row);
  }

  // the rows (the header first) with each shadow's pose at each row appended, in place
  void finish(const std::vector<std::vector<core::Pose2>>& shadow_poses) {
    if (!out_.is_open()) {
      std::string text;
      for (size_t i = 0; i < rows_.size(); ++i) {
        text += rows_[i];
        // (row 0 is the header: it names the shadows' columns already)
        if (i > 0)
          for (const auto& poses : shadow_poses) {
            const core::Pose2& p = poses[i - 1];
            char cols[100];
            std::snprintf(cols, sizeof(cols), ",%.4f,%.4f,%.5f", p.x, p.y, p.yaw);
            text += cols;
          }
        text += "\n";
      }
      write_file_atomically(file_, text);
      done_ = true;
      return;
    }
    out_.close();
    if (!out_) throw std::runtime_error(partial_.string() + ": cannot write");
    fs::rename(partial_, file_);
    done_ = true;
  }

 private:
  fs::path file_, partial_;
  std::ofstream out_;
  std::vector<std::string> rows_;
  bool done_ = false;
};

// the free space a run needs at least: metrics, trajectory, track and pictures of a long run
constexpr unsigned long long kMinFreeBytes = 16ull << 20;
// the probe written into an output folder before a run, bytes
constexpr size_t kProbeBytes = 64 * 1024;

// the longest a run of this event may take before the referee must have ruled
double hard_stop_s(const Scenario& s) {
  const RefereeParams& r = s.referee;
  double limit = r.timeout_trackdrive_total_s;
  switch (s.event) {
    case core::EventType::kAcceleration:
      limit = r.timeout_acceleration_s;
      break;
    case core::EventType::kSkidpad:
      limit = r.timeout_skidpad_s;
      break;
    case core::EventType::kAutocross:
      limit = r.timeout_autocross_s;
      break;
    case core::EventType::kTrackdrive:
      break;
  }
  return limit + r.stuck_time_s + kHardStopMarginS;
}

// the shadow lanes' names (every lane but the driving one)
std::vector<std::string> shadow_names(const SlamRunner& slam) {
  std::vector<std::string> names = slam.lane_names();
  names.erase(names.begin());
  return names;
}

// the pass criteria, one line per failure
// slam_metrics: the backend's metrics.json object, null without SLAM
std::vector<std::string> check_pass(const PassCriteria& pass, const RefereeResult& r,
                                    const nlohmann::json& slam_metrics) {
  std::vector<std::string> failures;
  if (pass.completed && !r.completed)
    failures.push_back("not completed" + (r.dnf_reason.empty() ? "" : ": " + r.dnf_reason));
  if (static_cast<int>(r.cones_hit.size()) > pass.max_cones_hit)
    failures.push_back(std::to_string(r.cones_hit.size()) + " cones hit, at most " +
                       std::to_string(pass.max_cones_hit) + " allowed");
  if (r.off_course > pass.max_off_course)
    failures.push_back(std::to_string(r.off_course) + " off-course, at most " +
                       std::to_string(pass.max_off_course) + " allowed");
  if (pass.max_final_time_s > 0.0 && r.final_time_s > pass.max_final_time_s)
    failures.push_back("final time " + human_number(r.final_time_s) + " s over " +
                       human_number(pass.max_final_time_s) + " s");
  // the SLAM estimate's quality; a figure with nothing measured (null: no landmark matched a
  // true cone, no association, no update) fails the criterion on it
  if (slam_metrics.is_null()) return failures;
  auto limit = [&](const char* key, const char* what, bool at_most, double bound,
                   const char* why_null) {
    const nlohmann::json& v = slam_metrics.at(key);
    const std::string rule =
        std::string(at_most ? "at most " : "at least ") + human_number(bound) + " required";
    if (v.is_null()) {
      failures.push_back(std::string(what) + " not measured (" + key + " is null: " + why_null +
                         "), " + rule);
      return;
    }
    const double x = v.get<double>();
    if (at_most ? x > bound : x < bound)
      failures.push_back(std::string(what) + " " + human_number(x) + ", " + rule);
  };
  if (pass.max_map_rmse_m)
    limit("map_rmse_m", "SLAM map RMSE [m]", true, *pass.max_map_rmse_m,
          "no map landmark matched a true cone");
  if (pass.max_ate_rmse_m)
    limit("ate_rmse_m", "SLAM trajectory RMSE [m]", true, *pass.max_ate_rmse_m, "no SLAM update");
  if (pass.min_da_correct_fraction)
    limit("da_correct_fraction", "SLAM correct association fraction", false,
          *pass.min_da_correct_fraction, "no observation was associated with a landmark");
  if (pass.max_map_missed_fraction)
    limit("map_missed_fraction", "SLAM map missed fraction of the cones in view", true,
          *pass.max_map_missed_fraction, "no true cone was ever in the perception's view");
  if (pass.max_false_loop_closures &&
      slam_metrics.at("false_loop_closures").get<int>() > *pass.max_false_loop_closures)
    failures.push_back(std::to_string(slam_metrics.at("false_loop_closures").get<int>()) +
                       " false loop closures, at most " +
                       std::to_string(*pass.max_false_loop_closures) + " allowed");
  return failures;
}

// the ids the cones' file gave them (what a user knows them by)
std::vector<uint64_t> file_ids(const tracks::Track& track, const std::vector<int>& ids) {
  std::vector<uint64_t> out;
  for (int id : ids) out.push_back(track.file_id(id));
  return out;
}

// the referee's events for metrics.json: kind, time, lap, the car's pose, reason, penalty, and
// the cone or the wheels
nlohmann::json events_json(const std::vector<RefereeEvent>& events) {
  nlohmann::json out = nlohmann::json::array();
  for (const RefereeEvent& e : events) {
    nlohmann::json j = {{"kind", to_string(e.kind)},
                        {"t_s", round_to(e.t_s, 1e-3)},
                        {"lap", e.lap},
                        {"x_m", round_to(e.pose.x, 1e-3)},
                        {"y_m", round_to(e.pose.y, 1e-3)},
                        {"yaw_rad", round_to(e.pose.yaw, 1e-4)},
                        {"reason", e.reason},
                        {"penalty_s", e.penalty_s}};
    if (e.kind == RefereeEvent::Kind::kConeHit) {
      j["cone_id"] = e.cone_file_id;
      j["cone_class"] = std::string(core::to_string(e.cone_class));
      j["cone_x_m"] = round_to(e.cone_position.x(), 1e-3);
      j["cone_y_m"] = round_to(e.cone_position.y(), 1e-3);
    } else if (e.kind == RefereeEvent::Kind::kOffCourse) {
      nlohmann::json wheels = nlohmann::json::array();
      for (const core::Vec2& w : e.wheels)
        wheels.push_back({round_to(w.x(), 1e-3), round_to(w.y(), 1e-3)});
      j["wheels_m"] = wheels;
      j["duration_s"] = round_to(e.duration_s, 1e-3);
    }
    out.push_back(std::move(j));
  }
  return out;
}

// where the car was when a fault began: the lap in progress (laps counted + 1) and the pose
struct FaultStart {
  int lap = 0;
  core::Pose2 pose;
};

// the driving estimate's position error at a trajectory row, with the true distance driven
struct TrajectoryError {
  TimeUs t = 0;
  double distance_m = 0.0;
  core::Vec2 position;
  double error_m = 0.0;
};

// the fault events among the referee's, in time order: kind `fault`, when it began and ended,
// what it is, the car's lap and pose at its start
nlohmann::json with_fault_events(nlohmann::json events, const std::vector<Fault>& faults,
                                 const std::vector<std::optional<FaultStart>>& starts) {
  for (size_t i = 0; i < faults.size(); ++i) {
    if (!starts[i]) continue;  // the run ended before it began
    const Fault& f = faults[i];
    events.push_back(
        {{"kind", "fault"},
         {"t_s", round_to(f.start_s, 1e-3)},
         {"end_s", f.end_s ? nlohmann::json(round_to(*f.end_s, 1e-3)) : nlohmann::json()},
         {"what", to_string(f.kind)},
         {"lap", starts[i]->lap},
         {"x_m", round_to(starts[i]->pose.x, 1e-3)},
         {"y_m", round_to(starts[i]->pose.y, 1e-3)},
         {"yaw_rad", round_to(starts[i]->pose.yaw, 1e-4)},
         {"reason", f.describe()},
         {"penalty_s", 0.0}});
  }
  std::stable_sort(events.begin(), events.end(),
                   [](const nlohmann::json& a, const nlohmann::json& b) {
                     return a.at("t_s").get<double>() < b.at("t_s").get<double>();
                   });
  return events;
}

// the RMSE of the errors at the rows in [from, to); null without a row
nlohmann::json rmse_between(const std::vector<TrajectoryError>& errors, TimeUs from, TimeUs to) {
  double sum = 0.0;
  int n = 0;
  for (const TrajectoryError& e : errors)
    if (e.t >= from && e.t < to) sum += e.error_m * e.error_m, ++n;
  if (n == 0) return nullptr;
  return round_to(std::sqrt(sum / n), 1e-4);
}

// the map error of the last map_error_over_distance row at or before `distance_m` (null
// without SLAM or before the first row)
nlohmann::json map_rmse_at(const nlohmann::json& slam_metrics, double distance_m) {
  nlohmann::json at = nullptr;
  if (slam_metrics.is_null() || !slam_metrics.contains("map_error_over_distance")) return at;
  for (const nlohmann::json& row : slam_metrics.at("map_error_over_distance")) {
    if (row.at("distance_m").get<double>() > distance_m) break;
    at = row.at("rmse_m");
  }
  return at;
}

// the true distance driven by time t
double distance_at(const std::vector<TrajectoryError>& errors, TimeUs t) {
  double d = 0.0;
  for (const TrajectoryError& e : errors) {
    if (e.t > t) break;
    d = e.distance_m;
  }
  return d;
}

// metrics.json's `faults`: each fault, what it did, and the driving estimate's error and the
// map's before, during and after it
nlohmann::json faults_json(const std::vector<Fault>& faults, const FaultCounts& counts,
                           const std::vector<TrajectoryError>& errors,
                           const nlohmann::json& slam_metrics, int frames_out_of_order) {
  nlohmann::json out = nlohmann::json::array();
  const TimeUs run_end = errors.empty() ? 0 : errors.back().t + 1;
  for (size_t i = 0; i < faults.size(); ++i) {
    const Fault& f = faults[i];
    const TimeUs start = core::from_seconds(f.start_s);
    const TimeUs end = f.end_s ? core::from_seconds(*f.end_s) : run_end;
    nlohmann::json j = {
        {"kind", to_string(f.kind)},
        {"start_s", round_to(f.start_s, 1e-3)},
        {"end_s", f.end_s ? nlohmann::json(round_to(*f.end_s, 1e-3)) : nlohmann::json()},
        {"what", f.describe()},
        {"affected", i < counts.affected.size() ? counts.affected[i] : 0},
        {"trajectory_rmse_before_m", rmse_between(errors, 0, start)},
        {"trajectory_rmse_during_m", rmse_between(errors, start, end)},
        {"trajectory_rmse_after_m",
         f.end_s ? rmse_between(errors, end, run_end) : nlohmann::json()},
        {"map_rmse_before_m", map_rmse_at(slam_metrics, distance_at(errors, start))},
        {"map_rmse_during_m", map_rmse_at(slam_metrics, distance_at(errors, end))},
        {"map_rmse_after_m",
         f.end_s && !slam_metrics.is_null() ? slam_metrics.at("map_rmse_m") : nlohmann::json()},
    };
    if (f.kind == FaultKind::kDelayJitter) j["frames_out_of_order"] = frames_out_of_order;
    out.push_back(std::move(j));
  }
  return out;
}

// two observers of the raw data as one: the replay recorder and the caller's tap, each given
// what it asked for (every Nth sweep by its own count)
class TeeTap : public SensorTap {
 public:
  TeeTap(SensorTap& a, SensorTap& b) : SensorTap(merged(a.kinds(), b.kinds())), a_(a), b_(b) {}
  void on_lidar(TimeUs delivered_us, const sdk::LidarSweep& sweep,
                const std::vector<int>* labels) override {
    const int64_t n = sweeps_++;
    for (SensorTap* tap : {&a_, &b_})
      if (tap->kinds().lidar && n % std::max(1, tap->kinds().lidar_every) == 0)
        tap->on_lidar(delivered_us, sweep, tap->kinds().lidar_labels ? labels : nullptr);
  }
  void on_stereo(TimeUs delivered_us, const sdk::StereoFrame& frame) override {
    for (SensorTap* tap : {&a_, &b_})
      if (tap->kinds().camera) tap->on_stereo(delivered_us, frame);
  }
  void on_imu(TimeUs delivered_us, const sdk::ImuSample& sample) override {
    for (SensorTap* tap : {&a_, &b_})
      if (tap->kinds().imu) tap->on_imu(delivered_us, sample);
  }
  void on_wheels(TimeUs delivered_us, const sdk::WheelSpeeds& sample) override {
    for (SensorTap* tap : {&a_, &b_})
      if (tap->kinds().wheels) tap->on_wheels(delivered_us, sample);
  }
  void on_steering(TimeUs delivered_us, const sdk::SteeringSample& sample) override {
    for (SensorTap* tap : {&a_, &b_})
      if (tap->kinds().steering) tap->on_steering(delivered_us, sample);
  }

 private:
  static SensorTapKinds merged(const SensorTapKinds& a, const SensorTapKinds& b) {
    SensorTapKinds k;
    k.lidar = a.lidar || b.lidar;
    k.lidar_labels = a.lidar_labels || b.lidar_labels;
    k.lidar_every = 1;
    k.camera = a.camera || b.camera;
    k.imu = a.imu || b.imu;
    k.wheels = a.wheels || b.wheels;
    k.steering = a.steering || b.steering;
    return k;
  }
  SensorTap& a_;
  SensorTap& b_;
  int64_t sweeps_ = 0;
};

// the LiDAR's sweep rate when the run has one anyway (the replay never switches it on), else 0
double run_lidar_sweep_hz(const Scenario& s) {
  if (!s.sensors.lidar_enabled && s.perception != "lidar" && s.perception != "fused") return 0.0;
  const auto config = sensors::lidar_preset(s.sensors.lidar_model);
  return config ? 1.0 / core::to_seconds(config->sweep_period_us()) : 0.0;
}

}  // namespace

std::string run_bounds_problem(const tracks::Track& track) {
  const auto outside = [](const core::Vec2& p) {
    return !(std::abs(p.x()) <= kMaxRunCoordinateM && std::abs(p.y()) <= kMaxRunCoordinateM);
  };
  char buf[300];
  for (const tracks::Cone& c : track.cones)
    if (outside(c.position)) {
      std::snprintf(buf, sizeof(buf),
                    "cone %llu stands at (%.1f, %.1f): a run needs every cone within %.0f m of "
                    "the origin on x and y (the sensors work in single precision); move the "
                    "layout's origin near the track",
                    static_cast<unsigned long long>(track.file_id(c.id)), c.position.x(),
                    c.position.y(), kMaxRunCoordinateM);
      return buf;
    }
  if (outside(track.start.position())) {
    std::snprintf(buf, sizeof(buf),
                  "the start (%.1f, %.1f) is more than %.0f m from the origin on x or y",
                  track.start.x, track.start.y, kMaxRunCoordinateM);
    return buf;
  }
  return {};
}

void check_output_writable(const fs::path& folder) {
  const auto refuse = [&folder](const std::string& why) {
    throw core::InputError(folder.string(), 0, "cannot write the results here: " + why);
  };
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) refuse("not a folder");

  // a probe file written, flushed to the disk and removed (a full disk fails the write or the
  // flush; a read-only one the open)
  const fs::path probe = folder / (".conesim-probe-" + std::to_string(getpid()));
  const int fd = open(probe.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) refuse(std::strerror(errno));
  const std::string block(kProbeBytes, '\n');
  const ssize_t written = write(fd, block.data(), block.size());
  const int write_errno = errno;
  const bool synced = written == static_cast<ssize_t>(block.size()) && fsync(fd) == 0;
  const int sync_errno = errno;
  close(fd);
  fs::remove(probe, ec);
  if (written != static_cast<ssize_t>(block.size()))
    refuse(written < 0 ? std::strerror(write_errno) : "the disk is full");
  if (!synced) refuse(std::strerror(sync_errno));

  // and room for the results
  struct statvfs space {};
  if (statvfs(folder.c_str(), &space) == 0) {
    const unsigned long long free_bytes =
        static_cast<unsigned long long>(space.f_bavail) * space.f_frsize;
    if (free_bytes < kMinFreeBytes)
      refuse(std::to_string(free_bytes >> 10) + " KiB free, a run needs at least " +
             std::to_string(kMinFreeBytes >> 20) + " MiB");
  }
}

namespace {

// acceleration: the braking zone against where the driver stops (it plans for FSG's zone: a
// shorter one, which it cannot see the end of in time, is overrun)
std::string acceleration_problem(const Scenario& s, const tracks::Track& track,
                                 const control::VehicleGeometry& geometry) {
  if (track.timing_gates.size() < 2) return {};  // the FSG distances are assumed
  const core::Vec2 forward = track.start.heading();
  const tracks::Gate& start = track.timing_gates.front();
  const tracks::Gate& finish = track.timing_gates[1];
  const core::Vec2 start_mid = 0.5 * (start.left + start.right);
  const core::Vec2 finish_mid = 0.5 * (finish.left + finish.right);
  const double finish_along = (finish_mid - start_mid).dot(forward);
  double farthest = -std::numeric_limits<double>::infinity();
  core::Vec2 last = finish_mid;
  for (const tracks::Cone& c : track.cones) {
    const double along = (c.position - start_mid).dot(forward);
    if (along > farthest) farthest = along, last = c.position;
  }
  if (finish_along <= 1.0 || farthest <= finish_along + 1.0) return {};  // no zone marked
  const double zone_m = farthest - finish_along;

  // the speed at the line: the driver's cap, or what the car reaches from a standing start
  std::vector<double> along, flat;
  for (double x = 0.0; x <= finish_along; x += 1.0) along.push_back(x), flat.push_back(0.0);
  const laptime::SpeedTrace launch =
      laptime::standing_start(along, flat, vehicle_models::PerformanceEnvelope::of(s.vehicle, 1.0));
  const double v = std::min(s.driver.acceleration_speed_mps, launch.speed_mps.back());
  const double stop_m = control::acceleration_stop_past_finish_m(s.driver, geometry, v);
  if (stop_m <= zone_m) return {};
  // the fastest crossing the driver stops from inside this zone (half a metre to spare)
  double lo = 0.0, hi = v;
  for (int i = 0; i < 40; ++i) {
    const double mid = 0.5 * (lo + hi);
    (control::acceleration_stop_past_finish_m(s.driver, geometry, mid) <= zone_m - 0.5 ? lo : hi) =
        mid;
  }
  char buf[400];
  std::snprintf(buf, sizeof(buf),
                "the braking zone is %.1f m long (finish gate at %s, last cone at %s), and the "
                "driver, crossing the line at %.1f m/s, stops %.1f m past it (it brakes for "
                "FSG's %.0f m zone, whose end it cannot see in time); it fits with "
                "driver.acceleration_speed_mps=%.0f",
                zone_m, core::format_place(finish_mid).c_str(), core::format_place(last).c_str(), v,
                stop_m, tracks::kAccelerationBrakingZoneM, std::floor(lo));
  return buf;
}

}  // namespace

// what the driver knows of the car: its geometry and its envelope at full measured grip
control::VehicleGeometry driver_vehicle(const vehicle_models::VehicleParams& vp) {
  control::VehicleGeometry g;
  g.wheelbase_m = vp.wheelbase_m;
  g.max_steer_rad = vp.max_steer_rad;
  g.max_steer_rate_rps = vp.max_steer_rate_rps;
  g.rear_axle_to_front_m = vp.front_overhang_from_rear_axle_m;
  g.rear_axle_to_back_m = vp.length_m - vp.front_overhang_from_rear_axle_m;
  g.width_m = vp.width_m;
  g.envelope = vehicle_models::PerformanceEnvelope::of(vp, 1.0);
  // the yaw gain table the driver carries is the default car's; any other car is measured
  if (!(vp == vehicle_models::VehicleParams{})) g.yaw_gain = measure_yaw_gain(vp);
  return g;
}

std::string drivability_problem(const Scenario& s, const tracks::Track& track) {
  // a cone under the car where it starts is hit before it moves
  const control::VehicleGeometry geometry = driver_vehicle(s.vehicle);
  const control::Footprint car{geometry.rear_axle_to_front_m, geometry.rear_axle_to_back_m,
                               0.5 * geometry.width_m, 0.0};
  const core::Pose2 rear_axle = track.start.compose({-geometry.rear_axle_to_front_m, 0.0, 0.0});
  for (const tracks::Cone& c : track.cones) {
    if (control::footprint_clearance(
            rear_axle, {{c.id, c.cls, c.position, Eigen::Matrix2d::Zero()}}, car) < 0.0)
      return "the " + std::string(core::to_string(c.cls)) + " cone at " +
             core::format_place(c.position) +
             " stands under the car where it starts (front wing at " +
             core::format_place(track.start.position()) + ")";
  }
  if (s.event == core::EventType::kAcceleration) return acceleration_problem(s, track, geometry);
  if (s.event != core::EventType::kAutocross && s.event != core::EventType::kTrackdrive) return {};
  // a car that starts off the track finds no path through the cones
  for (const tracks::Violation& v : tracks::check_rules(track, s.event))
    if (v.rule == "start_on_track") return v.message + ": the driver finds no path from there";
  std::vector<core::MapCone> cones;
  for (const tracks::Cone& c : track.cones)
    cones.push_back({c.id, c.cls, c.position, Eigen::Matrix2d::Identity() * 1e-6});
  const control::Drivability d = control::check_drivability(
      track.lane_points(track.left_lane), track.lane_points(track.right_lane), track.centre_line,
      track.closed, cones, geometry);
  return d.reason;
}

tracks::Track scenario_track(const Scenario& s) {
  if (!s.track.file) {
    tracks::GeneratorParams circuit;
    circuit.profile = s.track.generate_profile;
    return make_event_track(s.event, s.track.generate_seed.value_or(s.seed), circuit);
  }
  tracks::Track track = tracks::read_track(*s.track.file);

  // laps need a circuit: an open layout (a point-to-point course) is driven once, as autocross
  if (s.event == core::EventType::kTrackdrive && !track.closed && !track.left_lane.empty() &&
      !track.right_lane.empty()) {
    const std::string ends = core::format_place(track.cone(track.left_lane.back()).position) +
                             " and " +
                             core::format_place(track.cone(track.right_lane.back()).position);
    throw core::InputError(s.track.file->string(), "event",
                           std::string("trackdrive needs a closed circuit, and this layout's "
                                       "lanes do not close (they end at ") +
                               ends + "); run it as autocross");
  }
  return track;
}

core::ConeObservations perceive_ground_truth(const tracks::Track& track, const core::Pose2& pose,
                                             const SensorSettings& sensors,
                                             const std::function<bool(int)>& is_knocked,
                                             std::vector<int>* ids) {
  core::ConeObservations obs;
  const double range2 = sensors.cone_range_m * sensors.cone_range_m;
  const double half_fov = 0.5 * sensors.cone_fov_deg * std::numbers::pi / 180.0;
  for (const tracks::Cone& cone : track.cones) {
    const core::Vec2 local = pose.inverse_transform(cone.position);
    if (local.squaredNorm() > range2) continue;
    if (std::abs(std::atan2(local.y(), local.x())) > half_fov) continue;
    if (is_knocked && is_knocked(cone.id)) continue;
    core::ConeObservation o;
    o.position = local;
    o.cls = cone.cls;
    o.covariance = Eigen::Matrix2d::Identity() * 1e-6;
    obs.cones.push_back(o);
    if (ids) ids->push_back(cone.id);
  }
  return obs;
}

RunResult run_scenario(const Scenario& s, const tracks::Track& track, const RunOptions& options) {
  using clock = std::chrono::steady_clock;
  const auto wall_start = clock::now();
  fs::create_directories(options.out_dir);
  // a metrics.json from an earlier run in the same folder would look like this run's result
  fs::remove(options.out_dir / "metrics.json");
  fs::remove(options.out_dir / kIncompleteFile);

  // the world: the car with its front wing on the start pose, the referee and the driver
  const vehicle_models::VehicleParams& vp = s.vehicle;
  const core::Pose2 rear_axle_start =
      track.start.compose({-vp.front_overhang_from_rear_axle_m, 0.0, 0.0});
  VehicleSim car(vp, rear_axle_start, tracks::GroundModel(track, s.ground, s.seed));
  RefereeParams referee_params = s.referee;
  referee_params.trackdrive_laps = s.driver.trackdrive_laps;
  Referee referee(track, s.event, vp, referee_params);
  std::vector<core::MapCone> prior_map;
  if (s.event == core::EventType::kSkidpad) {
    // skidpad is driven from its known layout
    for (const tracks::Cone& c : track.cones)
      prior_map.push_back({c.id, c.cls, c.position, Eigen::Matrix2d::Identity() * 1e-6});
  }
  // the replay's record, beside the caller's tap when there is one
  std::unique_ptr<ReplayRecorder> recorder;
  std::unique_ptr<TeeTap> tee;
  SensorTap* tap = options.sensor_tap;
  if (options.replay) {
    recorder = std::make_unique<ReplayRecorder>(options.out_dir, track, run_lidar_sweep_hz(s));
    if (tap)
      tee = std::make_unique<TeeTap>(*recorder, *tap), tap = tee.get();
    else if (recorder->kinds().lidar)
      tap = recorder.get();
  }
  SensorRig rig(s, track, car, options.dump, options.out_dir, tap, options.labelled);
  // the replay's camera frames, a few a second, when the run has the camera anyway
  if (recorder && rig.camera_on() && recorder->settings().camera_rate_hz > 0.0)
    rig.set_camera_observer(
        core::from_seconds(1.0 / recorder->settings().camera_rate_hz),
        [r = recorder.get()](const CameraReplayFrame& frame) { r->on_camera(frame); });
  // the car's own sensors for the tap: a feed of its own, with SLAM's seed and noise (so the
  // samples SLAM's odometry integrates)
  std::optional<VehicleSensorFeed> tap_feed;
  if (options.sensor_tap && options.sensor_tap->kinds().vehicle_sensors())
    tap_feed.emplace(s.seed, s.sensors.imu, s.sensors.wheel_encoders);
  // every perception but ground truth delivers frames with noise and latency
  const bool noisy_perception = s.perception != "ground_truth";
  // the stack: every driver, the reference one included, runs through the SDK's interface; a
  // plug-in that fails ends the run with a DNF naming it
  std::string dnf_override;
  const control::VehicleGeometry geometry = driver_vehicle(vp);
  const std::unique_ptr<RunInfoStorage> run_info =
      make_run_info(s, geometry, rear_axle_start, prior_map);
  std::unique_ptr<SlamRunner> slam;
  std::unique_ptr<sdk::Driver> driver;
  try {
    if (s.slam != "none") slam = std::make_unique<SlamRunner>(s, track, car);
    if (slam && recorder)
      slam->set_map_observer(
          [r = recorder.get()](const std::string& lane, TimeUs stamp, const core::Estimate& e) {
            r->on_map(lane, stamp, e);
          });
    if (options.make_driver)
      driver = options.make_driver(run_info->info);
    else if (s.driver_plugin)
      driver = std::make_unique<GuardedDriver>(
          *s.driver_plugin, make_plugin_driver(*s.driver_plugin, run_info->info));
  } catch (const PluginFailure& e) {
    dnf_override = e.what();
  }
  if (!driver) driver = std::make_unique<ReferenceDriver>(s.event, s.driver, geometry, prior_map);
  core::Pose2 driving_pose = car.truth().pose;
  core::ConeObservations latest_detections;
  core::Pose2 latest_capture_pose;
  // the driver's input in the SDK's types (buffers reused from tick to tick)
  std::vector<sdk::ConeObservation> observation_buffer;
  std::vector<sdk::MapCone> map_buffer;
  sdk::DriverStatus driver_status = driver->status();

  // the schedule on the integer clock
  const TimeUs step_us = core::from_seconds(car.timestep_s());
  const TimeUs driver_period_us = core::from_seconds(1.0 / s.sensors.driver_rate_hz);
  const TimeUs trajectory_period_us = core::from_seconds(1.0 / kTrajectoryRateHz);
  const TimeUs hard_stop_us = core::from_seconds(hard_stop_s(s) + s.start_delay_s);
  const TimeUs start_delay_us = core::from_seconds(s.start_delay_s);
  const int laps_target = s.event == core::EventType::kTrackdrive ? s.driver.trackdrive_laps
                          : s.event == core::EventType::kSkidpad  ? 4
                                                                  : 1;

  // what the car has seen so far: with ground-truth perception and no SLAM, the map is the
  // true position of every cone seen once
  std::vector<char> seen(static_cast<size_t>(track.next_id()), 0);
  std::vector<core::MapCone> map;
  // the path driven and its speed, for the pictures
  std::vector<core::Vec2> driven;
  std::vector<double> driven_speed_mps;
  std::vector<core::Vec2> lap_ends;
  // trajectory.csv, each shadow back-end's estimate beside the driving one's; the shadows'
  // columns come after the run from the time and the odometry of each row
  const std::vector<std::string> shadow_lanes =
      slam ? shadow_names(*slam) : std::vector<std::string>{};
  std::string trajectory_header =
      "t_s,x_m,y_m,yaw_rad,speed_mps,steer_rad,accel_cmd_mps2,est_x_m,est_y_m,est_yaw_rad";
  for (const std::string& lane : shadow_lanes)
    trajectory_header += "," + lane + "_x_m," + lane + "_y_m," + lane + "_yaw_rad";
  TrajectoryFile trajectory_file(options.out_dir / "trajectory.csv", trajectory_header,
                                 shadow_lanes.empty());
  std::vector<TimeUs> trajectory_t;
  std::vector<core::Pose2> trajectory_odometry;
  auto is_knocked = [&referee](int id) { return referee.is_knocked(id); };
  // the faults: where the car was when each began, and the driving estimate's error at each
  // trajectory row with the true distance driven by then (their cost in metrics.json)
  std::vector<std::optional<FaultStart>> fault_starts(s.faults.size());
  std::vector<TrajectoryError> trajectory_errors;

  TimeUs t = 0;
  TimeUs next_replay_pose_us = 0;
  core::VehicleCommand command;
  auto last_progress = wall_start;
  int interrupted_by = 0;
  while (dnf_override.empty() && !referee.finished()) {
    // Ctrl-C or SIGTERM: the handler only set the flag, the loop stops here
    if ((interrupted_by = interrupt_signal()) != 0) break;
    if (t % driver_period_us == 0) {
      // a perception plug-in that failed on a frame collected by now ends the run
      if (!rig.failure().empty()) {
        dnf_override = rig.failure();
        break;
      }
      // perceive, estimate, drive
      const VehicleTruth truth = car.truth();
      if (!std::isfinite(truth.pose.x) || !std::isfinite(truth.pose.y)) {
        dnf_override = "physics diverged";
        break;
      }
      // the faults that begin by now: the car's place and lap then
      for (size_t i = 0; i < s.faults.size(); ++i)
        if (!fault_starts[i] && t >= core::from_seconds(s.faults[i].start_s))
          fault_starts[i] = FaultStart{referee.laps() + 1, truth.pose};
      // perception: perfect cones in view, or the cone sensor's latest delivered frame
      core::ConeObservations obs;
      std::vector<int> ids;
      core::Estimate estimate;
      slam::frontend::SweepMotion odometry_motion;
      if (slam) {
        // SLAM: every delivered frame updates the backend (at once, or taking effect after the
        // SLAM latency); the driver sees only its estimate
        slam->catch_up(t);
        while (auto d = rig.take_detections(t)) {
          if (recorder) recorder->on_detections(*d);
          slam->process(*d, t);
        }
        if (!slam->failure().empty()) {
          dnf_override = slam->failure();
          break;
        }
        estimate = slam->estimate_now(t, &odometry_motion);
        obs = slam->observations_at(estimate.pose);
      } else {
        if (noisy_perception) {
          while (auto d = rig.take_detections(t)) {
            if (recorder) recorder->on_detections(*d);
            // a frame delivered after a newer one (delay jitter) is too old to use
            if (!s.faults.empty() && d->observations.stamp < latest_detections.stamp) continue;
            latest_detections = std::move(d->observations);
            latest_capture_pose = d->capture_pose;
            for (int id : d->labels.cone_id)
              if (id >= 0) ids.push_back(id);
          }
          // frames were taken at their capture pose: express them in today's vehicle frame
          obs.stamp = latest_detections.stamp;
          for (core::ConeObservation o : latest_detections.cones) {
            o.position = truth.pose.inverse_transform(latest_capture_pose.transform(o.position));
            obs.cones.push_back(o);
          }
        } else {
          obs = perceive_ground_truth(track, truth.pose, s.sensors, is_knocked, &ids);
          obs.stamp = t;
        }
        // without SLAM the map is an oracle: the true position of every cone detected once
        for (size_t i = 0; i < ids.size(); ++i) {
          if (seen[ids[i]]) continue;
          seen[ids[i]] = 1;
          const tracks::Cone& c = track.cone(ids[i]);
          map.push_back({c.id, c.cls, c.position, Eigen::Matrix2d::Identity() * 1e-6});
        }
        estimate.stamp = t;
        estimate.pose = truth.pose;
        estimate.speed_mps = truth.vx_mps;
        estimate.yaw_rate_rps = truth.yaw_rate_rps;
        estimate.map = map;
      }
      driving_pose = estimate.pose;
      // perception de-skews and tracks with the odometry's motion (the truth without SLAM)
      rig.set_motion(slam ? odometry_motion
                          : slam::frontend::SweepMotion{estimate.speed_mps, estimate.yaw_rate_rps});
      if (options.on_tick) options.on_tick(t, referee.result());
      try {
        sdk::DriverInput input;
        input.now_us = t;
        input.estimate = to_sdk(estimate, map_buffer);
        input.observations = to_sdk(obs, observation_buffer);
        command = from_sdk(driver->update(input));
        driver_status = driver->status();
      } catch (const PluginFailure& e) {
        dnf_override = e.what();
        break;
      }
      // before the go signal the car is held at the start
      if (t < start_delay_us) command = {0.0, 0.0, true};

      // progress a few times per wall second
      if (options.on_progress && clock::now() - last_progress > std::chrono::milliseconds(250)) {
        last_progress = clock::now();
        const double wall = std::chrono::duration<double>(last_progress - wall_start).count();
        options.on_progress({core::to_seconds(t), core::to_seconds(t) / std::max(wall, 1e-9),
                             referee.laps(), laps_target, driver_status.state});
      }
    }
    if (t % trajectory_period_us == 0) {
      const VehicleTruth truth = car.truth();
      if (options.plot) {
        driven.push_back(truth.pose.position());
        driven_speed_mps.push_back(truth.vx_mps);
        // where each lap was counted, for run.png
        while (static_cast<int>(lap_ends.size()) < referee.laps())
          lap_ends.push_back(truth.pose.position());
      }
      char row[200];
      std::snprintf(row, sizeof(row), "%.3f,%.4f,%.4f,%.5f,%.3f,%.5f,%.3f,%.4f,%.4f,%.5f",
                    core::to_seconds(t), truth.pose.x, truth.pose.y, truth.pose.yaw, truth.vx_mps,
                    truth.steer_rad, command.accel_mps2, driving_pose.x, driving_pose.y,
                    driving_pose.yaw);
      trajectory_file.add(row);
      if (!s.faults.empty()) {
        const double along =
            trajectory_errors.empty()
                ? 0.0
                : trajectory_errors.back().distance_m +
                      (truth.pose.position() - trajectory_errors.back().position).norm();
        trajectory_errors.push_back({t, along, truth.pose.position(),
                                     (driving_pose.position() - truth.pose.position()).norm()});
      }
      if (!shadow_lanes.empty()) {
        trajectory_t.push_back(t);
        trajectory_odometry.push_back(slam->odometry_pose_now(t));
      }
    }
    // the replay places each LiDAR point where the car was when it was fired
    if (recorder && t >= next_replay_pose_us) {
      recorder->on_pose(t, car.truth().pose);
      next_replay_pose_us = t + kReplayPosePeriodUs;
    }
    // MuJoCo's sensors only on the steps whose IMU sample SLAM's odometry takes
    car.step(command,
             (slam && slam->imu_due(t + step_us)) || (tap_feed && tap_feed->imu_due(t + step_us)));
    t += step_us;
    referee.update(t, car.truth());
    rig.step(t, car, referee);
    if (tap_feed) {
      tap_feed->step(t, car);
      tap_feed->drain_to(*options.sensor_tap, t);
    }
    if (slam) {
      slam->step(t, car);
      // a frame the next driver tick takes goes to SLAM now if nothing before that tick reads
      // or changes SLAM's inputs (no trajectory row, and the tracker's motion is set at ticks
      // only): its update runs on a thread while the physics steps on, and takes effect at
      // the tick as if it had run there
      auto next_at_or_after = [t](TimeUs period) { return (t + period - 1) / period * period; };
      const TimeUs tick = next_at_or_after(driver_period_us);
      if (tick > t && next_at_or_after(trajectory_period_us) >= tick)
        while (const DeliveredDetections* d = rig.next_detections(tick)) {
          if (!slam->input_final(*d, t)) break;
          auto frame = rig.take_detections(tick);
          if (recorder) recorder->on_detections(*frame);
          slam->process_ahead(std::move(*frame), tick);
        }
    }
    if (t >= hard_stop_us) {
      dnf_override = "no verdict within the event's time limit";
      break;
    }
  }
  const double wall_s = std::chrono::duration<double>(clock::now() - wall_start).count();

  // interrupted: no verdict, no metrics.json; the queued work is dropped and the folder says
  // why it is incomplete (a run folder without metrics.json did not finish)
  if (interrupted_by != 0) {
    if (slam) slam->abandon();
    RunResult result;
    result.interrupted_by = interrupted_by;
    result.sim_time_s = core::to_seconds(t);
    result.wall_time_s = wall_s;
    char why[200];
    std::snprintf(why, sizeof(why),
                  "interrupted by %s at sim time %.3f s (%.1f s wall): this run did not finish "
                  "and wrote no metrics.json\n",
                  signal_name(interrupted_by), result.sim_time_s, wall_s);
    std::ofstream(options.out_dir / kIncompleteFile) << why;
    return result;
  }
  rig.finish();
  if (slam) slam->finish();

  // the verdict and the pass criteria
  RunResult result;
  result.referee = referee.result();
  if (!dnf_override.empty() && result.referee.dnf_reason.empty()) {
    result.referee.completed = false;
    result.referee.dnf_reason = dnf_override;
    RefereeEvent e;
    e.kind = RefereeEvent::Kind::kDnf;
    e.t_s = core::to_seconds(t);
    e.lap = result.referee.laps + 1;
    e.pose = car.truth().pose;
    e.reason = dnf_override;
    result.referee.events.push_back(e);
  }
  // the driver's own word on why it could not go on
  if (!result.referee.completed && *driver_status.problem)
    result.referee.dnf_reason += std::string(" (driver: ") + driver_status.problem + ")";
  // the faults that had begun by then, named
  if (!result.referee.completed) {
    std::string begun;
    for (size_t i = 0; i < s.faults.size(); ++i)
      if (fault_starts[i])
        begun += (begun.empty() ? "" : "; ") + to_string(s.faults[i].kind) + ": " +
                 s.faults[i].describe();
    if (!begun.empty()) {
      result.referee.dnf_reason += " (after faults: " + begun + ")";
      for (RefereeEvent& e : result.referee.events)
        if (e.kind == RefereeEvent::Kind::kDnf) e.reason += " (after faults: " + begun + ")";
    }
  }
  const nlohmann::json slam_metrics = slam ? slam->metrics() : nlohmann::json();
  result.failures = check_pass(s.pass, result.referee, slam_metrics);
  result.passed = result.failures.empty();
  result.sim_time_s = core::to_seconds(t);
  result.wall_time_s = wall_s;
  result.driver_laps = driver_status.laps_counted;
  if (slam) {
    const SlamScorer& scorer = slam->scorer();
    for (size_t i = 0; i < scorer.stamps().size() && i < scorer.update_cpu_ms().size(); ++i)
      result.slam_update_cpu_ms.push_back(
          {core::to_seconds(scorer.stamps()[i]), scorer.update_cpu_ms()[i]});
  }

  // metrics.json (every key in docs/metrics.md)
  const RefereeResult& r = result.referee;
  std::vector<double> lap_times;
  for (double lt : r.lap_times_s) lap_times.push_back(round_to(lt, 1e-3));
  nlohmann::json m = {
      {"scenario", s.name},
      {"event", std::string(core::to_string(s.event))},
      {"track", track.name},
      {"seed", s.seed},
      {"slam_driving", s.slam},
      {"slam_shadows", shadow_lanes},
      {"completed", r.completed},
      {"dnf_reason", r.dnf_reason},
      {"laps", r.laps},
      {"driver_laps", result.driver_laps},
      {"lap_times_s", lap_times},
      {"penalties",
       {{"cones_hit", r.cones_hit.size()},
        {"cones_hit_ids", file_ids(track, r.cones_hit)},
        {"off_course", r.off_course},
        {"penalty_time_s", round_to(r.final_time_s - r.raw_time_s, 1e-3)}}},
      {"events", with_fault_events(events_json(r.events), s.faults, fault_starts)},
      {"raw_time_s", round_to(r.raw_time_s, 1e-3)},
      {"final_time_s", round_to(r.final_time_s, 1e-3)},
      {"sim_time_s", round_to(result.sim_time_s, 1e-3)},
      {"wall_time_s", round_to(wall_s, 1e-3)},
      {"real_time_factor", round_to(result.sim_time_s / std::max(wall_s, 1e-9), 0.1)},
      {"passed", result.passed},
      {"pass_failures", result.failures},
      {"slam", slam ? slam->all_metrics() : nlohmann::json::object()},
      // the contract's perception figures (raw-data perception) and always the mode
      {"perception",
       rig.perception() ? rig.perception()->metrics() : nlohmann::json{{"mode", s.perception}}},
      {"sensors",
       {{"lidar_scans", rig.stats().lidar_scans},
        {"lidar_points", rig.stats().lidar_points},
        {"lidar_returns_faded", rig.stats().lidar_returns_faded},
        {"realism", s.sensors.realism ? "on" : "off"},
        {"camera_frames", rig.stats().camera_frames},
        {"cone_sensor_frames", rig.stats().cone_frames},
        {"lidar_detect_ms_mean",
         round_to(rig.stats().lidar_detect_ms_total / std::max(1, rig.stats().lidar_scans), 1e-3)},
        {"stereo_detect_ms_mean",
         round_to(rig.stats().stereo_detect_ms_total / std::max(1, rig.stats().camera_frames),
                  1e-3)}}},
  };
  // each fault, what it did and what it cost (a run without faults has no such key)
  if (!s.faults.empty()) {
    FaultCounts counts = rig.fault_counts();
    if (slam) counts.add(slam->fault_counts());
    m["faults"] = faults_json(s.faults, counts, trajectory_errors, slam_metrics,
                              slam ? slam->frames_out_of_order() : 0);
    m["sensors"]["lidar_sweeps_lost"] = rig.stats().lidar_sweeps_lost;
  }
  // the scenery beside the track (a run without clutter has no such key)
  if (!rig.scenery().empty()) {
    nlohmann::json by_class = nlohmann::json::object();
    for (core::ClutterClass c : core::kClutterClasses)
      by_class[std::string(core::to_string(c))] = 0;
    for (const tracks::SceneryObject& o : rig.scenery())
      by_class[std::string(core::to_string(o.cls))] =
          by_class[std::string(core::to_string(o.cls))].get<int>() + 1;
    m["world"] = {{"clutter_objects", rig.scenery().size()},
                  {"clutter_objects_per_100m", s.clutter.objects_per_100m},
                  {"clutter_by_class", by_class}};
  }
  // the ground under the track (a run on flat ground has no such key)
  if (!car.ground().flat()) {
    const tracks::GroundGrid& g = car.ground().grid();
    m["world"]["ground_relief_m"] = g.max_z - g.min_z;
    m["world"]["ground_cell_m"] = g.cell_m;
  }
  // the sensors' look world.randomise drew (a run without it has no such key)
  if (s.randomise) m["world"]["look"] = s.look;
  // the plug-ins in the loop, by name (a run of the built-in stack has no such key)
  if (s.perception_plugin || s.slam_plugin || s.driver_plugin) {
    auto name = [](const std::optional<PluginSpec>& p, const std::string& builtin) {
      return p ? "plugin:" + p->name() : builtin;
    };
    m["autonomy"] = {{"perception", name(s.perception_plugin, s.perception)},
                     {"slam", s.slam},
                     {"driver", name(s.driver_plugin, "reference")}};
  }
  // the lap-time bound at the car's full measured grip beside the lap times
  laptime::LapTimeOptions bound_options;
  bound_options.event = s.event;
  const laptime::LapTimeBound bound = laptime::lap_time_bound(track, vp, bound_options);
  add_lap_time_bound(m, bound, lap_times);
  result.metrics = m;

  // the results, metrics.json last of them: a run without it did not finish
  {
    std::vector<std::vector<core::Pose2>> shadow_poses;
    for (size_t k = 1; k <= shadow_lanes.size(); ++k)
      shadow_poses.push_back(slam->lane_poses(k, trajectory_t, trajectory_odometry));
    trajectory_file.finish(shadow_poses);
  }
  tracks::write_eufs_csv(track, options.out_dir / "track.csv");
  write_file_atomically(options.out_dir / "metrics.json", json_text(m, 2) + "\n");

  // the pictures after the results: one that fails (no gnuplot) is a warning, the result stands
  auto picture = [&result](const std::string& what, const std::function<void()>& draw) {
    // interrupted once the results are written: the pictures are left out, the run stands
    if (const int signal = interrupt_signal()) {
      result.warnings.push_back(what + " not written: interrupted by " + signal_name(signal));
      return;
    }
    try {
      draw();
    } catch (const std::exception& e) {
      result.warnings.push_back(what + " not written: " + e.what());
    }
  };
  if (options.plot) {
    PlotOverlay overlay{driven, r.cones_hit, "", {}, driven_speed_mps, {}};
    for (size_t k = 0; k < lap_ends.size(); ++k) {
      char lap[64];
      if (k < r.lap_times_s.size())
        std::snprintf(lap, sizeof(lap), "lap %zu: %.2f s", k + 1, r.lap_times_s[k]);
      else
        std::snprintf(lap, sizeof(lap), "lap %zu", k + 1);
      overlay.lap_ends.push_back({lap_ends[k], lap});
    }
    char summary[200];
    std::snprintf(summary, sizeof(summary), "%s, %d laps, %.2f s, %zu cones hit, %d off-course",
                  r.completed ? "completed" : ("DNF: " + r.dnf_reason).c_str(), r.laps,
                  r.final_time_s, r.cones_hit.size(), r.off_course);
    overlay.subtitle = summary;
    // every referee event where it happened: the cone, or the middle of the car
    int off_course_count = 0;
    for (const RefereeEvent& e : r.events) {
      using Kind = PlotOverlay::Mark::Kind;
      const core::Vec2 car_centre =
          e.pose.transform({0.5 * vp.front_overhang_from_rear_axle_m -
                                0.5 * (vp.length_m - vp.front_overhang_from_rear_axle_m),
                            0.0});
      const std::string lap = ", lap " + std::to_string(e.lap);
      switch (e.kind) {
        case RefereeEvent::Kind::kConeHit:
          overlay.marks.push_back(
              {Kind::kConeHit, e.cone_position, "cone " + std::to_string(e.cone_file_id) + lap});
          break;
        case RefereeEvent::Kind::kOffCourse:
          overlay.marks.push_back({Kind::kOffCourse, car_centre,
                                   "off-course " + std::to_string(++off_course_count) + lap});
          break;
        case RefereeEvent::Kind::kDnf:
          overlay.marks.push_back({Kind::kDnf, car_centre, "DNF" + lap});
          break;
      }
    }
    picture("run.png", [&] { plot_track(track, s.event, options.out_dir / "run.png", &overlay); });
    if (rig.perception())
      picture("perception_bands.png",
              [&] { rig.perception()->write_plot(options.out_dir / "perception_bands.png"); });
    if (slam) picture("the SLAM figures", [&] { slam->write_report(options.out_dir); });
    // the driven speed against the bound's, lap by lap (the run-out after the finish left out)
    if (bound.usable)
      picture("speed.png", [&] {
        std::vector<SpeedSeries> laps = driven_laps(bound, driven, driven_speed_mps, track.closed);
        if (laps.size() > r.lap_times_s.size()) laps.resize(r.lap_times_s.size());
        plot_speed(bound, laps, track.name + ": speed over distance against the lap-time bound",
                   options.out_dir / "speed.png");
      });
  }
  // report.html from metrics.json, verdict first: every run has one, pictures or not
  picture("report.html", [&] { write_run_report(options.out_dir, m); });
  if (recorder) {
    picture(kReplayPageFile, [&] {
      recorder->finish();
      write_replay_page(options.out_dir, default_three_js_dir());
    });
  }
  return result;
}

}  // namespace conesim::sim
