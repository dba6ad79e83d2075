#pragma once
// The autonomy behind the SDK's interfaces (sdk/include/conesim/sdk): plug-in libraries and
// their loading, the conversions between conesim's core types and the SDK's plain structs, the
// reference driver as an sdk::Driver, and a plug-in Slam as a SLAM lane's back-end. The run
// loop drives every driver, built-in or plug-in, through sdk::Driver.

#include <chrono>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "conesim/sdk/plugin.hpp"
#include "control/driver.hpp"
#include "core/autonomy_types.hpp"
#include "sdk/builtin/bridge.hpp"
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

/// Times a plug-in's calls against its budget and turns what it throws into PluginFailure.
class PluginGuard {
 public:
  explicit PluginGuard(const PluginSpec& spec)
      : label_(spec.label()), budget_ms_(spec.time_budget_ms) {}
  /// Runs f(); rethrows anything as PluginFailure naming the plug-in and `what` ("update"),
  /// and raises one when the call took longer than the budget.
  template <typename F>
  auto call(const char* what, F&& f) const {
    const auto start = std::chrono::steady_clock::now();
    auto check_time = [&] {
      const double ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
              .count();
      if (ms > budget_ms_) overran(what, ms);
    };
    try {
      if constexpr (std::is_void_v<decltype(f())>) {
        f();
        check_time();
      } else {
        auto r = f();
        check_time();
        return r;
      }
    } catch (const PluginFailure&) {
      throw;
    } catch (const std::exception& e) {
      threw(what, e.what());
    } catch (...) {
      threw(what, "an exception that is not a std::exception");
    }
  }
  /// Raises PluginFailure for a number that is not finite in the output `what`.
  void check_finite(const char* what, double value) const;
  const std::string& label() const { return label_; }

 private:
  [[noreturn]] void threw(const char* what, const std::string& message) const;
  [[noreturn]] void overran(const char* what, double ms) const;
  std::string label_;
  double budget_ms_;
};

/// A driver plug-in under its guard: exceptions, NaN commands and overruns become
/// PluginFailure.
class GuardedDriver final : public sdk::Driver {
 public:
  GuardedDriver(const PluginSpec& spec, PluginInstance<sdk::Driver> driver)
      : guard_(spec), driver_(std::move(driver)) {}
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
