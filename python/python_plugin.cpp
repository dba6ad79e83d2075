// A Python class as the driver or the SLAM of a `conesim run`: a plug-in that embeds Debian's
// Python and calls the class through the SDK's interfaces (docs/sdk.md, "Python").
//
//   autonomy:
//     driver:
//       plugin: build/python/libconesim_python_plugin.so
//       config: {file: examples/python_driver.py, class: PurePursuit, options: {...}}
//     slam:
//       plugin: build/python/libconesim_python_plugin.so
//       config: {file: examples/python_slam.py, class: NearestNeighbourSlam}
//
// Either class is made with (run, options): `run` a dict of the RunInfo (event, seed,
// start_pose, wheelbase_m, max_steer_rad, driver_rate_hz, trackdrive_laps), `options` the
// config's `options` block as a dict of strings.
// - A driver's update(obs) gets the observation dict conesim.Sim gives and returns
//   (steer_rad, accel_mps2[, hold_stopped]).
// - A SLAM's reset(start_pose, t_s, prior_map), process(inp) and estimate() have the meaning
//   of sdk::Slam's (inp: the odometry since the previous frame and the frame's cones; the
//   estimate: a dict with pose and map); associations(), new_landmark_ids() and
//   loop_closures() are optional.
// In the file, `import conesim` gives the class constants (BLUE, YELLOW, ...). A Python
// exception ends the run with a DNF naming the plug-in and the exception.

#include <dlfcn.h>
#include <pybind11/embed.h>
#include <pybind11/stl.h>

#include <conesim/sdk.hpp>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "python/observation.hpp"

namespace py = pybind11;
using namespace conesim;

// the constants a class's file imports as `conesim` inside a run
PYBIND11_EMBEDDED_MODULE(conesim_run, m) {
  m.attr("BLUE") = static_cast<int>(sdk::ConeClass::kBlue);
  m.attr("YELLOW") = static_cast<int>(sdk::ConeClass::kYellow);
  m.attr("ORANGE_SMALL") = static_cast<int>(sdk::ConeClass::kOrangeSmall);
  m.attr("ORANGE_BIG") = static_cast<int>(sdk::ConeClass::kOrangeBig);
  m.attr("UNKNOWN") = static_cast<int>(sdk::ConeClass::kUnknown);
}

namespace {

// starts the interpreter once per process; the GIL is released between calls (each call takes
// it, from whichever thread conesim calls on)
void start_python() {
  static std::once_flag once;
  std::call_once(once, [] {
    // NumPy's extension modules need libpython's symbols global (conesim loads this plug-in
    // with RTLD_LOCAL)
    Dl_info where{};
    if (dladdr(reinterpret_cast<void*>(&Py_IsInitialized), &where) && where.dli_fname)
      dlopen(where.dli_fname, RTLD_NOW | RTLD_GLOBAL | RTLD_NOLOAD);
    // the interpreter is never finalized and keeps this library's embedded module and
    // pybind11's state (held by this library's globals): the library stays loaded for the
    // process, also after conesim closes the plug-in (LeakSanitizer found that state lost)
    Dl_info self{};
    if (dladdr(reinterpret_cast<void*>(&start_python), &self) && self.dli_fname)
      dlopen(self.dli_fname, RTLD_NOW | RTLD_NODELETE | RTLD_NOLOAD);
    py::initialize_interpreter();
    PyEval_SaveThread();
  });
}

// a Python exception as a std::runtime_error with its type and message
[[noreturn]] void rethrow(const py::error_already_set& e) {
  throw std::runtime_error(std::string("Python: ") + e.what());
}

py::array_t<double> pose_array(const sdk::Pose2& p) {
  py::array_t<double> a(3);
  a.mutable_at(0) = p.x_m;
  a.mutable_at(1) = p.y_m;
  a.mutable_at(2) = p.yaw_rad;
  return a;
}

// the class named by the config (file, class, options), made with (run, options); the caller
// holds the GIL
py::object make_class(const sdk::RunInfo& run, const sdk::Config& config,
                      const char* default_class) {
  static const char* const kKnown[] = {"file", "class", "options", nullptr};
  config.require_known(kKnown);
  const std::string file = config.text("file", "");
  const std::string cls = config.text("class", default_class);
  if (file.empty()) throw std::invalid_argument("file: expected the Python file of the class");
  try {
    // `import conesim` in the file gives the constants
    py::module_::import("sys").attr("modules")["conesim"] = py::module_::import("conesim_run");
    py::module_ util = py::module_::import("importlib.util");
    py::object spec = util.attr("spec_from_file_location")("conesim_user_" + cls, file);
    if (spec.is_none()) throw std::invalid_argument("file: cannot load '" + file + "'");
    py::object module = util.attr("module_from_spec")(spec);
    spec.attr("loader").attr("exec_module")(module);
    if (!py::hasattr(module, cls.c_str()))
      throw std::invalid_argument("class: '" + file + "' has no class " + cls);
    py::dict info;
    info["event"] = static_cast<int>(run.event);
    info["seed"] = run.seed;
    info["start_pose"] = pose_array(run.start_pose);
    info["wheelbase_m"] = run.vehicle.wheelbase_m;
    info["max_steer_rad"] = run.vehicle.max_steer_rad;
    info["driver_rate_hz"] = run.driver_rate_hz;
    info["trackdrive_laps"] = run.trackdrive_laps;
    py::dict options;
    for (const sdk::ConfigEntry& e : config.entries()) {
      const std::string key = e.key;
      if (key.starts_with("options.")) options[py::str(key.substr(8))] = e.value;
    }
    return module.attr(cls.c_str())(info, options);
  } catch (const py::error_already_set& e) {
    throw std::invalid_argument(std::string("the class failed to load: ") + e.what());
  }
}

// a Python object dropped with the GIL held
struct PythonObject {
  py::object object;
  ~PythonObject() {
    py::gil_scoped_acquire gil;
    object = py::object();
  }
};

class PythonDriver final : public sdk::Driver {
 public:
  PythonDriver(const sdk::RunInfo& run, const sdk::Config& config) {
    start_python();
    py::gil_scoped_acquire gil;
    driver_.object = make_class(run, config, "Driver");
  }

  sdk::Command update(const sdk::DriverInput& in) override {
    py::gil_scoped_acquire gil;
    try {
      const py::object result = driver_.object.attr("update")(python::observation(
          1e-6 * static_cast<double>(in.now_us), in.estimate, in.observations, false));
      const py::sequence seq = result.cast<py::sequence>();
      if (seq.size() < 2 || seq.size() > 3)
        throw std::runtime_error("update returned " + std::to_string(seq.size()) +
                                 " values, expected (steer_rad, accel_mps2[, hold_stopped])");
      sdk::Command c;
      c.steer_rad = seq[0].cast<double>();
      c.accel_mps2 = seq[1].cast<double>();
      c.hold_stopped = seq.size() == 3 && seq[2].cast<bool>() ? 1 : 0;
      return c;
    } catch (const py::error_already_set& e) {
      rethrow(e);
    } catch (const py::cast_error& e) {
      throw std::runtime_error(std::string("update's result: ") + e.what());
    }
  }

 private:
  PythonObject driver_;
};

// a map as arrays: map (M x 2), map_classes (M,), map_ids (M,)
py::dict map_dict(sdk::Span<sdk::MapCone> map) {
  py::array_t<double> xy(std::vector<py::ssize_t>{static_cast<py::ssize_t>(map.size), 2});
  py::array_t<int32_t> classes(static_cast<py::ssize_t>(map.size));
  py::array_t<int32_t> ids(static_cast<py::ssize_t>(map.size));
  for (uint64_t i = 0; i < map.size; ++i) {
    xy.mutable_at(i, 0) = map[i].x_m;
    xy.mutable_at(i, 1) = map[i].y_m;
    classes.mutable_at(i) = static_cast<int32_t>(map[i].cls);
    ids.mutable_at(i) = map[i].id;
  }
  py::dict d;
  d["map"] = xy;
  d["map_classes"] = classes;
  d["map_ids"] = ids;
  return d;
}

class PythonSlam final : public sdk::Slam {
 public:
  PythonSlam(const sdk::RunInfo& run, const sdk::Config& config) {
    start_python();
    py::gil_scoped_acquire gil;
    slam_.object = make_class(run, config, "Slam");
    for (const char* method : {"reset", "process", "estimate"})
      if (!py::hasattr(slam_.object, method))
        throw std::invalid_argument(std::string("class: has no method ") + method +
                                    " (a SLAM class has reset, process and estimate)");
  }

  void reset(const sdk::Pose2& start, sdk::TimeUs stamp_us,
             sdk::Span<sdk::MapCone> prior_map) override {
    py::gil_scoped_acquire gil;
    try {
      slam_.object.attr("reset")(pose_array(start), 1e-6 * static_cast<double>(stamp_us),
                                 map_dict(prior_map));
    } catch (const py::error_already_set& e) {
      rethrow(e);
    }
    stamp_us_ = stamp_us;
  }

  void process(const sdk::SlamInput& in) override {
    py::gil_scoped_acquire gil;
    // the odometry since the previous frame and the frame's cones, as arrays
    const sdk::OdometryDelta& o = in.odometry;
    py::dict odometry;
    odometry["from_s"] = 1e-6 * static_cast<double>(o.from_us);
    odometry["to_s"] = 1e-6 * static_cast<double>(o.to_us);
    odometry["delta"] = pose_array(o.delta);
    py::array_t<double> covariance(std::vector<py::ssize_t>{3, 3});
    std::copy(o.covariance, o.covariance + 9, covariance.mutable_data());
    odometry["covariance"] = covariance;
    odometry["distance_m"] = o.distance_m;
    odometry["speed_mps"] = o.speed_mps;
    odometry["yaw_rate_rps"] = o.yaw_rate_rps;
    const sdk::Span<sdk::ConeObservation> cones = in.observations.cones;
    const auto n = static_cast<py::ssize_t>(cones.size);
    py::array_t<double> xy(std::vector<py::ssize_t>{n, 2});
    py::array_t<double> cov(std::vector<py::ssize_t>{n, 2, 2});
    py::array_t<int32_t> classes(n), tracks(n);
    for (py::ssize_t i = 0; i < n; ++i) {
      const sdk::ConeObservation& c = cones[static_cast<uint64_t>(i)];
      xy.mutable_at(i, 0) = c.x_m;
      xy.mutable_at(i, 1) = c.y_m;
      cov.mutable_at(i, 0, 0) = c.covariance.xx;
      cov.mutable_at(i, 0, 1) = c.covariance.xy;
      cov.mutable_at(i, 1, 0) = c.covariance.yx;
      cov.mutable_at(i, 1, 1) = c.covariance.yy;
      classes.mutable_at(i) = static_cast<int32_t>(c.cls);
      tracks.mutable_at(i) = c.track_id;
    }
    py::dict inp;
    inp["t_s"] = 1e-6 * static_cast<double>(o.to_us);
    inp["odometry"] = odometry;
    inp["cones"] = xy;
    inp["cone_classes"] = classes;
    inp["cone_covariances"] = cov;
    inp["track_ids"] = tracks;
    try {
      slam_.object.attr("process")(inp);
      // what it did with each observation, when it says
      associations_.clear();
      started_.clear();
      if (py::hasattr(slam_.object, "associations"))
        for (const py::handle& code : slam_.object.attr("associations")())
          associations_.push_back(code.cast<int32_t>());
      if (py::hasattr(slam_.object, "new_landmark_ids"))
        for (const py::handle& id : slam_.object.attr("new_landmark_ids")())
          started_.push_back(id.cast<int32_t>());
    } catch (const py::error_already_set& e) {
      rethrow(e);
    } catch (const py::cast_error& e) {
      throw std::runtime_error(std::string("associations' result: ") + e.what());
    }
    stamp_us_ = o.to_us;
    speed_mps_ = o.speed_mps;
    yaw_rate_rps_ = o.yaw_rate_rps;
  }

  sdk::Estimate estimate() const override {
    py::gil_scoped_acquire gil;
    sdk::Estimate e;
    e.stamp_us = stamp_us_;
    e.speed_mps = speed_mps_;
    e.yaw_rate_rps = yaw_rate_rps_;
    map_.clear();
    try {
      const py::dict d = slam_.object.attr("estimate")().cast<py::dict>();
      const auto pose = d["pose"].cast<std::vector<double>>();
      if (pose.size() != 3)
        throw std::runtime_error("estimate()['pose']: expected [x, y, yaw], got " +
                                 std::to_string(pose.size()) + " numbers");
      e.pose = {pose[0], pose[1], pose[2]};
      if (d.contains("map")) {
        const auto xy = d["map"].cast<std::vector<std::vector<double>>>();
        std::vector<int32_t> classes(xy.size(), static_cast<int32_t>(sdk::ConeClass::kUnknown));
        std::vector<int32_t> ids(xy.size());
        for (size_t i = 0; i < ids.size(); ++i) ids[i] = static_cast<int32_t>(i);
        if (d.contains("map_classes")) classes = d["map_classes"].cast<std::vector<int32_t>>();
        if (d.contains("map_ids")) ids = d["map_ids"].cast<std::vector<int32_t>>();
        if (classes.size() != xy.size() || ids.size() != xy.size())
          throw std::runtime_error("estimate(): map, map_classes and map_ids differ in length");
        for (size_t i = 0; i < xy.size(); ++i) {
          if (xy[i].size() != 2)
            throw std::runtime_error("estimate()['map']: expected rows of [x, y]");
          sdk::MapCone c;
          c.id = ids[i];
          c.cls = static_cast<sdk::ConeClass>(classes[i]);
          c.x_m = xy[i][0];
          c.y_m = xy[i][1];
          map_.push_back(c);
        }
      }
      if (d.contains("map_complete")) e.map_complete = d["map_complete"].cast<bool>() ? 1 : 0;
      if (d.contains("localising") && d["localising"].cast<bool>())
        e.phase = sdk::SlamPhase::kLocalisation;
    } catch (const py::error_already_set& err) {
      rethrow(err);
    } catch (const py::cast_error& err) {
      throw std::runtime_error(std::string("estimate()'s result: ") + err.what());
    }
    e.map = {map_.data(), map_.size()};
    return e;
  }

  sdk::Span<int32_t> associations() const override {
    return {associations_.data(), associations_.size()};
  }

  sdk::Span<int32_t> new_landmark_ids() const override {
    return {started_.data(), started_.size()};
  }

  int32_t loop_closures() const override {
    py::gil_scoped_acquire gil;
    if (!py::hasattr(slam_.object, "loop_closures")) return 0;
    try {
      return slam_.object.attr("loop_closures")().cast<int32_t>();
    } catch (const py::error_already_set& e) {
      rethrow(e);
    } catch (const py::cast_error& e) {
      throw std::runtime_error(std::string("loop_closures' result: ") + e.what());
    }
  }

 private:
  PythonObject slam_;
  sdk::TimeUs stamp_us_ = 0;
  double speed_mps_ = 0.0;
  double yaw_rate_rps_ = 0.0;
  std::vector<int32_t> associations_;
  std::vector<int32_t> started_;
  mutable std::vector<sdk::MapCone> map_;
};

}  // namespace

CONESIM_PLUGIN("python", void, PythonSlam, PythonDriver)
