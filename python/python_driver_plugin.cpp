// A Python class as the driver of a `conesim run`: a plug-in that embeds Debian's Python and
// calls the class each driver tick (docs/sdk.md, "Python").
//
//   autonomy:
//     driver:
//       plugin: build/python/libconesim_python_driver.so
//       config: {file: examples/python_driver.py, class: PurePursuit, options: {...}}
//
// The class is made with (run, options): `run` a dict of the RunInfo (event, seed, start_pose,
// vehicle, driver_rate_hz, trackdrive_laps), `options` the config's `options` block as a dict
// of strings; its update(obs) gets the observation dict conesim.Sim gives and returns
// (steer_rad, accel_mps2[, hold_stopped]). In the file, `import conesim` gives the class
// constants (BLUE, YELLOW, ...). A Python exception ends the run with a DNF naming the
// plug-in and the exception.

#include <dlfcn.h>
#include <pybind11/embed.h>

#include <conesim/sdk.hpp>
#include <mutex>
#include <stdexcept>
#include <string>

#include "python/observation.hpp"

namespace py = pybind11;
using namespace conesim;

// the constants a driver file imports as `conesim` inside a run
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
    py::initialize_interpreter();
    PyEval_SaveThread();
  });
}

// a Python exception as a std::runtime_error with its type and message
[[noreturn]] void rethrow(const py::error_already_set& e) {
  throw std::runtime_error(std::string("Python: ") + e.what());
}

class PythonDriver final : public sdk::Driver {
 public:
  PythonDriver(const sdk::RunInfo& run, const sdk::Config& config) {
    static const char* const kKnown[] = {"file", "class", "options", nullptr};
    config.require_known(kKnown);
    const std::string file = config.text("file", "");
    const std::string cls = config.text("class", "Driver");
    if (file.empty()) throw std::invalid_argument("file: expected the Python file of the driver");
    start_python();
    py::gil_scoped_acquire gil;
    try {
      // `import conesim` in the file gives the constants
      py::module_::import("sys").attr("modules")["conesim"] = py::module_::import("conesim_run");
      py::module_ util = py::module_::import("importlib.util");
      py::object spec = util.attr("spec_from_file_location")("conesim_user_driver", file);
      if (spec.is_none()) throw std::invalid_argument("file: cannot load '" + file + "'");
      py::object module = util.attr("module_from_spec")(spec);
      spec.attr("loader").attr("exec_module")(module);
      if (!py::hasattr(module, cls.c_str()))
        throw std::invalid_argument("class: '" + file + "' has no class " + cls);
      py::dict info;
      info["event"] = static_cast<int>(run.event);
      info["seed"] = run.seed;
      py::array_t<double> start(3);
      start.mutable_at(0) = run.start_pose.x_m;
      start.mutable_at(1) = run.start_pose.y_m;
      start.mutable_at(2) = run.start_pose.yaw_rad;
      info["start_pose"] = start;
      info["wheelbase_m"] = run.vehicle.wheelbase_m;
      info["max_steer_rad"] = run.vehicle.max_steer_rad;
      info["driver_rate_hz"] = run.driver_rate_hz;
      info["trackdrive_laps"] = run.trackdrive_laps;
      py::dict options;
      for (const sdk::ConfigEntry& e : config.entries()) {
        const std::string key = e.key;
        if (key.starts_with("options.")) options[py::str(key.substr(8))] = e.value;
      }
      driver_ = module.attr(cls.c_str())(info, options);
    } catch (const py::error_already_set& e) {
      throw std::invalid_argument(std::string("the class failed to load: ") + e.what());
    }
  }

  ~PythonDriver() override {
    py::gil_scoped_acquire gil;
    driver_ = py::object();
  }

  sdk::Command update(const sdk::DriverInput& in) override {
    py::gil_scoped_acquire gil;
    try {
      const py::object result = driver_.attr("update")(python::observation(
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
  py::object driver_;
};

}  // namespace

CONESIM_PLUGIN_DRIVER("python", PythonDriver)
