// The closed loop end to end: MuJoCo car, referee, ground-truth perception and the driver.

#include <gtest/gtest.h>

#include <fstream>

#include "sim/run.hpp"
#include "sim/scenario.hpp"

namespace conesim::sim {
namespace {

namespace fs = std::filesystem;

// runs a shipped scenario into a temporary folder, without the PNG
RunResult run_shipped(const std::string& name, uint64_t seed, const std::string& tag,
                      const std::vector<std::string>& sets = {}) {
  std::vector<std::string> overrides = sets;
  overrides.push_back("seed=" + std::to_string(seed));
  const Scenario s = load_scenario(find_scenario(name), overrides);
  RunOptions options;
  options.out_dir =
      fs::temp_directory_path() / ("conesim-closed-loop-" + tag + "-" + std::to_string(::getpid()));
  options.plot = false;
  RunResult r = run_scenario(s, scenario_track(s), options);
  EXPECT_TRUE(fs::exists(options.out_dir / "metrics.json"));
  EXPECT_TRUE(fs::exists(options.out_dir / "trajectory.csv"));
  EXPECT_TRUE(fs::exists(options.out_dir / "track.csv"));
  fs::remove_all(options.out_dir);
  return r;
}

// metrics without the keys that depend on the machine's speed
nlohmann::json without_timing(nlohmann::json m) {
  m.erase("wall_time_s");
  m.erase("real_time_factor");
  return m;
}

TEST(ClosedLoop, AccelerationCompletesInARealisticTime) {
  const RunResult r = run_shipped("acceleration", 1, "accel");
  EXPECT_TRUE(r.referee.completed) << r.referee.dnf_reason;
  EXPECT_TRUE(r.referee.cones_hit.empty());
  // 75 m from a standing start: 3.5-4.5 s for real FS cars, 3.75 s for this car at full power
  EXPECT_GT(r.referee.raw_time_s, 3.5);
  EXPECT_LT(r.referee.raw_time_s, 4.6);
  EXPECT_TRUE(r.passed);
}

TEST(ClosedLoop, SkidpadCompletesFourLapsWithoutPenalties) {
  const RunResult r = run_shipped("skidpad", 1, "skidpad");
  EXPECT_TRUE(r.referee.completed) << r.referee.dnf_reason;
  EXPECT_EQ(r.referee.lap_times_s.size(), 4u);
  EXPECT_TRUE(r.referee.cones_hit.empty());
  EXPECT_EQ(r.referee.off_course, 0);
}

TEST(ClosedLoop, SkidpadLocalisesOnItsKnownLayout) {
  // the layout is the prior map: every association is to a known cone, checked by its id
  const RunResult r = run_shipped("skidpad-graphslam", 1, "skidpad-slam");
  EXPECT_TRUE(r.referee.completed) << r.referee.dnf_reason;
  EXPECT_TRUE(r.referee.cones_hit.empty());
  const nlohmann::json& g = r.metrics["slam"]["graph"];
  EXPECT_EQ(g["phase"].get<std::string>(), "localisation");
  EXPECT_GE(g["da_correct_fraction"].get<double>(), 0.99);
  EXPECT_LE(g["ate_rmse_m"].get<double>(), 0.15);
  EXPECT_TRUE(r.passed);
}

TEST(ClosedLoop, SlamPassCriteriaFailTheRun) {
  // a run that drives well but whose map misses the scenario's bound does not pass, and says why
  const RunResult r =
      run_shipped("acceleration-graphslam", 1, "slam-pass", {"pass.max_map_rmse_m=0.001"});
  EXPECT_TRUE(r.referee.completed) << r.referee.dnf_reason;
  EXPECT_FALSE(r.passed);
  ASSERT_EQ(r.failures.size(), 1u);
  EXPECT_NE(r.failures[0].find("SLAM map RMSE"), std::string::npos) << r.failures[0];
}

// the generated hard-profile circuit of a seed, driven `laps` laps of the shipped trackdrive
// (ground truth) without a cone hit or an off-course
void expect_clean_hard_trackdrive(uint64_t seed, int laps) {
  const RunResult r = run_shipped(
      "trackdrive", seed, "hard-" + std::to_string(seed),
      {"track.generate.profile=hard", "driver.trackdrive_laps=" + std::to_string(laps)});
  EXPECT_TRUE(r.referee.completed) << r.referee.dnf_reason;
  EXPECT_TRUE(r.referee.cones_hit.empty()) << r.referee.cones_hit.size() << " cones hit";
  EXPECT_EQ(r.referee.off_course, 0);
}

TEST(ClosedLoop, ExplorationTurnsIntoAMinimumHairpinWithoutUnwindingTheLock) {
  // generated hard circuit 7177: lap 1 meets a hairpin of 9.45 m outside diameter (cone
  // centres) at the end of a straight. The manoeuvre search turned in at full lock, then, its
  // model turning a little tighter than the car, chose "straight for 0.1 s, then lock" on one
  // tick and lock on the next for 0.4 s: the steering flipped between 0.25 and 0.63 rad, the
  // car turned in 0.35 m late and knocked three outer cones. A turn under way is now never
  // straightened first (control/manoeuvre.cpp, kCommittedSteerShare)
  expect_clean_hard_trackdrive(7177, 1);
}

TEST(ClosedLoop, FastLapsLeaveATurnWithTheGripTheTurnLeaves) {
  // generated hard circuit 7051, lap 3: out of a turn the car lagged its speed profile, the
  // speed command's P-term asked its 15 m/s^2 cap with the steering still near the tyres'
  // limit, the car ran 0.2 m wide and its rear corner knocked a cone of a 3.3 m lane at
  // 13.8 m/s. The drive out of a turn is now what the turn leaves of the grip
  // (control/driver.cpp, exit_accel_cap)
  expect_clean_hard_trackdrive(7051, 3);
}

TEST(ClosedLoop, AutocrossIsDeterministicBySeed) {
  const RunResult a = run_shipped("autocross", 2, "a");
  const RunResult b = run_shipped("autocross", 2, "b");
  EXPECT_TRUE(a.referee.completed) << a.referee.dnf_reason;
  EXPECT_TRUE(a.passed);
  EXPECT_EQ(without_timing(a.metrics), without_timing(b.metrics));
  // a different seed is a different circuit
  const RunResult c = run_shipped("autocross", 3, "c");
  EXPECT_NE(a.metrics["track"], c.metrics["track"]);
}

}  // namespace
}  // namespace conesim::sim

namespace conesim::sim {
namespace {

TEST(ClosedLoop, AutocrossDrivesOnTheGraphSlamEstimate) {
  // the driver sees only the SLAM estimate built from the noisy cone sensor and odometry
  const RunResult r = run_shipped("autocross", 1, "slam", {"perception=cone_sensor", "slam=graph"});
  EXPECT_TRUE(r.referee.completed) << r.referee.dnf_reason;
  EXPECT_TRUE(r.referee.cones_hit.empty());
  const nlohmann::json& g = r.metrics["slam"]["graph"];
  // issue 5 targets that hold in the loop: map error, associations, one true loop closure
  EXPECT_LE(g["map_rmse_m"].get<double>(), 0.15);
  EXPECT_GE(g["da_correct_fraction"].get<double>(), 0.99);
  EXPECT_EQ(g["loop_closures"].get<int>(), 1);
  EXPECT_EQ(g["false_loop_closures"].get<int>(), 0);
  EXPECT_EQ(g["phase"].get<std::string>(), "localisation");
  EXPECT_EQ(g["map_spurious"].get<int>(), 0);
}

}  // namespace
}  // namespace conesim::sim

namespace conesim::sim {
namespace {

TEST(ClosedLoop, DumpsLidarCameraAndDetectionsBesideTheRun) {
  const Scenario s = load_scenario(find_scenario("acceleration"), {"seed=1"});
  RunOptions options;
  options.out_dir = fs::temp_directory_path() / ("conesim-dump-" + std::to_string(::getpid()));
  options.plot = false;
  options.dump.sensors = {"lidar", "camera", "detections"};
  options.dump.every = 25;
  options.dump.review_png = false;
  const RunResult r = run_scenario(s, scenario_track(s), options);
  EXPECT_TRUE(r.referee.completed) << r.referee.dnf_reason;
  const fs::path images = options.out_dir / "images";

  // the first LiDAR sweep: a PCD with the documented fields and a sidecar
  std::ifstream pcd(images / "lidar/000000.pcd");
  std::string line, fields;
  while (std::getline(pcd, line))
    if (line.rfind("FIELDS", 0) == 0) fields = line;
  EXPECT_EQ(fields, "FIELDS x y z intensity ring time label");
  EXPECT_TRUE(fs::exists(images / "lidar/000000.json"));
  // the camera pair and its calibration, the detections with their labels
  EXPECT_TRUE(fs::exists(images / "camera/left/000000.png"));
  EXPECT_TRUE(fs::exists(images / "camera/right/000000.png"));
  nlohmann::json cam, det;
  std::ifstream(images / "camera/000000.json") >> cam;
  EXPECT_GT(cam["intrinsics"]["fx"].get<double>(), 100.0);
  EXPECT_NEAR(cam["baseline_m"].get<double>(), 0.12, 1e-9);
  std::ifstream(images / "detections/000000.json") >> det;
  EXPECT_FALSE(det["cones"].empty());
  EXPECT_TRUE(det["cones"][0].contains("true_cone_id"));
  EXPECT_GT(r.metrics["sensors"]["lidar_scans"].get<int>(), 0);
  fs::remove_all(options.out_dir);
}

}  // namespace
}  // namespace conesim::sim
