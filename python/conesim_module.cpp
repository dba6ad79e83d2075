// The Python module `conesim` (pybind11): a scenario run in lock-step from Python.
//
//   import conesim
//   sim = conesim.Sim("autocross", seed=3, set={"driver.explore_speed_mps": 8})
//   obs = sim.observation
//   while not obs["done"]:
//       obs = sim.step((steer_rad, accel_mps2))
//   print(sim.metrics()["final_time_s"])
//
// The run is conesim's own (`conesim run`: the same scenario checks, clock, sensors, referee,
// scoring and run folder); the Python program is its driver, called at every driver tick
// through the same sdk::Driver interface as the reference driver or a plug-in (docs/sdk.md).
// With observe=[...], each observation also holds the raw sensor data delivered since the
// previous tick, handed out by the run's SensorTap (sim/sensor_tap.hpp) as NumPy arrays.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <exception>
#include <initializer_list>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "core/error.hpp"
#include "python/observation.hpp"
#include "sim/autonomy.hpp"
#include "sim/json_text.hpp"
#include "sim/regress.hpp"
#include "sim/run.hpp"
#include "sim/scenario.hpp"
#include "sim/sensor_tap.hpp"

namespace py = pybind11;
using namespace conesim;

namespace {

// a LiDAR sweep and a stereo pair, copied out of the run thread
struct LidarFrame {
  core::TimeUs delivered_us = 0;
  sdk::LidarSweep sweep;
  std::vector<sdk::LidarPoint> points;
  std::vector<int32_t> labels;
  bool has_labels = false;
};
struct CameraFrame {
  core::TimeUs delivered_us = 0;
  sdk::StereoFrame frame;
  std::vector<uint8_t> left, right;
};

// the raw sensor data delivered since the previous driver tick
struct RawData {
  std::vector<LidarFrame> lidar;
  std::vector<CameraFrame> camera;
  std::vector<sdk::ImuSample> imu;
  std::vector<sdk::WheelSpeeds> wheels;
  std::vector<sdk::SteeringSample> steering;
};

// the observer of a lock-step run's raw data (observe=): keeps what the rig and the vehicle
// sensors deliver until the driver tick at or after its delivery
class RawDataTap final : public sim::SensorTap {
 public:
  using sim::SensorTap::SensorTap;

  void on_lidar(core::TimeUs delivered_us, const sdk::LidarSweep& sweep,
                const std::vector<int>* labels) override {
    LidarFrame f;
    f.delivered_us = delivered_us;
    f.sweep = sweep;
    f.points.assign(sweep.points.begin(), sweep.points.end());
    f.sweep.points = {};
    if (labels) f.labels.assign(labels->begin(), labels->end());
    f.has_labels = labels != nullptr;
    pending_.lidar.push_back(std::move(f));
  }
  void on_stereo(core::TimeUs delivered_us, const sdk::StereoFrame& frame) override {
    CameraFrame f;
    f.delivered_us = delivered_us;
    f.frame = frame;
    auto copy = [](const sdk::RgbImage& image, std::vector<uint8_t>& out) {
      out.assign(image.rgb, image.rgb + 3 * static_cast<size_t>(image.width_px) * image.height_px);
    };
    copy(frame.left, f.left);
    copy(frame.right, f.right);
    f.frame.left.rgb = f.frame.right.rgb = nullptr;
    pending_.camera.push_back(std::move(f));
  }
  void on_imu(core::TimeUs, const sdk::ImuSample& sample) override {
    pending_.imu.push_back(sample);
  }
  void on_wheels(core::TimeUs, const sdk::WheelSpeeds& sample) override {
    pending_.wheels.push_back(sample);
  }
  void on_steering(core::TimeUs, const sdk::SteeringSample& sample) override {
    pending_.steering.push_back(sample);
  }

  // moves what is delivered by `now` into `out` (emptied first)
  void take(core::TimeUs now, RawData& out) {
    auto move_due = [now](auto& from, auto& to) {
      to.clear();
      auto it = from.begin();
      for (; it != from.end() && it->delivered_us <= now; ++it) to.push_back(std::move(*it));
      from.erase(from.begin(), it);
    };
    move_due(pending_.lidar, out.lidar);
    move_due(pending_.camera, out.camera);
    // the car's own sensors are handed over as they are delivered
    out.imu = std::move(pending_.imu);
    out.wheels = std::move(pending_.wheels);
    out.steering = std::move(pending_.steering);
    pending_.imu.clear();
    pending_.wheels.clear();
    pending_.steering.clear();
  }

 private:
  RawData pending_;
};

// one driver tick as Python sees it (copied out of the run thread)
struct Tick {
  core::TimeUs t = 0;
  sdk::Pose2 pose;
  double speed_mps = 0.0;
  double yaw_rate_rps = 0.0;
  std::vector<sdk::ConeObservation> cones;
  std::vector<sdk::MapCone> map;
  bool map_complete = false;
  sim::RefereeResult referee;
  RawData raw;
};

// what the run thread and Python share: the latest tick, the command for it, the end
struct Channel {
  std::mutex mutex;
  std::condition_variable wake;
  Tick tick;
  bool tick_ready = false;
  std::optional<sdk::Command> command;
  bool closing = false;
  bool finished = false;
  sim::RefereeResult referee;
  nlohmann::json metrics;
  std::exception_ptr error;
  // the raw data asked for (observe=), null for none
  std::unique_ptr<RawDataTap> tap;
};

// the driver of a lock-step run: hands each tick to Python and waits for its command
class ChannelDriver final : public sdk::Driver {
 public:
  explicit ChannelDriver(std::shared_ptr<Channel> channel) : channel_(std::move(channel)) {}

  sdk::Command update(const sdk::DriverInput& in) override {
    std::unique_lock<std::mutex> lock(channel_->mutex);
    Tick& tick = channel_->tick;
    tick.t = in.now_us;
    tick.pose = in.estimate.pose;
    tick.speed_mps = in.estimate.speed_mps;
    tick.yaw_rate_rps = in.estimate.yaw_rate_rps;
    tick.cones.assign(in.observations.cones.begin(), in.observations.cones.end());
    tick.map.assign(in.estimate.map.begin(), in.estimate.map.end());
    tick.map_complete = in.estimate.map_complete != 0;
    tick.referee = channel_->referee;
    if (channel_->tap) channel_->tap->take(in.now_us, tick.raw);
    channel_->tick_ready = true;
    channel_->command.reset();
    channel_->wake.notify_all();
    channel_->wake.wait(lock, [this] { return channel_->command || channel_->closing; });
    if (!channel_->command)
      throw sim::PluginFailure("the Python driver closed the simulation before the end");
    const sdk::Command c = *channel_->command;
    if (!std::isfinite(c.steer_rad) || !std::isfinite(c.accel_mps2))
      throw sim::PluginFailure(std::string("the Python driver returned ") +
                               (std::isfinite(c.steer_rad)
                                    ? "a number that is not finite as accel_mps2"
                                    : "a number that is not finite as steer_rad"));
    return c;
  }

 private:
  std::shared_ptr<Channel> channel_;
};

py::dict referee_dict(const sim::RefereeResult& r) {
  py::dict d;
  d["completed"] = r.completed;
  d["dnf_reason"] = r.dnf_reason;
  d["laps"] = r.laps;
  d["lap_times_s"] = r.lap_times_s;
  d["cones_hit"] = r.cones_hit.size();
  d["cones_hit_ids"] = r.cones_hit;
  d["off_course"] = r.off_course;
  d["raw_time_s"] = r.raw_time_s;
  d["final_time_s"] = r.final_time_s;
  return d;
}

py::array_t<double> array_of(std::initializer_list<double> values) {
  py::array_t<double> a(static_cast<py::ssize_t>(values.size()));
  std::copy(values.begin(), values.end(), a.mutable_data());
  return a;
}

// a pose on the car: position (3,) and orientation as a unit quaternion w, x, y, z (4,)
py::dict pose3_dict(const sdk::Pose3& p) {
  py::dict d;
  d["position_m"] = array_of({p.position_m.x, p.position_m.y, p.position_m.z});
  d["quaternion_wxyz"] =
      array_of({p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z});
  return d;
}

py::dict lidar_dict(const LidarFrame& f) {
  py::dict d;
  d["stamp_s"] = core::to_seconds(f.sweep.stamp_us);
  d["end_s"] = core::to_seconds(f.sweep.end_us);
  d["delivered_s"] = core::to_seconds(f.delivered_us);
  // x, y, z, intensity, ring, time after the sweep's start: one row per return
  const auto n = static_cast<py::ssize_t>(f.points.size());
  py::array_t<float> points(std::vector<py::ssize_t>{n, 6});
  float* out = points.mutable_data();
  for (const sdk::LidarPoint& p : f.points) {
    *out++ = p.x_m, *out++ = p.y_m, *out++ = p.z_m, *out++ = p.intensity;
    *out++ = static_cast<float>(p.ring), *out++ = p.time_offset_s;
  }
  d["points"] = points;
  d["sensor_in_vehicle"] = pose3_dict(f.sweep.sensor_in_vehicle);
  if (f.has_labels) {
    py::array_t<int32_t> labels(n);
    std::copy(f.labels.begin(), f.labels.end(), labels.mutable_data());
    d["labels_truth"] = labels;
  }
  return d;
}

py::dict camera_dict(const CameraFrame& f) {
  const sdk::StereoFrame& s = f.frame;
  auto image = [](const sdk::RgbImage& size, const std::vector<uint8_t>& rgb) {
    py::array_t<uint8_t> a(std::vector<py::ssize_t>{size.height_px, size.width_px, 3});
    std::memcpy(a.mutable_data(), rgb.data(), rgb.size());
    return a;
  };
  py::dict d;
  d["stamp_s"] = core::to_seconds(s.stamp_us);
  d["delivered_s"] = core::to_seconds(f.delivered_us);
  d["left"] = image(s.left, f.left);
  d["right"] = image(s.right, f.right);
  const sdk::CameraIntrinsics& k = s.intrinsics;
  py::dict intrinsics;
  intrinsics["width_px"] = k.width_px;
  intrinsics["height_px"] = k.height_px;
  intrinsics["fx"] = k.fx;
  intrinsics["fy"] = k.fy;
  intrinsics["cx"] = k.cx;
  intrinsics["cy"] = k.cy;
  intrinsics["distortion"] =
      py::make_tuple(k.distortion[0], k.distortion[1], k.distortion[2], k.distortion[3],
                     k.distortion[4]);
  d["intrinsics"] = intrinsics;
  py::array_t<double> matrix(std::vector<py::ssize_t>{3, 3});
  const double values[9] = {k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0};
  std::copy(values, values + 9, matrix.mutable_data());
  d["K"] = matrix;
  d["baseline_m"] = s.baseline_m;
  d["left_in_vehicle"] = pose3_dict(s.left_in_vehicle);
  d["right_in_vehicle"] = pose3_dict(s.right_in_vehicle);
  return d;
}

// samples as arrays: t_s (K,) and each field (K, width)
template <typename Sample, typename Fill>
py::array_t<double> columns(const std::vector<Sample>& samples, py::ssize_t width, Fill fill) {
  py::array_t<double> a(width == 1 ? std::vector<py::ssize_t>{py::ssize_t(samples.size())}
                                   : std::vector<py::ssize_t>{py::ssize_t(samples.size()), width});
  double* out = a.mutable_data();
  for (const Sample& s : samples) out = fill(s, out);
  return a;
}

py::dict tick_dict(const Tick& tick, bool done, const sim::SensorTapKinds* kinds) {
  sdk::Estimate estimate;
  estimate.pose = tick.pose;
  estimate.speed_mps = tick.speed_mps;
  estimate.yaw_rate_rps = tick.yaw_rate_rps;
  estimate.map = {tick.map.data(), tick.map.size()};
  estimate.map_complete = tick.map_complete ? 1 : 0;
  py::dict d = python::observation(core::to_seconds(tick.t), estimate,
                                   {tick.t, {tick.cones.data(), tick.cones.size()}}, done);
  if (!kinds) return d;
  // the raw data delivered since the previous tick, of the kinds asked for
  const RawData& raw = tick.raw;
  auto stamps = [](const auto& samples) {
    return columns(samples, 1, [](const auto& s, double* out) {
      *out++ = core::to_seconds(s.stamp_us);
      return out;
    });
  };
  if (kinds->lidar) {
    py::list sweeps;
    for (const LidarFrame& f : raw.lidar) sweeps.append(lidar_dict(f));
    d["lidar"] = sweeps;
  }
  if (kinds->camera) {
    py::list frames;
    for (const CameraFrame& f : raw.camera) frames.append(camera_dict(f));
    d["camera"] = frames;
  }
  if (kinds->imu) {
    py::dict imu;
    imu["t_s"] = stamps(raw.imu);
    imu["gyro_rps"] = columns(raw.imu, 3, [](const sdk::ImuSample& s, double* out) {
      return std::copy(s.gyro_rps, s.gyro_rps + 3, out);
    });
    imu["accel_mps2"] = columns(raw.imu, 3, [](const sdk::ImuSample& s, double* out) {
      return std::copy(s.accel_mps2, s.accel_mps2 + 3, out);
    });
    d["imu"] = imu;
  }
  if (kinds->wheels) {
    py::dict wheels;
    wheels["t_s"] = stamps(raw.wheels);
    wheels["omega_rps"] = columns(raw.wheels, 4, [](const sdk::WheelSpeeds& s, double* out) {
      return std::copy(s.omega_rps, s.omega_rps + 4, out);
    });
    d["wheels"] = wheels;
  }
  if (kinds->steering) {
    py::dict steering;
    steering["t_s"] = stamps(raw.steering);
    steering["steer_rad"] = columns(raw.steering, 1, [](const sdk::SteeringSample& s, double* out) {
      *out++ = s.steer_rad;
      return out;
    });
    d["steering"] = steering;
  }
  // what in this observation is ground truth, which no car has
  py::list truth;
  if (kinds->lidar_labels) truth.append("lidar.labels_truth");
  d["ground_truth"] = truth;
  return d;
}

// the observe= argument: which raw data, checked
sim::SensorTapKinds read_observe(const std::vector<std::string>& observe, bool lidar_labels) {
  sim::SensorTapKinds kinds;
  for (const std::string& name : observe) {
    if (name == "lidar")
      kinds.lidar = true;
    else if (name == "camera")
      kinds.camera = true;
    else if (name == "imu")
      kinds.imu = true;
    else if (name == "wheels")
      kinds.wheels = true;
    else if (name == "steering")
      kinds.steering = true;
    else
      throw py::value_error("observe: expected lidar, camera, imu, wheels or steering, got '" +
                            name + "'");
  }
  if (lidar_labels && !kinds.lidar)
    throw py::value_error("lidar_labels: the LiDAR's labels need observe=[\"lidar\", ...]");
  kinds.lidar_labels = lidar_labels;
  return kinds;
}

// a --set value from a Python value: YAML text (lists and dicts as flow YAML)
std::string yaml_value(const py::handle& v) {
  if (py::isinstance<py::bool_>(v)) return v.cast<bool>() ? "true" : "false";
  if (py::isinstance<py::int_>(v) || py::isinstance<py::float_>(v))
    return py::str(py::repr(v)).cast<std::string>();
  if (py::isinstance<py::str>(v)) return v.cast<std::string>();
  if (py::isinstance<py::list>(v) || py::isinstance<py::tuple>(v)) {
    std::string out = "[";
    for (const py::handle& item : v) out += (out.size() > 1 ? ", " : "") + yaml_value(item);
    return out + "]";
  }
  if (py::isinstance<py::dict>(v)) {
    std::string out = "{";
    for (const auto& [k, item] : v.cast<py::dict>())
      out +=
          (out.size() > 1 ? ", " : "") + py::str(k).cast<std::string>() + ": " + yaml_value(item);
    return out + "}";
  }
  throw py::type_error("set: a value must be a number, bool, string, list or dict, got " +
                       py::str(py::type::of(v)).cast<std::string>());
}

class Sim {
 public:
  Sim(const std::string& scenario, std::optional<uint64_t> seed, const py::dict& set,
      const std::string& out, bool plot, const std::vector<std::string>& observe, bool lidar_labels)
      : channel_(std::make_shared<Channel>()) {
    const sim::SensorTapKinds kinds = read_observe(observe, lidar_labels);
    // the checks of `conesim run`, before anything is written
    std::vector<std::string> overrides;
    for (const auto& [key, value] : set)
      overrides.push_back(py::str(key).cast<std::string>() + "=" + yaml_value(value));
    sim::Scenario s;
    try {
      s = sim::load_scenario(sim::find_scenario(scenario), overrides, seed);
      track_ = sim::scenario_track(s);
      if (s.driver.check_drivable)
        if (const std::string why = sim::drivability_problem(s, track_); !why.empty())
          throw core::InputError(s.track.file ? s.track.file->string() : track_.name, 0,
                                 "not drivable by this car: " + why);
      if (s.slam_plugin || s.perception_plugin)
        sim::check_plugins(
            s, sim::make_run_info(s, sim::driver_vehicle(s.vehicle), track_.start, {})->info);
    } catch (const core::InputError& e) {
      throw py::value_error(e.what());
    }
    scenario_ = s;
    options_.plot = plot;
    options_.out_dir = out.empty() ? sim::make_run_dir("runs", s.name) : std::filesystem::path(out);
    run_dir_ = options_.out_dir.string();
    std::shared_ptr<Channel> channel = channel_;
    if (!observe.empty()) {
      channel->tap = std::make_unique<RawDataTap>(kinds);
      options_.sensor_tap = channel->tap.get();
    }
    options_.make_driver = [channel](const sdk::RunInfo&) {
      return std::make_unique<ChannelDriver>(channel);
    };
    options_.on_tick = [channel](core::TimeUs, const sim::RefereeResult& r) {
      std::lock_guard<std::mutex> lock(channel->mutex);
      channel->referee = r;
    };

    // the run on a thread of its own; Python drives it tick by tick
    thread_ = std::thread([this, channel] {
      try {
        const sim::RunResult r = sim::run_scenario(scenario_, track_, options_);
        std::lock_guard<std::mutex> lock(channel->mutex);
        channel->metrics = r.metrics;
        channel->referee = r.referee;
      } catch (...) {
        std::lock_guard<std::mutex> lock(channel->mutex);
        channel->error = std::current_exception();
      }
      std::lock_guard<std::mutex> lock(channel->mutex);
      channel->finished = true;
      channel->wake.notify_all();
    });
    wait_for_tick();
  }

  ~Sim() {
    try {
      close();
    } catch (...) {
      // an internal error of the run surfaces in close(); a destructor cannot raise it
    }
  }

  // applies the command to the current tick and returns the next tick's observation
  py::dict step(const py::object& command) {
    sdk::Command c;
    if (py::isinstance<py::dict>(command)) {
      const py::dict d = command.cast<py::dict>();
      c.steer_rad = d.contains("steer_rad") ? d["steer_rad"].cast<double>() : 0.0;
      c.accel_mps2 = d.contains("accel_mps2") ? d["accel_mps2"].cast<double>() : 0.0;
      c.hold_stopped = d.contains("hold_stopped") && d["hold_stopped"].cast<bool>() ? 1 : 0;
    } else {
      const py::sequence seq = command.cast<py::sequence>();
      if (seq.size() < 2 || seq.size() > 3)
        throw py::value_error("step: expected (steer_rad, accel_mps2[, hold_stopped]) or a dict");
      c.steer_rad = seq[0].cast<double>();
      c.accel_mps2 = seq[1].cast<double>();
      c.hold_stopped = seq.size() == 3 && seq[2].cast<bool>() ? 1 : 0;
    }
    {
      std::lock_guard<std::mutex> lock(channel_->mutex);
      if (channel_->finished) throw py::value_error("step: the run has ended (obs['done'])");
      channel_->tick_ready = false;
      channel_->command = c;
    }
    channel_->wake.notify_all();
    return wait_for_tick();
  }

  // the latest observation
  py::dict observation() {
    std::lock_guard<std::mutex> lock(channel_->mutex);
    return tick_dict(channel_->tick, channel_->finished,
                     channel_->tap ? &channel_->tap->kinds() : nullptr);
  }

  // the referee's verdict so far
  py::dict referee() {
    std::lock_guard<std::mutex> lock(channel_->mutex);
    return referee_dict(channel_->referee);
  }

  bool done() {
    std::lock_guard<std::mutex> lock(channel_->mutex);
    return channel_->finished;
  }

  // metrics.json of the finished run, as a dict
  py::object metrics() {
    std::lock_guard<std::mutex> lock(channel_->mutex);
    if (!channel_->finished)
      throw py::value_error("metrics: the run has not ended (step until obs['done'], or close())");
    return py::module_::import("json").attr("loads")(conesim::sim::json_text(channel_->metrics));
  }

  // ends the run (a DNF if it had not ended) and writes its folder
  void close() {
    if (!thread_.joinable()) return;
    {
      std::lock_guard<std::mutex> lock(channel_->mutex);
      channel_->closing = true;
    }
    channel_->wake.notify_all();
    {
      py::gil_scoped_release release;
      thread_.join();
    }
    if (channel_->error) std::rethrow_exception(channel_->error);
  }

  const std::string& run_dir() const { return run_dir_; }

 private:
  py::dict wait_for_tick() {
    {
      py::gil_scoped_release release;
      std::unique_lock<std::mutex> lock(channel_->mutex);
      channel_->wake.wait(lock, [this] { return channel_->tick_ready || channel_->finished; });
    }
    if (channel_->finished) {
      close();
    }
    return observation();
  }

  std::shared_ptr<Channel> channel_;
  sim::Scenario scenario_;
  tracks::Track track_;
  sim::RunOptions options_;
  std::string run_dir_;
  std::thread thread_;
};

}  // namespace

PYBIND11_MODULE(conesim, m) {
  m.doc() = "conesim: a Formula Student Driverless simulator run in lock-step from Python";
  m.attr("BLUE") = static_cast<int>(sdk::ConeClass::kBlue);
  m.attr("YELLOW") = static_cast<int>(sdk::ConeClass::kYellow);
  m.attr("ORANGE_SMALL") = static_cast<int>(sdk::ConeClass::kOrangeSmall);
  m.attr("ORANGE_BIG") = static_cast<int>(sdk::ConeClass::kOrangeBig);
  m.attr("UNKNOWN") = static_cast<int>(sdk::ConeClass::kUnknown);
  m.attr("SDK_VERSION") = sdk::kSdkVersion;
  py::class_<Sim>(m, "Sim",
                  "A scenario run with this Python program as its driver, tick by tick (the "
                  "scenario's driver rate). Raises ValueError for bad input, as `conesim run` "
                  "exits 2.")
      .def(py::init<const std::string&, std::optional<uint64_t>, const py::dict&,
                    const std::string&, bool, const std::vector<std::string>&, bool>(),
           py::arg("scenario"), py::arg("seed") = py::none(), py::arg("set") = py::dict(),
           py::arg("out") = "", py::arg("plot") = false,
           py::arg("observe") = std::vector<std::string>{}, py::arg("lidar_labels") = false,
           "scenario: a shipped scenario's name or a file; seed: as --seed; set: {key.path: "
           "value} as --set; out: the run folder (default runs/<name>-<stamp>); plot: draw the "
           "pictures; observe: raw sensor data in each observation, any of lidar, camera, imu, "
           "wheels, steering (asking for the LiDAR or the camera switches it on); lidar_labels: "
           "the true cone id of each LiDAR point as 'labels_truth' (ground truth)")
      .def("step", &Sim::step, py::arg("command"),
           "Applies (steer_rad, accel_mps2[, hold_stopped]) (or a dict of those keys) from the "
           "current driver tick to the next and returns the next tick's observation")
      .def_property_readonly("observation", &Sim::observation,
                             "The current tick's observation: t_s, pose [x, y, yaw] (the "
                             "estimate), speed_mps, yaw_rate_rps, cones (N x 2, vehicle frame), "
                             "cone_classes, map (M x 2), map_classes, map_complete, done; with "
                             "observe=, the raw data delivered since the previous tick (lidar, "
                             "camera, imu, wheels, steering) and ground_truth (docs/sdk.md)")
      .def_property_readonly("referee", &Sim::referee, "The referee's verdict so far")
      .def_property_readonly("done", &Sim::done, "True once the referee has ruled")
      .def_property_readonly("run_dir", &Sim::run_dir, "The run folder")
      .def("metrics", &Sim::metrics, "metrics.json of the ended run, as a dict")
      .def("close", &Sim::close,
           "Ends the run (a DNF 'closed by the Python driver' if the referee had not ruled) and "
           "writes its folder");
}
