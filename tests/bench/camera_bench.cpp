// Stereo camera: one rendered pair (two 640 x 480 frames) on a track of about 250 cones.
// Target (issue 4): at most 25 ms per pair.

#include <benchmark/benchmark.h>

#include <cmath>
#include <ctime>
#include <numbers>

#include "sensors/stereo_camera.hpp"
#include "sim/vehicle_sim.hpp"
#include "vehicle_models/vehicle_params.hpp"

namespace {

using namespace conesim;

// an oval circuit of 250 cones (straights of 80 m, bends of radius 20 m, lane 3.5 m wide,
// cones every 2.5 m on each side) plus four big orange cones at the start; the car starts on
// the bottom straight facing +x
tracks::Track oval_track() {
  tracks::Track t;
  t.name = "bench_oval";
  const double straight = 80.0, radius = 20.0, half_width = 1.75;
  const double perimeter = 2.0 * straight + 2.0 * std::numbers::pi * radius;
  const int per_side = 125;
  int id = 0;
  for (int side = 0; side < 2; ++side) {
    const double offset = side == 0 ? half_width : -half_width;  // left is inside
    for (int i = 0; i < per_side; ++i) {
      const double s = perimeter * i / per_side;
      core::Vec2 p;
      if (s < straight) {
        p = {s, offset};
      } else if (s < straight + std::numbers::pi * radius) {
        const double a = (s - straight) / radius - 0.5 * std::numbers::pi;
        p = {straight + (radius - offset) * std::cos(a), radius + (radius - offset) * std::sin(a)};
      } else if (s < 2.0 * straight + std::numbers::pi * radius) {
        p = {straight - (s - straight - std::numbers::pi * radius), 2.0 * radius - offset};
      } else {
        const double a =
            (s - 2.0 * straight - std::numbers::pi * radius) / radius + 0.5 * std::numbers::pi;
        p = {(radius - offset) * std::cos(a), radius + (radius - offset) * std::sin(a)};
      }
      t.cones.push_back(
          {id++, side == 0 ? core::ConeClass::kBlue : core::ConeClass::kYellow, p, std::nullopt});
    }
  }
  for (const double y : {-2.2, 2.2})
    for (const double x : {5.0, 5.5})
      t.cones.push_back({id++, core::ConeClass::kOrangeBig, {x, y}, std::nullopt});
  return t;
}

// CPU time of all threads of this process, seconds
double process_cpu_s() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

// the car a few metres before the big orange cones, looking along the straight
void render_pair(benchmark::State& state, bool with_depth) {
  const tracks::Track track = oval_track();
  const sim::VehicleSim car(vehicle_models::VehicleParams{}, {0.0, 0.0, 0.0});
  sensors::StereoCamera camera({}, car.model(), track);
  core::StereoFrame frame;
  core::StereoLabels labels;
  const auto none_knocked = [](int) { return false; };
  // the first frame compiles llvmpipe's shaders: keep it out of the figures
  camera.render(car.data(), car.vehicle_pose3(), 0, none_knocked, with_depth, frame, labels);
  const double cpu_start_s = process_cpu_s();
  for (auto _ : state) {
    camera.render(car.data(), car.vehicle_pose3(), 0, none_knocked, with_depth, frame, labels);
    benchmark::DoNotOptimize(frame.left.rgb.data());
  }

  // llvmpipe rasterises on worker threads: report the CPU time of the whole process too
  state.counters["cones"] = static_cast<double>(track.cones.size());
  state.counters["process_cpu_ms_per_pair"] =
      1e3 * (process_cpu_s() - cpu_start_s) / static_cast<double>(state.iterations());
}

void BM_StereoPair(benchmark::State& state) {
  render_pair(state, false);
}
void BM_StereoPairWithDepth(benchmark::State& state) {
  render_pair(state, true);
}

BENCHMARK(BM_StereoPair)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(3.0);
BENCHMARK(BM_StereoPairWithDepth)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(3.0);

}  // namespace

BENCHMARK_MAIN();
