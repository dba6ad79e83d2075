#pragma once
// `conesim bench sensors`: the speed figures of the sensors and of the closed loop;
// `conesim bench tracks`: what the track commands cost on large layouts.

#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace conesim::sim {

/// Measures the LiDAR (single thread: Mrays/s and ms per scan), a stereo pair of 640x480
/// frames, and trackdrive in closed loop with and without the LiDAR sweeping at 10 Hz.
/// Medians over repeated runs; the machine's load shows in the spread (p10, p90 given too).
nlohmann::json bench_sensors(int repeats, bool closed_loop);

/// Times `track validate`, `track info` and `track convert` (in process, file to file) on the
/// large layouts of sim/big_layouts.hpp with the given cone counts: the median over `repeats`
/// of each, seconds. With `keep_dir`, the layouts are written there (EUFS CSV) and kept.
nlohmann::json bench_tracks(const std::vector<int>& cone_counts, int repeats,
                            const std::filesystem::path& keep_dir = {});

/// What `conesim bench soak` runs: a shipped scenario for many laps.
struct SoakOptions {
  std::string scenario = "trackdrive-lidar";
  int laps = 100;
  uint64_t seed = 1;
  /// More `--set` values for the run.
  std::vector<std::string> sets;
};

/// Runs the scenario for o.laps laps in this process and reports, lap by lap, the process's
/// resident memory when the lap is counted and the driving SLAM update's p99 CPU time; then the
/// last lap's memory against lap 10's and the last ten laps' p99 against the first ten's.
nlohmann::json bench_soak(const SoakOptions& o);

}  // namespace conesim::sim
