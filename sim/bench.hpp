#pragma once
// `conesim bench sensors`: the speed figures of the sensors and of the closed loop.

#include <nlohmann/json.hpp>

namespace conesim::sim {

/// Measures the LiDAR (single thread: Mrays/s and ms per scan), a stereo pair of 640x480
/// frames, and trackdrive in closed loop with and without the LiDAR sweeping at 10 Hz.
/// Medians over repeated runs; the machine's load shows in the spread (p10, p90 given too).
nlohmann::json bench_sensors(int repeats, bool closed_loop);

}  // namespace conesim::sim
