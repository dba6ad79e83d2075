#pragma once
// The autonomy behind the SDK's interfaces (sdk/include/conesim/sdk): plug-in libraries and
// their loading, the conversions between conesim's core types and the SDK's plain structs, the
// reference driver as an sdk::Driver, and a plug-in Slam as a SLAM lane's back-end. The run
// loop drives every driver, built-in or plug-in, through sdk::Driver.

#include <chrono>
#include <exception>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <type_traits>
#include <utility>
#include <vector>

#include "conesim/sdk/plugin.hpp"
#include "control/driver.hpp"
#include "core/autonomy_types.hpp"
#include "sdk/builtin/bridge.hpp"
#include "sdk/builtin/slam_bridge.hpp"
#include "slam/backend.hpp"

namespace conesim::sim {

struct Scenario;

/// A plug-in's failure in the loop (it threw, returned NaN or overran its time budget): the run
/// ends with a DNF whose reason is what().
class PluginFailure : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// An opened plug-in library (dlopen), checked: it has the entry point and was built against
/// this conesim's SDK ABI. Closed when the last holder lets go.
class PluginLibrary {
 public:
  /// Opens and checks the library. Throws std::runtime_error with what went wrong (no such
  /// file, not loadable, no entry point, another SDK ABI, a name that is not a plain word).
  static std::shared_ptr<const PluginLibrary> open(const std::filesystem::path& file);
  ~PluginLibrary();
  PluginLibrary(const PluginLibrary&) = delete;
  PluginLibrary& operator=(const PluginLibrary&) = delete;

  const sdk::PluginInfo& info() const { return *info_; }
  const std::filesystem::path& file() const { return file_; }

 private:
  PluginLibrary() = default;
  void* handle_ = nullptr;
  const sdk::PluginInfo* info_ = nullptr;
  std::filesystem::path file_;
};

/// Which interface a plug-in fills.
enum class PluginKind { kPerception, kSlam, kDriver };

/// "perception", "slam", "driver".
const char* to_string(PluginKind kind);

/// A plug-in a scenario chose (`autonomy: {driver: {plugin: PATH, config: {...}}}`).
struct PluginSpec {
  PluginKind kind = PluginKind::kDriver;
  std::filesystem::path file;
  /// The `config:` block flattened ("a.b" -> "1.5"), and as YAML text.
  std::vector<std::pair<std::string, std::string>> config;
  std::string config_yaml = "{}";
  /// The longest one call may take, wall milliseconds; over it the run ends with a DNF.
  double time_budget_ms = 1000.0;
  /// Perception only: the sensors it is given.
  bool lidar = true;
  bool camera = false;
  std::shared_ptr<const PluginLibrary> library;

  /// The plug-in's name (its PluginInfo::name).
  std::string name() const { return library ? library->info().name : file.stem().string(); }
  /// How messages name it: "driver plug-in 'follow_gap' (examples/.../libfollow_gap.so)".
  std::string label() const;
};

/// What the driver knows of the car: its geometry and its envelope at full measured grip (the
/// yaw gain table measured in MuJoCo for any car but the default one).
control::VehicleGeometry driver_vehicle(const vehicle_models::VehicleParams& vp);

/// What every plug-in is told about the run, with the storage its views point into.
struct RunInfoStorage {
  sdk::RunInfo info;
  std::vector<sdk::YawGain> yaw_gain;
  std::vector<sdk::MapCone> prior_map;
  std::string scenario_file;
};

/// The run as plug-ins see it (vehicle: what the driver knows of the car).
std::unique_ptr<RunInfoStorage> make_run_info(const Scenario& s,
                                              const control::VehicleGeometry& vehicle,
                                              const core::Pose2& start,
                                              const std::vector<core::MapCone>& prior_map);

// the conversions to and from the SDK's types (sdk/builtin/bridge.hpp)
using sdk_bridge::from_sdk;
using sdk_bridge::to_sdk;

/// conesim's reference driver (control::Driver) behind the SDK's Driver interface.
class ReferenceDriver final : public sdk::Driver {
 public:
  ReferenceDriver(core::EventType event, const control::DriverParams& params,
                  const control::VehicleGeometry& vehicle, std::vector<core::MapCone> prior_map);
  sdk::Command update(const sdk::DriverInput& input) override;
  sdk::DriverStatus status() const override;

 private:
  control::Driver driver_;
};

/// An instance made by a plug-in: the object, then the library it came from (so the library
/// is closed after the object is gone).
template <typename T>
struct PluginInstance {
  std::shared_ptr<const PluginLibrary> library;
  std::unique_ptr<T> object;
};

/// Makes the plug-in's object of its kind with its configuration. Throws core::InputError
/// naming the scenario key (its factory refused the configuration, or it offers no such kind).
PluginInstance<sdk::Driver> make_plugin_driver(const PluginSpec& spec, const sdk::RunInfo& run);
PluginInstance<sdk::Slam> make_plugin_slam(const PluginSpec& spec, const sdk::RunInfo& run);
PluginInstance<sdk::Perception> make_plugin_perception(const PluginSpec& spec,
                                                       const sdk::RunInfo& run);

/// Makes each plug-in of the scenario once and lets it go: a factory that refuses its
/// configuration stops the run before anything is written. Throws core::InputError.
void check_plugins(const Scenario& s, const sdk::RunInfo& run);

/// A thread of its own for a plug-in's calls: the caller waits for each call up to the time
/// budget, and a call that does not return by then is left behind, still running (a plug-in's
/// code cannot be stopped from outside), with the thread.
class PluginCallThread {
 public:
  PluginCallThread();
  /// Stops the thread; one left behind is detached instead.
  ~PluginCallThread();
  PluginCallThread(const PluginCallThread&) = delete;
  PluginCallThread& operator=(const PluginCallThread&) = delete;

  /// Runs the job on the thread and waits for it at most timeout_ms; false when it did not
  /// return by then (the thread is then left behind, and every later run() is refused).
  bool run(std::function<void()> job, double timeout_ms);
  /// True once a call did not return within its time.
  bool abandoned() const;

 private:
  struct State;
  std::shared_ptr<State> state_;
  std::thread thread_;
};

/// What ends a run whose plug-in call never returns, for a command that owns its process
/// (`conesim run`): called on a watchdog's thread with the reason while the call is still
/// stuck; it must not return (it marks the run's folder and ends the process).
using PluginHangHandler = void (*)(const std::string& reason);

/// Sets the handler for the guards made from now on; nullptr (the default, and what a library
/// user such as the Python module keeps) makes each guard call its plug-in on a thread of its
/// own instead. Call it before the run starts.
void set_plugin_hang_handler(PluginHangHandler handler);

/// Watches the calls a guard makes on the caller's own thread: a few times a budget it looks
/// at the call under way, and one still running at twice the budget is a hang, handed to the
/// hang handler.
class PluginWatchdog {
 public:
  PluginWatchdog(std::string label, double budget_ms, PluginHangHandler handler);
  ~PluginWatchdog();
  PluginWatchdog(const PluginWatchdog&) = delete;
  PluginWatchdog& operator=(const PluginWatchdog&) = delete;

  /// A call named `what` (a string literal) starts now, on the caller's thread.
  std::chrono::steady_clock::time_point begin(const char* what);
  /// The call under way returned (or threw).
  void end();

 private:
  struct State;
  std::shared_ptr<State> state_;
  std::thread thread_;
};

/// Runs a plug-in's calls within its time budget and turns what it throws into PluginFailure.
/// With a hang handler set (set_plugin_hang_handler) the calls run on the caller's thread
/// under a PluginWatchdog: no hand-off between threads, which cost about 170 microseconds a
/// call where the cores sit idle between calls; a call that returns after its budget ends the
/// run with a DNF, one that never returns ends the process through the handler. Without one,
/// each call runs on a PluginCallThread, and a call that never returns is left behind there
/// while the run ends with its DNF.
class PluginGuard {
 public:
  explicit PluginGuard(const PluginSpec& spec);
  /// Runs f(); raises PluginFailure naming the plug-in and `what` ("update", a string literal)
  /// when it throws or does not return within the budget.
  template <typename F>
  auto call(const char* what, F&& f) const {
    using Result = decltype(f());
    if (watchdog_) {
      // on this thread, watched; one call at a time, whichever thread makes it (a plug-in's
      // object need not be thread-safe)
      std::lock_guard<std::mutex> one_call(*call_mutex_);
      const auto started = watchdog_->begin(what);
      if constexpr (std::is_void_v<Result>) {
        try {
          f();
        } catch (...) {
          watchdog_->end();
          rethrow_as_failure(what, std::current_exception());
        }
        watchdog_->end();
        check_returned_in_time(what, started);
      } else {
        std::optional<Result> result;
        try {
          result.emplace(f());
        } catch (...) {
          watchdog_->end();
          rethrow_as_failure(what, std::current_exception());
        }
        watchdog_->end();
        check_returned_in_time(what, started);
        return std::move(*result);
      }
    } else if constexpr (std::is_void_v<Result>) {
      // on the call thread; the result lives beside the call, not in this frame: a call left
      // behind that returns later writes it there
      run(what, [fn = &f] { (*fn)(); });
    } else {
      auto result = std::make_shared<std::optional<Result>>();
      run(what, [fn = &f, result] { *result = (*fn)(); });
      return std::move(**result);
    }
  }
  /// Raises PluginFailure for a number that is not finite in the output `what`.
  void check_finite(const char* what, double value) const;
  const std::string& label() const { return label_; }
  /// True once a call did not return within the budget on the call thread: the plug-in's
  /// object and library must then never be destroyed (its code may still be running).
  bool abandoned() const { return thread_ && thread_->abandoned(); }

 private:
  void run(const char* what, std::function<void()> job) const;
  [[noreturn]] void rethrow_as_failure(const char* what, std::exception_ptr error) const;
  void check_returned_in_time(const char* what,
                              std::chrono::steady_clock::time_point started) const;
  std::string label_;
  double budget_ms_;
  std::unique_ptr<PluginCallThread> thread_;
  std::unique_ptr<PluginWatchdog> watchdog_;
  std::unique_ptr<std::mutex> call_mutex_ = std::make_unique<std::mutex>();
};

/// Keeps a plug-in's object and library for good when a call of it was left running.
template <typename T>
void keep_if_abandoned(const PluginGuard& guard, PluginInstance<T>& instance) {
  if (!guard.abandoned()) return;
  (void)instance.object.release();
  (void)new std::shared_ptr<const PluginLibrary>(instance.library);
}

/// A driver plug-in under its guard: exceptions, NaN commands and overruns become
/// PluginFailure.
class GuardedDriver final : public sdk::Driver {
 public:
  GuardedDriver(const PluginSpec& spec, PluginInstance<sdk::Driver> driver)
      : guard_(spec), driver_(std::move(driver)) {}
  ~GuardedDriver() override { keep_if_abandoned(guard_, driver_); }
  sdk::Command update(const sdk::DriverInput& input) override;
  sdk::DriverStatus status() const override;

 private:
  PluginGuard guard_;
  PluginInstance<sdk::Driver> driver_;
};

/// A plug-in Slam as a SLAM lane's back-end: same odometry, frames, latency and scoring as a
/// built-in one. Its failures are PluginFailure.
class PluginBackend final : public slam::Backend {
 public:
  PluginBackend(const PluginSpec& spec, PluginInstance<sdk::Slam> slam);
  ~PluginBackend() override { keep_if_abandoned(guard_, slam_); }
  void reset(const core::Pose2& initial_pose, core::TimeUs stamp) override;
  void set_prior_map(const std::vector<core::MapCone>& map) override;
  void process(const slam::SlamInput& input) override;
  core::Estimate estimate() const override;
  const std::vector<slam::Association>& last_associations() const override;
  int loop_closures() const override;
  std::string name() const override { return name_; }

 private:
  PluginGuard guard_;
  PluginInstance<sdk::Slam> slam_;
  std::string name_;
  core::Pose2 start_;
  core::TimeUs start_stamp_ = 0;
  std::vector<sdk::ConeObservation> observations_;
  std::vector<slam::Association> associations_;
};

}  // namespace conesim::sim
