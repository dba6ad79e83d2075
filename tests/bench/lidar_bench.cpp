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
#include "tracks/ground.hpp"
#include "tracks/scenery.hpp"
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
    track.left_lane.push_back(id);
    track.cones.push_back({id++, core::ConeClass::kBlue, p + kHalfWidthM * left, {}});
    track.right_lane.push_back(id);
    track.cones.push_back({id++, core::ConeClass::kYellow, p - kHalfWidthM * left, {}});
  }
  track.closed = true;
  track.centre_line = tracks::derive_centre_line(track);
  return track;
}

// the car on the first straight at 10 m/s, poses every physics step (1 ms), on the ground
sensors::PoseHistory driving_poses(const tracks::GroundModel& ground) {
  sensors::PoseHistory poses;
  for (core::TimeUs t = 0; t <= 200'000; t += 1000) {
    core::Pose3 p;
    p.position = {10.0 + 10.0 * core::to_seconds(t), 0.0, 0.0};
    p.position.z() = ground.height(p.position.x(), p.position.y());
    poses.push(t, p);
  }
  return poses;
}

// one sweep per iteration; reports rays/s and points per sweep
void run_sweeps(benchmark::State& state, const sensors::LidarConfig& config,
                const std::vector<tracks::SceneryObject>& scenery = {},
                const tracks::GroundModel& ground = {}) {
  const tracks::Track track = stadium();
  const sensors::Lidar lidar(config, track, scenery, ground);
  const sensors::PoseHistory poses = driving_poses(ground);
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
  state.counters["objects"] = static_cast<double>(scenery.size());
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

// the VLP-32C among clutter at 5 objects per 100 m and the grass edge's 4 m strips along both
// sides (what a realistic venue puts beside the lanes)
void BM_Vlp32cSweepAmongClutter(benchmark::State& state) {
  tracks::ClutterConfig clutter;
  clutter.objects_per_100m = 5.0;
  clutter.grass_edge = true;
  run_sweeps(state, *sensors::lidar_preset("vlp32c"), tracks::place_scenery(stadium(), clutter, 1));
}
BENCHMARK(BM_Vlp32cSweepAmongClutter)->Unit(benchmark::kMillisecond);

// the same clutter on a 2 % grade with 3 cm bumps, two per 100 m^2 (the "everything on")
void BM_Vlp32cSweepAmongClutterOnBumpyGrade(benchmark::State& state) {
  tracks::ClutterConfig clutter;
  clutter.objects_per_100m = 5.0;
  clutter.grass_edge = true;
  tracks::GroundConfig shape;
  shape.grade_percent = 2.0;
  shape.bump_height_m = 0.03;
  shape.bumps_per_100m2 = 2.0;
  const tracks::Track track = stadium();
  const tracks::GroundModel ground(track, shape, 1);
  std::vector<tracks::SceneryObject> scenery = tracks::place_scenery(track, clutter, 1);
  tracks::lay_on_ground(scenery, ground);
  run_sweeps(state, *sensors::lidar_preset("vlp32c"), scenery, ground);
}
BENCHMARK(BM_Vlp32cSweepAmongClutterOnBumpyGrade)->Unit(benchmark::kMillisecond);

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
