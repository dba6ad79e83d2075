// Google Benchmark of the LiDAR front-end: milliseconds per sweep of the cone detector (de-skew,
// ground fit, clustering, fits, colour) and of the tracker, on a VLP-16 sweep of a generated
// circuit with the car at 10 m/s. The sweep is cast once; only the front-end is timed.
//
//   build/tests/bench_perception --benchmark_counters_tabular=true

#include <benchmark/benchmark.h>

#include <algorithm>

#include "sensors/lidar.hpp"
#include "sensors/lidar_config.hpp"
#include "sensors/pose_history.hpp"
#include "slam/frontend/cone_tracker.hpp"
#include "slam/frontend/lidar_cone_detector.hpp"
#include "tracks/generator.hpp"

namespace {

using namespace conesim;

// one sweep from the start pose of a generated circuit, driving straight at 10 m/s
sensors::LidarScan one_sweep(const tracks::Track& track, const sensors::LidarConfig& config) {
  const sensors::Lidar lidar(config, track);
  sensors::PoseHistory poses;
  const core::Pose2 start = track.start;
  for (core::TimeUs t = 0; t <= 120'000; t += 1000) {
    core::Pose3 p;
    const double s = 10.0 * core::to_seconds(t);
    p.position = {start.x + s * std::cos(start.yaw), start.y + s * std::sin(start.yaw), 0.0};
    p.orientation = Eigen::AngleAxisd(start.yaw, Eigen::Vector3d::UnitZ());
    poses.push(t, p);
  }
  core::Rng rng(1);
  return lidar.sweep(0, poses, rng);
}

void BM_LidarConeDetector(benchmark::State& state) {
  const sensors::LidarConfig config;
  const sensors::LidarScan scan = one_sweep(tracks::generate_circuit(7), config);
  const slam::frontend::LidarConeDetector detector({}, config.mount);
  size_t cones = 0;
  for (auto _ : state) {
    const slam::frontend::LidarDetections d = detector.detect(scan.cloud, {10.0, 0.0});
    cones = d.cones.size();
    benchmark::DoNotOptimize(cones);
  }
  state.counters["points"] = static_cast<double>(scan.cloud.points.size());
  state.counters["cones"] = static_cast<double>(cones);
}
BENCHMARK(BM_LidarConeDetector)->Unit(benchmark::kMillisecond);

void BM_LidarConeDetectorVlp32c(benchmark::State& state) {
  // the shipped trackdrive-lidar sensor: twice the rings, and four times the points on cones
  const sensors::LidarConfig config = *sensors::lidar_preset("vlp32c");
  const sensors::LidarScan scan = one_sweep(tracks::generate_circuit(7), config);
  slam::frontend::LidarDetectorConfig detector_config;
  detector_config.ring_elevations_deg = config.elevations_deg;
  std::sort(detector_config.ring_elevations_deg.begin(), detector_config.ring_elevations_deg.end());
  const slam::frontend::LidarConeDetector detector(detector_config, config.mount);
  size_t cones = 0;
  int raised = 0;
  for (auto _ : state) {
    const slam::frontend::LidarDetections d = detector.detect(scan.cloud, {10.0, 0.0});
    cones = d.cones.size();
    raised = d.non_ground_points;
    benchmark::DoNotOptimize(cones);
  }
  state.counters["points"] = static_cast<double>(scan.cloud.points.size());
  state.counters["raised"] = raised;
  state.counters["cones"] = static_cast<double>(cones);
}
BENCHMARK(BM_LidarConeDetectorVlp32c)->Unit(benchmark::kMillisecond);

void BM_ConeTracker(benchmark::State& state) {
  const sensors::LidarConfig config;
  const sensors::LidarScan scan = one_sweep(tracks::generate_circuit(7), config);
  const core::ConeObservations frame =
      slam::frontend::LidarConeDetector({}, config.mount).detect(scan.cloud, {}).observations();
  slam::frontend::ConeTracker tracker({});
  for (auto _ : state) benchmark::DoNotOptimize(tracker.update(frame, core::Pose2{}));
  state.counters["cones"] = static_cast<double>(frame.cones.size());
}
BENCHMARK(BM_ConeTracker)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
