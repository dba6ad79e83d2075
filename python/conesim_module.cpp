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

#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cmath>
#include <condition_variable>
#include <exception>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "core/error.hpp"
#include "python/observation.hpp"
#include "sim/autonomy.hpp"
#include "sim/regress.hpp"
#include "sim/run.hpp"
#include "sim/scenario.hpp"

namespace py = pybind11;
using namespace conesim;

namespace {

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

py::dict tick_dict(const Tick& tick, bool done) {
  sdk::Estimate estimate;
  estimate.pose = tick.pose;
  estimate.speed_mps = tick.speed_mps;
  estimate.yaw_rate_rps = tick.yaw_rate_rps;
  estimate.map = {tick.map.data(), tick.map.size()};
  estimate.map_complete = tick.map_complete ? 1 : 0;
  return python::observation(core::to_seconds(tick.t), estimate,
                             {tick.t, {tick.cones.data(), tick.cones.size()}}, done);
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
      const std::string& out, bool plot)
      : channel_(std::make_shared<Channel>()) {
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
    return tick_dict(channel_->tick, channel_->finished);
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
    return py::module_::import("json").attr("loads")(channel_->metrics.dump());
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
                    const std::string&, bool>(),
           py::arg("scenario"), py::arg("seed") = py::none(), py::arg("set") = py::dict(),
           py::arg("out") = "", py::arg("plot") = false,
           "scenario: a shipped scenario's name or a file; seed: as --seed; set: {key.path: "
           "value} as --set; out: the run folder (default runs/<name>-<stamp>); plot: draw the "
           "pictures")
      .def("step", &Sim::step, py::arg("command"),
           "Applies (steer_rad, accel_mps2[, hold_stopped]) (or a dict of those keys) from the "
           "current driver tick to the next and returns the next tick's observation")
      .def_property_readonly("observation", &Sim::observation,
                             "The current tick's observation: t_s, pose [x, y, yaw] (the "
                             "estimate), speed_mps, yaw_rate_rps, cones (N x 2, vehicle frame), "
                             "cone_classes, map (M x 2), map_classes, map_complete, done")
      .def_property_readonly("referee", &Sim::referee, "The referee's verdict so far")
      .def_property_readonly("done", &Sim::done, "True once the referee has ruled")
      .def_property_readonly("run_dir", &Sim::run_dir, "The run folder")
      .def("metrics", &Sim::metrics, "metrics.json of the ended run, as a dict")
      .def("close", &Sim::close,
           "Ends the run (a DNF 'closed by the Python driver' if the referee had not ruled) and "
           "writes its folder");
}
