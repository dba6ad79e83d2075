#pragma once
// `conesim bench sensors`: the speed figures of the sensors and of the closed loop;
// `conesim bench tracks`: what the track commands cost on large layouts.

#include <filesystem>
#include <nlohmann/json.hpp>
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

}  // namespace conesim::sim
