#include "sim/autonomy.hpp"

#include <dlfcn.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <condition_variable>
#include <cstring>
#include <mutex>

#include "core/error.hpp"
#include "core/files.hpp"
#include "sim/scenario.hpp"

namespace conesim::sim {

namespace fs = std::filesystem;

namespace {

// the entry point's type
using EntryPoint = const sdk::PluginInfo* (*)();

bool plain_word(const char* name) {
  if (!name || !*name) return false;
  for (const char* c = name; *c; ++c)
    if (!std::isalnum(static_cast<unsigned char>(*c)) && *c != '_' && *c != '-') return false;
  return true;
}

// the flattened configuration as the SDK's view: pointers into the spec's strings
struct ConfigView {
  std::vector<sdk::ConfigEntry> entries;
  explicit ConfigView(const PluginSpec& spec) {
    for (const auto& [k, v] : spec.config) entries.push_back({k.c_str(), v.c_str()});
  }
  sdk::Config config(const PluginSpec& spec) const {
    return sdk::Config({entries.data(), entries.size()}, spec.config_yaml.c_str());
  }
};

template <typename T, typename Factory>
PluginInstance<T> make_instance(const PluginSpec& spec, const sdk::RunInfo& run, Factory factory,
                                const char* key) {
  const std::string where = std::string("autonomy.") + key;
  if (!factory)
    throw core::InputError(
        spec.file.string(), where,
        "the plug-in '" + spec.name() + "' offers no " + key + " (its CONESIM_PLUGIN names none)");
  const ConfigView view(spec);
  T* object = nullptr;
  try {
    object = factory(run, view.config(spec));
  } catch (const std::exception& e) {
    throw core::InputError(spec.file.string(), where + ".config",
                           spec.label() + " refused its configuration: " + e.what());
  } catch (...) {
    throw core::InputError(spec.file.string(), where + ".config",
                           spec.label() + " refused its configuration");
  }
  if (!object) throw core::InputError(spec.file.string(), where, spec.label() + " made no object");
  return {spec.library, std::unique_ptr<T>(object)};
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// the library

std::shared_ptr<const PluginLibrary> PluginLibrary::open(const fs::path& file) {
  if (!core::path_exists(file)) throw std::runtime_error(file.string() + ": no such plug-in file");
  if (!core::is_file(file))
    throw std::runtime_error(file.string() + ": not a file (a plug-in is a shared library)");
  std::shared_ptr<PluginLibrary> lib(new PluginLibrary);
  lib->file_ = file;
  // a path with a slash: dlopen takes it as is and does not search the library path
  const std::string path = file.has_parent_path() ? file.string() : "./" + file.string();
  lib->handle_ = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (!lib->handle_) {
    const char* e = dlerror();
    throw std::runtime_error(file.string() +
                             ": cannot load the plug-in: " + (e ? e : "unknown error"));
  }
  dlerror();
  void* entry = dlsym(lib->handle_, sdk::kEntryPointSymbol);
  if (!entry)
    throw std::runtime_error(file.string() + ": no symbol " + sdk::kEntryPointSymbol +
                             ": not a conesim plug-in (define it with CONESIM_PLUGIN from "
                             "<conesim/sdk/plugin.hpp>)");
  const sdk::PluginInfo* info = reinterpret_cast<EntryPoint>(entry)();
  if (!info) throw std::runtime_error(file.string() + ": its entry point returned nothing");
  // the ABI first: nothing else of the info is read from a plug-in of another ABI
  if (info->abi_version != sdk::kAbiVersion)
    throw std::runtime_error(file.string() + ": built against conesim SDK ABI " +
                             std::to_string(info->abi_version) + ", and this conesim (" +
                             sdk::kSdkVersion + ") takes ABI " + std::to_string(sdk::kAbiVersion) +
                             ": rebuild the plug-in against this conesim's installed SDK");
  if (!plain_word(info->name))
    throw std::runtime_error(file.string() + ": the plug-in's name '" +
                             (info->name ? info->name : "") +
                             "' is not a plain word (letters, digits, '_', '-')");
  lib->info_ = info;
  return lib;
}

PluginLibrary::~PluginLibrary() {
  if (handle_) dlclose(handle_);
}

const char* to_string(PluginKind kind) {
  switch (kind) {
    case PluginKind::kPerception:
      return "perception";
    case PluginKind::kSlam:
      return "slam";
    case PluginKind::kDriver:
      break;
  }
  return "driver";
}

std::string PluginSpec::label() const {
  return std::string(to_string(kind)) + " plug-in '" + name() + "' (" + file.string() + ")";
}

std::unique_ptr<RunInfoStorage> make_run_info(const Scenario& s, const control::VehicleGeometry& g,
                                              const core::Pose2& start,
                                              const std::vector<core::MapCone>& prior_map) {
  auto storage = std::make_unique<RunInfoStorage>();
  sdk::RunInfo& run = storage->info;
  run.event = static_cast<sdk::Event>(s.event);
  run.seed = s.seed;
  sdk::Vehicle& v = run.vehicle;
  v.wheelbase_m = g.wheelbase_m;
  v.max_steer_rad = g.max_steer_rad;
  v.max_steer_rate_rps = g.max_steer_rate_rps;
  v.rear_axle_to_front_m = g.rear_axle_to_front_m;
  v.rear_axle_to_back_m = g.rear_axle_to_back_m;
  v.width_m = g.width_m;
  v.wheel_radius_m = s.vehicle.wheel_radius_m;
  const auto& e = g.envelope;
  v.envelope = {e.mass_kg,   e.friction,          e.downforce_n_per_v2, e.drag_n_per_v2,
                e.rolling_n, e.max_drive_force_n, e.max_power_w,        e.max_brake_force_n};
  for (const auto& [angle, gain] : g.yaw_gain) storage->yaw_gain.push_back({angle, gain});
  v.yaw_gain = {storage->yaw_gain.data(), storage->yaw_gain.size()};
  run.trackdrive_laps = s.driver.trackdrive_laps;
  run.driver_rate_hz = s.sensors.driver_rate_hz;
  run.start_pose = to_sdk(start);
  for (const core::MapCone& c : prior_map) storage->prior_map.push_back(to_sdk(c));
  run.prior_map = {storage->prior_map.data(), storage->prior_map.size()};
  storage->scenario_file = s.source_file.string();
  run.scenario_file = storage->scenario_file.c_str();
  return storage;
}

// ---------------------------------------------------------------------------------------------
// the reference driver

ReferenceDriver::ReferenceDriver(core::EventType event, const control::DriverParams& params,
                                 const control::VehicleGeometry& vehicle,
                                 std::vector<core::MapCone> prior_map)
    : driver_(event, params, vehicle, std::move(prior_map)) {}

sdk::Command ReferenceDriver::update(const sdk::DriverInput& input) {
  const core::VehicleCommand c =
      driver_.update({from_sdk(input.estimate), from_sdk(input.observations)});
  return {c.steer_rad, c.accel_mps2, c.hold_stopped ? 1 : 0};
}

sdk::DriverStatus ReferenceDriver::status() const {
  const control::DriverStatus& s = driver_.status();
  return {s.laps_counted, s.finished ? 1 : 0, s.state.c_str(), s.problem.c_str()};
}

// ---------------------------------------------------------------------------------------------
// plug-in instances

PluginInstance<sdk::Driver> make_plugin_driver(const PluginSpec& spec, const sdk::RunInfo& run) {
  return make_instance<sdk::Driver>(spec, run, spec.library->info().create_driver, "driver");
}

PluginInstance<sdk::Slam> make_plugin_slam(const PluginSpec& spec, const sdk::RunInfo& run) {
  return make_instance<sdk::Slam>(spec, run, spec.library->info().create_slam, "slam");
}

PluginInstance<sdk::Perception> make_plugin_perception(const PluginSpec& spec,
                                                       const sdk::RunInfo& run) {
  return make_instance<sdk::Perception>(spec, run, spec.library->info().create_perception,
                                        "perception");
}

void check_plugins(const Scenario& s, const sdk::RunInfo& run) {
  if (s.driver_plugin) make_plugin_driver(*s.driver_plugin, run);
  if (s.slam_plugin) make_plugin_slam(*s.slam_plugin, run);
  if (s.perception_plugin) make_plugin_perception(*s.perception_plugin, run);
}

void PluginGuard::check_finite(const char* what, double value) const {
  if (!std::isfinite(value))
    throw PluginFailure(label_ + " returned " + (std::isnan(value) ? "NaN" : "an infinite value") +
                        " as " + what);
}

struct PluginCallThread::State {
  // one call at a time, whichever thread makes it
  std::mutex call;
  std::mutex mutex;
  std::condition_variable wake;
  std::function<void()> job;
  bool has_job = false;
  bool done = false;
  bool stopping = false;
  bool abandoned = false;

  void loop() {
    std::unique_lock<std::mutex> lock(mutex);
    for (;;) {
      wake.wait(lock, [this] { return has_job || stopping; });
      if (!has_job) return;
      std::function<void()> next = std::move(job);
      has_job = false;
      lock.unlock();
      next();
      lock.lock();
      done = true;
      wake.notify_all();
    }
  }
};

PluginCallThread::PluginCallThread() : state_(std::make_shared<State>()) {
  thread_ = std::thread([state = state_] { state->loop(); });
}

PluginCallThread::~PluginCallThread() {
  {
    std::lock_guard<std::mutex> lock(state_->mutex);
    state_->stopping = true;
  }
  state_->wake.notify_all();
  // a thread still in a call that never returned is left to the end of the process
  if (abandoned())
    thread_.detach();
  else
    thread_.join();
}

bool PluginCallThread::run(std::function<void()> job, double timeout_ms) {
  std::lock_guard<std::mutex> one_call(state_->call);
  std::unique_lock<std::mutex> lock(state_->mutex);
  if (state_->abandoned) return false;
  state_->job = std::move(job);
  state_->has_job = true;
  state_->done = false;
  state_->wake.notify_all();
  const bool done = state_->wake.wait_for(
      lock, std::chrono::duration<double, std::milli>(timeout_ms), [this] { return state_->done; });
  if (!done) state_->abandoned = true;
  return done;
}

bool PluginCallThread::abandoned() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->abandoned;
}

namespace {
std::atomic<PluginHangHandler> hang_handler{nullptr};
}  // namespace

void set_plugin_hang_handler(PluginHangHandler handler) { hang_handler.store(handler); }

struct PluginWatchdog::State {
  std::string label;
  double budget_ms = 0.0;
  PluginHangHandler handler = nullptr;
  // the call under way: when it started (steady clock, ns; -1 when none) and its name
  std::atomic<int64_t> started_ns{-1};
  std::atomic<const char*> what{""};
  std::mutex mutex;
  std::condition_variable wake;
  bool stopping = false;

  static int64_t now_ns() {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
  }

  void loop() {
    // a look a quarter budget apart (5 to 250 ms): a hang is seen between 2 and 2.25 budgets
    // after its call began, and the watchdog wakes at most 200 times a wall second
    const auto every = std::chrono::duration<double, std::milli>(std::clamp(budget_ms / 4.0, 5.0, 250.0));
    const auto hang_ns = static_cast<int64_t>(2.0 * budget_ms * 1e6);
    std::unique_lock<std::mutex> lock(mutex);
    while (!stopping) {
      wake.wait_for(lock, every);
      if (stopping) return;
      const int64_t started = started_ns.load();
      if (started < 0) continue;
      const int64_t running_ns = now_ns() - started;
      if (running_ns < hang_ns) continue;
      char buf[200];
      std::snprintf(buf, sizeof(buf),
                    " did not return from %s within its time budget of %.0f ms (still running "
                    "after %.0f ms)",
                    what.load(), budget_ms, running_ns / 1e6);
      handler(label + buf);
      std::_Exit(1);  // a handler must not return; if it did, the run's thread is stuck still
    }
  }
};

PluginWatchdog::PluginWatchdog(std::string label, double budget_ms, PluginHangHandler handler)
    : state_(std::make_shared<State>()) {
  state_->label = std::move(label);
  state_->budget_ms = budget_ms;
  state_->handler = handler;
  thread_ = std::thread([state = state_] { state->loop(); });
}

PluginWatchdog::~PluginWatchdog() {
  {
    std::lock_guard<std::mutex> lock(state_->mutex);
    state_->stopping = true;
  }
  state_->wake.notify_all();
  thread_.join();
}

std::chrono::steady_clock::time_point PluginWatchdog::begin(const char* what) {
  const auto now = std::chrono::steady_clock::now();
  state_->what.store(what);
  state_->started_ns.store(
      std::chrono::duration_cast<std::chrono::nanoseconds>(now.time_since_epoch()).count());
  return now;
}

void PluginWatchdog::end() { state_->started_ns.store(-1); }

PluginGuard::PluginGuard(const PluginSpec& spec)
    : label_(spec.label()), budget_ms_(spec.time_budget_ms) {
  if (PluginHangHandler handler = hang_handler.load())
    watchdog_ = std::make_unique<PluginWatchdog>(label_, budget_ms_, handler);
  else
    thread_ = std::make_unique<PluginCallThread>();
}

void PluginGuard::check_returned_in_time(const char* what,
                                         std::chrono::steady_clock::time_point started) const {
  const double took_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - started)
          .count();
  if (took_ms <= budget_ms_) return;
  char buf[200];
  std::snprintf(buf, sizeof(buf),
                " did not return from %s within its time budget of %.0f ms (it took %.0f ms)",
                what, budget_ms_, took_ms);
  throw PluginFailure(label_ + buf);
}

void PluginGuard::rethrow_as_failure(const char* what, std::exception_ptr error) const {
  try {
    std::rethrow_exception(error);
  } catch (const PluginFailure&) {
    throw;
  } catch (const std::exception& e) {
    throw PluginFailure(label_ + " threw in " + what + ": " + e.what());
  } catch (...) {
    throw PluginFailure(label_ + " threw in " + what +
                        ": an exception that is not a std::exception");
  }
}

void PluginGuard::run(const char* what, std::function<void()> job) const {
  if (thread_->abandoned())
    throw PluginFailure(label_ + " is not answering: an earlier call never returned");
  // what the call threw comes back beside it
  auto error = std::make_shared<std::exception_ptr>();
  const bool returned = thread_->run(
      [job = std::move(job), error] {
        try {
          job();
        } catch (...) {
          *error = std::current_exception();
        }
      },
      budget_ms_);
  if (!returned) {
    char buf[160];
    std::snprintf(buf, sizeof(buf), " did not return from %s within its time budget of %.0f ms",
                  what, budget_ms_);
    throw PluginFailure(label_ + buf);
  }
  if (*error) rethrow_as_failure(what, *error);
}

sdk::Command GuardedDriver::update(const sdk::DriverInput& input) {
  const sdk::Command c = guard_.call("update", [&] { return driver_.object->update(input); });
  guard_.check_finite("steer_rad", c.steer_rad);
  guard_.check_finite("accel_mps2", c.accel_mps2);
  return c;
}

sdk::DriverStatus GuardedDriver::status() const {
  sdk::DriverStatus s = guard_.call("status", [&] { return driver_.object->status(); });
  if (!s.state) s.state = "";
  if (!s.problem) s.problem = "";
  return s;
}

// ---------------------------------------------------------------------------------------------
// a plug-in SLAM as a lane's back-end

PluginBackend::PluginBackend(const PluginSpec& spec, PluginInstance<sdk::Slam> slam)
    : guard_(spec), slam_(std::move(slam)), name_("plugin:" + spec.name()) {}

void PluginBackend::reset(const core::Pose2& initial_pose, core::TimeUs stamp) {
  start_ = initial_pose;
  start_stamp_ = stamp;
  guard_.call("reset", [&] { slam_.object->reset(to_sdk(initial_pose), stamp, {}); });
}

void PluginBackend::set_prior_map(const std::vector<core::MapCone>& map) {
  // the SDK's reset takes the prior map: start over with it
  std::vector<sdk::MapCone> prior;
  for (const core::MapCone& c : map) prior.push_back(to_sdk(c));
  guard_.call("reset", [&] {
    slam_.object->reset(to_sdk(start_), start_stamp_, {prior.data(), prior.size()});
  });
}

void PluginBackend::process(const slam::SlamInput& input) {
  sdk::SlamInput in;
  in.odometry = to_sdk(input.odometry);
  in.observations = to_sdk(input.observations, observations_);
  guard_.call("process", [&] { slam_.object->process(in); });
  // what it did with each observation: kept only when it reports one per observation
  associations_.clear();
  const sdk::Span<int32_t> codes =
      guard_.call("associations", [&] { return slam_.object->associations(); });
  if (codes.size != input.observations.cones.size()) return;
  // and the landmarks the new ones started, when it says
  const sdk::Span<int32_t> started =
      guard_.call("new_landmark_ids", [&] { return slam_.object->new_landmark_ids(); });
  for (uint64_t i = 0; i < codes.size; ++i) {
    const int32_t code = codes[i];
    slam::Association a;
    a.kind = code >= 0    ? slam::Association::Kind::kMatched
             : code == -1 ? slam::Association::Kind::kNew
                          : slam::Association::Kind::kRejected;
    a.landmark_id = code >= 0                                  ? code
                    : code == -1 && started.size == codes.size ? started[i]
                                                               : slam::Association::kNoLandmark;
    associations_.push_back(a);
  }
}

core::Estimate PluginBackend::estimate() const {
  const sdk::Estimate e = guard_.call("estimate", [&] { return slam_.object->estimate(); });
  guard_.check_finite("estimate.pose.x_m", e.pose.x_m);
  guard_.check_finite("estimate.pose.y_m", e.pose.y_m);
  guard_.check_finite("estimate.pose.yaw_rad", e.pose.yaw_rad);
  guard_.check_finite("estimate.speed_mps", e.speed_mps);
  guard_.check_finite("estimate.yaw_rate_rps", e.yaw_rate_rps);
  for (const sdk::MapCone& c : e.map) {
    guard_.check_finite("a map cone's x_m", c.x_m);
    guard_.check_finite("a map cone's y_m", c.y_m);
  }
  return from_sdk(e);
}

const std::vector<slam::Association>& PluginBackend::last_associations() const {
  return associations_;
}

int PluginBackend::loop_closures() const {
  return guard_.call("loop_closures", [&] { return slam_.object->loop_closures(); });
}

}  // namespace conesim::sim
