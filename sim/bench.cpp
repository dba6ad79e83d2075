#include "sim/bench.hpp"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <thread>

#include "sensors/lidar.hpp"
#include "sensors/pose_history.hpp"
#include "sensors/stereo_camera.hpp"
#include "sim/big_layouts.hpp"
#include "sim/json_text.hpp"
#include "sim/run.hpp"
#include "sim/scenario.hpp"
#include "sim/track_commands.hpp"
#include "sim/vehicle_sim.hpp"
#include "tracks/io.hpp"

namespace conesim::sim {

namespace {

using clock = std::chrono::steady_clock;

double ms_since(clock::time_point start) {
  return std::chrono::duration<double, std::milli>(clock::now() - start).count();
}

// median, 10th and 90th percentile of a sample
nlohmann::json spread(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  auto at = [&v](double q) { return v[static_cast<size_t>(q * (v.size() - 1) + 0.5)]; };
  return {{"median", at(0.5)}, {"p10", at(0.1)}, {"p90", at(0.9)}, {"n", v.size()}};
}

// a run of a shipped scenario into a scratch folder; returns sim seconds per wall second
// (the median of `repeats` runs: one run's figure moves with the machine's load)
double closed_loop_rtf(const std::string& name, const std::vector<std::string>& sets, int repeats) {
  const Scenario s = load_scenario(find_scenario(name), sets);
  const tracks::Track track = scenario_track(s);
  RunOptions options;
  options.out_dir =
      std::filesystem::temp_directory_path() / ("conesim-bench-" + std::to_string(::getpid()));
  options.plot = false;
  std::vector<double> rtf;
  for (int i = 0; i < std::max(repeats, 1); ++i) {
    const RunResult r = run_scenario(s, track, options);
    rtf.push_back(r.sim_time_s / r.wall_time_s);
  }
  std::filesystem::remove_all(options.out_dir);
  return spread(rtf)["median"];
}

// the host's 1-minute load average (-1 when it cannot be read)
double load_average_1min() {
  double load[1] = {-1.0};
  getloadavg(load, 1);
  return load[0];
}

// what the figures were measured on: the same build gives figures twice as high on one host of a
// machine class as on another, and a busy host lowers them by a fifth (docs/slam_comparison.md,
// "Speed"); the load average is read here, at the start, and again at the end (note_end_load)
nlohmann::json host_facts() {
  std::string cpu = "unknown";
  std::ifstream info("/proc/cpuinfo");
  for (std::string line; std::getline(info, line);)
    if (line.rfind("model name", 0) == 0) {
      const size_t colon = line.find(':');
      if (colon != std::string::npos) cpu = line.substr(line.find_first_not_of(" \t", colon + 1));
      break;
    }
  return {{"cpu", cpu},
          {"logical_cpus", std::thread::hardware_concurrency()},
          {"load_average_1min_start", load_average_1min()}};
}

void note_end_load(nlohmann::json& host) {
  host["load_average_1min_end"] = load_average_1min();
}

}  // namespace

nlohmann::json bench_sensors(int repeats, bool closed_loop) {
  const tracks::Track track = make_event_track(core::EventType::kTrackdrive, 1);
  nlohmann::json out;
  out["host"] = host_facts();

  // LiDAR: sweeps of a car moving at 10 m/s along the start straight, with the VLP-16's realism
  // (the default) and as the ideal sensor (`sensors.realism: off`)
  for (const bool realism : {true, false}) {
    sensors::LidarConfig config;
    if (!realism) config.clear_realism();
    sensors::Lidar lidar(config, track);
    sensors::PoseHistory poses(2 * core::kUsPerSecond);
    for (core::TimeUs t = 0; t <= 200'000; t += 1000) {
      core::Pose3 p;
      p.position = {track.start.x + 10.0 * core::to_seconds(t), track.start.y, 0.0};
      poses.push(t, p);
    }
    core::Rng rng(1);
    std::vector<double> ms, mrays;
    lidar.sweep(0, poses, rng);  // warm-up
    for (int i = 0; i < std::max(repeats, 5) * 4; ++i) {
      const auto start = clock::now();
      const auto scan = lidar.sweep(0, poses, rng);
      const double elapsed = ms_since(start);
      ms.push_back(elapsed);
      mrays.push_back(static_cast<double>(scan.stats.rays) / (elapsed * 1e3));
    }
    const std::string suffix = realism ? "" : "_ideal";
    out["lidar_scan_ms" + suffix] = spread(ms)["median"];
    out["lidar_mrays_per_s" + suffix] = spread(mrays)["median"];
    out["lidar_scan_ms_spread" + suffix] = spread(ms);
  }

  // stereo: two 640x480 frames of the car at the start, with the sensor's noise, lens, the
  // asphalt's grain, the sun with its shadows and the exposure's motion blur (the default; the
  // car stands, so the blur's pass finds nothing to smear), with the sun's shadows and the
  // noise only, and without any of them (`sensors.realism: off`)
  enum class Look { kRealistic, kShadowsNoise, kIdeal };
  for (const Look look : {Look::kRealistic, Look::kShadowsNoise, Look::kIdeal}) {
    VehicleSim car(vehicle_models::VehicleParams{}, track.start.compose({-2.25, 0.0, 0.0}));
    sensors::StereoCameraConfig config;
    if (look == Look::kIdeal) config.response.full_well_e = 0.0;
    if (look != Look::kIdeal) config.sun_diffuse = sensors::kTypicalSunDiffuse;
    if (look == Look::kRealistic) {
      config.distortion = sensors::kTypicalLensDistortion;
      config.ground_texture = true;
      config.exposure_time_ms = sensors::kTypicalExposureTimeMs;
    }
    sensors::StereoCamera camera(config, car.model(), track);
    core::StereoFrame frame;
    core::StereoLabels labels;
    camera.render(car.data(), car.vehicle_pose3(), 0, {}, false, frame, labels);  // warm-up
    std::vector<double> ms;
    for (int i = 0; i < std::max(repeats, 5) * 2; ++i) {
      const auto start = clock::now();
      camera.render(car.data(), car.vehicle_pose3(), 0, {}, false, frame, labels);
      ms.push_back(ms_since(start));
    }
    const std::string suffix = look == Look::kRealistic      ? ""
                               : look == Look::kShadowsNoise ? "_shadows_noise"
                                                             : "_ideal";
    out["stereo_pair_ms" + suffix] = spread(ms)["median"];
    out["stereo_pair_ms_spread" + suffix] = spread(ms);
  }

  // the closed loop: trackdrive (ten laps) without and with the LiDAR at 10 Hz
  if (closed_loop) {
    out["closed_loop_rtf"] = closed_loop_rtf("trackdrive", {"seed=1"}, repeats);
    out["closed_loop_lidar_rtf"] =
        closed_loop_rtf("trackdrive", {"seed=1", "sensors.lidar.enabled=true"}, repeats);
    // GraphSLAM driving from the cone sensor (issue 5's closed loop)
    out["closed_loop_graphslam_rtf"] = closed_loop_rtf("trackdrive-graphslam", {"seed=1"}, repeats);
    // GraphSLAM driving with EKF SLAM and the association variants in shadow (each lane on a
    // thread of its own)
    out["closed_loop_graphslam_shadows_rtf"] = closed_loop_rtf(
        "trackdrive-graphslam",
        {"seed=1", "slam.shadow=[ekf, 'ekf:nn', 'ekf:scnn', 'ekf:jcbb', 'graph:nn', 'graph:jcbb']"},
        repeats);
    // GraphSLAM driving with EKF SLAM and both FastSLAMs (50 particles) in shadow
    out["closed_loop_graphslam_filters_rtf"] = closed_loop_rtf(
        "trackdrive-graphslam", {"seed=1", "slam.shadow=[ekf, fastslam1, fastslam2]"}, repeats);
    // raw data through the loop: the LiDAR front-end feeding GraphSLAM (two laps: mapping and
    // one localised lap), with the shipped VLP-32C and with a VLP-16
    out["closed_loop_lidar_slam_rtf"] =
        closed_loop_rtf("trackdrive-lidar", {"seed=1", "driver.trackdrive_laps=2"}, repeats);
    out["closed_loop_lidar_slam_vlp16_rtf"] = closed_loop_rtf(
        "trackdrive-lidar", {"seed=1", "driver.trackdrive_laps=2", "sensors.lidar.model=vlp16"},
        repeats);
    // the host's speed divides out of these: GraphSLAM's run against the ground-truth run of the
    // same call, the six shadow lanes against GraphSLAM alone
    out["closed_loop_graphslam_vs_ground_truth"] =
        out["closed_loop_graphslam_rtf"].get<double>() / out["closed_loop_rtf"].get<double>();
    out["closed_loop_graphslam_shadows_vs_graphslam"] =
        out["closed_loop_graphslam_shadows_rtf"].get<double>() /
        out["closed_loop_graphslam_rtf"].get<double>();
  }
  note_end_load(out["host"]);
  out["targets"] = {{"lidar_mrays_per_s", ">= 25"},
                    {"stereo_pair_ms", "<= 25"},
                    {"stereo_pair_ms_shadows_noise", "<= 20"},
                    {"closed_loop_lidar_rtf", ">= 30"},
                    {"closed_loop_rtf", ">= 30"},
                    {"closed_loop_graphslam_rtf", ">= 30"},
                    {"closed_loop_graphslam_shadows_rtf", ">= 50"},
                    {"closed_loop_graphslam_filters_rtf", ">= 30"},
                    {"closed_loop_lidar_slam_rtf", ">= 20"}};
  return out;
}

nlohmann::json bench_tracks(const std::vector<int>& cone_counts, int repeats,
                            const std::filesystem::path& keep_dir) {
  namespace fs = std::filesystem;
  using clock = std::chrono::steady_clock;
  const fs::path dir = keep_dir.empty() ? fs::temp_directory_path() /
                                              ("conesim-bench-tracks-" + std::to_string(getpid()))
                                        : keep_dir;
  fs::create_directories(dir);
  nlohmann::json out = {
      {"unit", "seconds, median of repeats"}, {"repeats", repeats}, {"host", host_facts()}};
  nlohmann::json rows = nlohmann::json::array();
  for (BigLayout kind :
       {BigLayout::kClutter, BigLayout::kLong, BigLayout::kRandom, BigLayout::kOutlier}) {
    for (int n : cone_counts) {
      // the layout as a file, as a user hands it in
      const tracks::Track made = big_layout(kind, n, 1);
      const fs::path file = dir / (std::string(to_string(kind)) + "-" + std::to_string(n) + ".csv");
      tracks::write_eufs_csv(made, file);
      const fs::path converted = dir / (file.stem().string() + ".yaml");

      // each command, timed from the file to its output
      const auto median_s = [repeats](const std::function<void()>& f) {
        std::vector<double> t;
        for (int r = 0; r < std::max(1, repeats); ++r) {
          const auto start = clock::now();
          f();
          t.push_back(std::chrono::duration<double>(clock::now() - start).count());
        }
        std::sort(t.begin(), t.end());
        return t[t.size() / 2];
      };
      std::ostringstream sink;
      int cones_read = 0;
      const double validate_s =
          median_s([&] { track_validate({file}, std::nullopt, false, sink, sink); });
      const double info_s = median_s([&] {
        const tracks::Track t = tracks::read_track(file);
        cones_read = static_cast<int>(t.cones.size());
        sink << json_text(track_info(t, std::nullopt));
      });
      const double convert_s =
          median_s([&] { write_track_atomically(tracks::read_track(file), converted); });
      rows.push_back({{"layout", to_string(kind)},
                      {"cones", cones_read},
                      {"validate_s", validate_s},
                      {"info_s", info_s},
                      {"convert_s", convert_s}});
      if (keep_dir.empty()) {
        fs::remove(file);
        fs::remove(converted);
      }
    }
  }
  if (keep_dir.empty()) fs::remove_all(dir);
  out["layouts"] = rows;
  note_end_load(out["host"]);
  out["target"] = "validate under 1 s at 20000 cones";
  return out;
}

namespace {

// the process's resident memory, MB (/proc/self/statm: pages)
double resident_mb() {
  std::ifstream statm("/proc/self/statm");
  long pages_total = 0, pages_resident = 0;
  statm >> pages_total >> pages_resident;
  return static_cast<double>(pages_resident) * static_cast<double>(::sysconf(_SC_PAGESIZE)) / 1e6;
}

// the p-quantile (nearest rank) of a sample; null when empty
nlohmann::json quantile(std::vector<double> v, double q) {
  if (v.empty()) return nullptr;
  std::sort(v.begin(), v.end());
  const size_t rank = static_cast<size_t>(std::ceil(q * static_cast<double>(v.size())));
  return v[std::clamp<size_t>(rank, 1, v.size()) - 1];
}

}  // namespace

nlohmann::json bench_soak(const SoakOptions& o) {
  std::vector<std::string> sets = o.sets;
  sets.push_back("seed=" + std::to_string(o.seed));
  sets.push_back("driver.trackdrive_laps=" + std::to_string(o.laps));
  // room for every lap: two minutes each
  sets.push_back("referee.timeout_trackdrive_total_s=" + std::to_string(120 * o.laps));
  const Scenario s = load_scenario(find_scenario(o.scenario), sets);

  // the process's memory when each lap is counted
  std::vector<double> lap_end_s, lap_rss_mb;
  RunOptions options;
  options.out_dir =
      std::filesystem::temp_directory_path() / ("conesim-soak-" + std::to_string(::getpid()));
  options.plot = false;
  options.on_tick = [&](core::TimeUs t, const RefereeResult& r) {
    while (static_cast<int>(lap_end_s.size()) < r.laps) {
      lap_end_s.push_back(core::to_seconds(t));
      lap_rss_mb.push_back(resident_mb());
    }
  };
  const double rss_start_mb = resident_mb();
  const RunResult r = run_scenario(s, scenario_track(s), options);
  std::filesystem::remove_all(options.out_dir);

  // the SLAM updates of laps [from, to) (1-based), CPU ms
  auto updates_of_laps = [&](int from, int to) {
    const double t0 = from <= 1 ? 0.0 : lap_end_s[static_cast<size_t>(from - 2)];
    const double t1 = lap_end_s[static_cast<size_t>(to - 2)];
    std::vector<double> ms;
    for (const auto& [t_s, cpu_ms] : r.slam_update_cpu_ms)
      if (t_s >= t0 && t_s < t1) ms.push_back(cpu_ms);
    return ms;
  };
  nlohmann::json per_lap = nlohmann::json::array();
  for (size_t k = 0; k < lap_end_s.size(); ++k) {
    const std::vector<double> ms =
        updates_of_laps(static_cast<int>(k) + 1, static_cast<int>(k) + 2);
    per_lap.push_back({{"lap", k + 1},
                       {"end_s", lap_end_s[k]},
                       {"rss_mb", lap_rss_mb[k]},
                       {"slam_updates", ms.size()},
                       {"slam_update_cpu_ms_p99", quantile(ms, 0.99)}});
  }
  nlohmann::json out = {{"scenario", o.scenario},
                        {"seed", o.seed},
                        {"laps", r.referee.laps},
                        {"completed", r.referee.completed},
                        {"dnf_reason", r.referee.dnf_reason},
                        {"cones_hit", r.referee.cones_hit.size()},
                        {"off_course", r.referee.off_course},
                        {"sim_time_s", r.sim_time_s},
                        {"wall_time_s", r.wall_time_s},
                        {"rss_start_mb", rss_start_mb},
                        {"per_lap", per_lap}};
  const int n = static_cast<int>(lap_end_s.size());
  // the SLAM update's p99 and the memory by decade of laps (1-10, 11-20, ...)
  nlohmann::json by_decade = nlohmann::json::array();
  for (int from = 1; from + 9 <= n; from += 10)
    by_decade.push_back(
        {{"laps", std::to_string(from) + "-" + std::to_string(from + 9)},
         {"slam_update_cpu_ms_p99", quantile(updates_of_laps(from, from + 10), 0.99)},
         {"rss_mb_at_end", lap_rss_mb[static_cast<size_t>(from + 8)]}});
  out["by_decade"] = by_decade;
  if (n >= 20) {
    const double first = lap_rss_mb[9], last = lap_rss_mb[static_cast<size_t>(n - 1)];
    out["rss_lap10_mb"] = first;
    out["rss_last_lap_mb"] = last;
    out["rss_growth_fraction"] = last / first - 1.0;
    const nlohmann::json p_first = quantile(updates_of_laps(1, 11), 0.99);
    const nlohmann::json p_last = quantile(updates_of_laps(n - 9, n + 1), 0.99);
    out["slam_update_cpu_ms_p99_first10"] = p_first;
    out["slam_update_cpu_ms_p99_last10"] = p_last;
    if (p_first.is_number() && p_last.is_number())
      out["slam_update_p99_ratio"] = p_last.get<double>() / p_first.get<double>();
  }
  out["targets"] = {{"rss_growth_fraction", "<= 0.10 (the last lap's RSS within 10 % of lap 10's)"},
                    {"slam_update_p99_ratio", "<= 1.25 (last ten laps' p99 over the first ten's)"}};
  return out;
}

}  // namespace conesim::sim
