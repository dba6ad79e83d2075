// Google Benchmark of the Embree LiDAR: milliseconds per sweep and rays per second on one
// thread, over a stadium track of 248 cones with the car driving at 10 m/s.
//
//   build/tests/bench_lidar --benchmark_counters_tabular=true

#include <benchmark/benchmark.h>

#include <cmath>
#include <numbers>
#include <string>

#include "sensors/lidar.hpp"
#include "sensors/lidar_config.hpp"
#include "sensors/pose_history.hpp"
#include "tracks/track.hpp"

namespace {

using namespace conesim;

constexpr double kStraightM = 80.0;
constexpr double kRadiusM = 20.0;
constexpr double kHalfWidthM = 1.5;
constexpr int kConesPerSide = 124;

// a point of the stadium's centre line at arc length s, with its left normal
void centre_line(double s, Eigen::Vector2d& p, Eigen::Vector2d& left) {
  const double arc = std::numbers::pi * kRadiusM;
  const double lap = 2.0 * kStraightM + 2.0 * arc;
  s = std::fmod(s, lap);
  if (s < kStraightM) {
    p = {s, 0.0};
    left = {0.0, 1.0};
  } else if (s < kStraightM + arc) {
    const double a = (s - kStraightM) / kRadiusM - std::numbers::pi / 2.0;
    p = {kStraightM + kRadiusM * std::cos(a), kRadiusM + kRadiusM * std::sin(a)};
    left = -Eigen::Vector2d(std::cos(a), std::sin(a));
  } else if (s < 2.0 * kStraightM + arc) {
    p = {kStraightM - (s - kStraightM - arc), 2.0 * kRadiusM};
    left = {0.0, -1.0};
  } else {
    const double a = (s - 2.0 * kStraightM - arc) / kRadiusM + std::numbers::pi / 2.0;
    p = {kRadiusM * std::cos(a), kRadiusM + kRadiusM * std::sin(a)};
    left = -Eigen::Vector2d(std::cos(a), std::sin(a));
  }
}

// blue cones on the left, yellow on the right, evenly along the lap
tracks::Track stadium() {
  tracks::Track track;
  track.name = "bench-stadium";
  const double lap = 2.0 * kStraightM + 2.0 * std::numbers::pi * kRadiusM;
  int id = 0;
  for (int i = 0; i < kConesPerSide; ++i) {
    Eigen::Vector2d p, left;
    centre_line(lap * i / kConesPerSide, p, left);
    track.cones.push_back({id++, core::ConeClass::kBlue, p + kHalfWidthM * left, {}});
    track.cones.push_back({id++, core::ConeClass::kYellow, p - kHalfWidthM * left, {}});
  }
  track.closed = true;
  return track;
}

// the car on the first straight at 10 m/s, poses every physics step (1 ms)
sensors::PoseHistory driving_poses() {
  sensors::PoseHistory poses;
  for (core::TimeUs t = 0; t <= 200'000; t += 1000) {
    core::Pose3 p;
    p.position = {10.0 + 10.0 * core::to_seconds(t), 0.0, 0.0};
    poses.push(t, p);
  }
  return poses;
}

// one sweep per iteration; reports rays/s and points per sweep
void run_sweeps(benchmark::State& state, const sensors::LidarConfig& config) {
  const sensors::Lidar lidar(config, stadium());
  const sensors::PoseHistory poses = driving_poses();
  core::Rng rng(1);
  int64_t rays = 0, points = 0, traced = 0;
  for (auto _ : state) {
    const sensors::LidarScan scan = lidar.sweep(0, poses, rng);
    rays += scan.stats.rays;
    traced += scan.stats.traced;
    points += static_cast<int64_t>(scan.cloud.points.size());
    benchmark::DoNotOptimize(scan.cloud.points.data());
  }
  state.counters["Mrays_per_s"] =
      benchmark::Counter(static_cast<double>(rays) * 1e-6, benchmark::Counter::kIsRate);
  state.counters["points_per_sweep"] =
      static_cast<double>(points) / static_cast<double>(state.iterations());
  // the share of rays that pass near a cone and go through Embree
  state.counters["traced_share"] = static_cast<double>(traced) / static_cast<double>(rays);
}

// the default VLP-16 with its datasheet noise: the figure `conesim bench sensors` quotes
void BM_Vlp16Sweep(benchmark::State& state) {
  run_sweeps(state, sensors::LidarConfig{});
}
BENCHMARK(BM_Vlp16Sweep)->Unit(benchmark::kMillisecond);

// the same without noise: the cost of the ray casting and the poses alone
void BM_Vlp16SweepNoiseless(benchmark::State& state) {
  sensors::LidarConfig config;
  config.range_noise_sigma_m = 0.0;
  config.intensity_noise_sigma = 0.0;
  run_sweeps(state, config);
}
BENCHMARK(BM_Vlp16SweepNoiseless)->Unit(benchmark::kMillisecond);

// the denser presets
void BM_Vlp32cSweep(benchmark::State& state) {
  run_sweeps(state, *sensors::lidar_preset("vlp32c"));
}
BENCHMARK(BM_Vlp32cSweep)->Unit(benchmark::kMillisecond);

void BM_Os1_64Sweep(benchmark::State& state) {
  run_sweeps(state, *sensors::lidar_preset("os1-64"));
}
BENCHMARK(BM_Os1_64Sweep)->Unit(benchmark::kMillisecond);

// a knocked cone: one scene update (disable and commit) and putting it back
void BM_KnockCone(benchmark::State& state) {
  sensors::Lidar lidar(sensors::LidarConfig{}, stadium());
  for (auto _ : state) {
    lidar.set_cone_present(7, false);
    lidar.set_cone_present(7, true);
  }
  state.SetItemsProcessed(2 * state.iterations());
}
BENCHMARK(BM_KnockCone)->Unit(benchmark::kMillisecond);

// building the scene of the whole track
void BM_BuildScene(benchmark::State& state) {
  const tracks::Track track = stadium();
  for (auto _ : state) {
    sensors::Lidar lidar(sensors::LidarConfig{}, track);
    benchmark::DoNotOptimize(&lidar);
  }
}
BENCHMARK(BM_BuildScene)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
