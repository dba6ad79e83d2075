#pragma once
// One closed-loop run: world (MuJoCo car on the track), referee, perception, estimate, driver;
// then the outputs in the run directory.

#include <chrono>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "conesim/sdk/interfaces.hpp"
#include "core/autonomy_types.hpp"
#include "sim/referee.hpp"
#include "sim/scenario.hpp"
#include "sim/sensor_rig.hpp"
#include "sim/sensor_tap.hpp"
#include "tracks/track.hpp"

namespace conesim::sim {

/// What the progress line shows, handed out a few times per wall-clock second.
struct Progress {
  double sim_time_s = 0.0;
  double real_time_factor = 0.0;
  int laps = 0;
  int laps_target = 0;
  std::string driver_state;
};

/// How to run (not part of the scenario: it does not change the result).
struct RunOptions {
  /// The run directory to write; created if missing.
  std::filesystem::path out_dir;
  /// Called about four times per wall-clock second when set.
  std::function<void(const Progress&)> on_progress;
  /// Write the top-down PNG (needs gnuplot).
  bool plot = true;
  /// Sensor data to write under images/ (dumping a sensor switches it on).
  DumpOptions dump;
  /// A driver in place of the scenario's, made with the run's RunInfo (the Python module's
  /// lock-step driver); unset: the scenario's. It is called like any driver, and a
  /// PluginFailure it raises ends the run with a DNF.
  std::function<std::unique_ptr<sdk::Driver>(const sdk::RunInfo&)> make_driver;
  /// Called at every driver tick before the driver, with the sim time and the referee's verdict
  /// so far.
  std::function<void(core::TimeUs, const RefereeResult&)> on_tick;
  /// An observer of the raw sensor data (the Python module's `observe=`), null for none: the
  /// sensors it asks for are switched on; it changes nothing else of the run.
  SensorTap* sensor_tap = nullptr;
  /// A recorder of labelled frames (`conesim dataset`), null for none: the camera (and the
  /// LiDAR when it wants sweeps) are switched on; it changes nothing else of the run.
  LabelledDataSink* labelled = nullptr;
  /// Record the run for its 3D replay (replay.bin: LiDAR sweeps thinned, the SLAM maps as they
  /// grow) and write replay.html at the end (sim/replay.hpp, `conesim view`).
  bool replay = false;
};

/// The outcome of a run.
struct RunResult {
  RefereeResult referee;
  bool passed = false;
  /// Why the pass criteria failed, one line each.
  std::vector<std::string> failures;
  double sim_time_s = 0.0;
  double wall_time_s = 0.0;
  int driver_laps = 0;
  nlohmann::json metrics;
  /// The driving SLAM lane's updates: the frame's stamp (sim s) and the update's CPU time (ms),
  /// in order (empty without SLAM; `conesim bench soak` compares laps by them).
  std::vector<std::pair<double, double>> slam_update_cpu_ms;
  /// What went wrong without touching the result (a picture gnuplot could not draw).
  std::vector<std::string> warnings;
  /// The signal (SIGINT, SIGTERM) that stopped the run before its verdict, 0 when none did: the
  /// folder then has no metrics.json and an INCOMPLETE file that says why.
  int interrupted_by = 0;
};

/// The file an interrupted run leaves in its folder instead of metrics.json.
inline constexpr const char* kIncompleteFile = "INCOMPLETE";

/// Refuses (core::InputError, exit 2) an output folder a run could not write its results to:
/// a probe file is written, flushed to the disk and removed, so that a read-only or full
/// location is named before the run starts rather than after it.
void check_output_writable(const std::filesystem::path& folder);

/// Builds the track a scenario asks for (its file, the FSG layout or a generated circuit).
tracks::Track scenario_track(const Scenario& scenario);

/// The cones a perfect sensor sees from the vehicle pose: within range and field of view, not
/// knocked over, in the vehicle frame; `ids` receives each observation's true cone id.
core::ConeObservations perceive_ground_truth(const tracks::Track& track, const core::Pose2& pose,
                                             const SensorSettings& sensors,
                                             const std::function<bool(int)>& is_knocked,
                                             std::vector<int>* ids = nullptr);

/// Why the car cannot drive the scenario's circuit (autocross, trackdrive), naming the place,
/// e.g. "lanes 1.90 m apart at (12.3, -4.5), the car needs 1.83 m"; empty when it can or when
/// the event is not a circuit.
std::string drivability_problem(const Scenario& scenario, const tracks::Track& track);

/// Farthest a cone or the start may stand from the track frame's origin in a run, metres: the
/// LiDAR and the camera work in single precision (millimetres up to here), and the referee's
/// grids cost memory by the layout's extent. Surveyed layouts in UTM coordinates are moved to
/// a local origin first.
inline constexpr double kMaxRunCoordinateM = 2000.0;

/// Why a layout is beyond what a run handles (kMaxRunCoordinateM), empty when it is not.
std::string run_bounds_problem(const tracks::Track& track);

/// Runs the scenario on the track to the referee's verdict and writes trajectory.csv, track.csv
/// and metrics.json (last of the results, so a run that stops early leaves none; an earlier one
/// in the folder is removed first) to options.out_dir, then the pictures (run.png, and the
/// perception and SLAM reports): a picture that fails is a warning in the result.
RunResult run_scenario(const Scenario& scenario, const tracks::Track& track,
                       const RunOptions& options);

}  // namespace conesim::sim
