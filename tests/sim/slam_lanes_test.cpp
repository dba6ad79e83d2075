// SLAM lanes in the closed loop: shadow back-ends get the driving one's input, are scored, and
// never change the run; every lane's figures and estimate columns are written.

#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <sstream>

#include "sim/run.hpp"
#include "sim/scenario.hpp"

namespace conesim::sim {
namespace {

namespace fs = std::filesystem;

struct LaneRun {
  RunResult result;
  std::vector<std::string> trajectory;  // trajectory.csv's lines
};

// two laps of the shipped GraphSLAM trackdrive (the loop closes, then localisation)
LaneRun run_trackdrive(const std::vector<std::string>& sets, const std::string& tag) {
  std::vector<std::string> overrides = {"driver.trackdrive_laps=2"};
  overrides.insert(overrides.end(), sets.begin(), sets.end());
  const Scenario s = load_scenario(find_scenario("trackdrive-graphslam"), overrides);
  RunOptions options;
  options.out_dir =
      fs::temp_directory_path() / ("conesim-lanes-" + tag + "-" + std::to_string(::getpid()));
  options.plot = false;
  LaneRun run;
  run.result = run_scenario(s, scenario_track(s), options);
  std::ifstream in(options.out_dir / "trajectory.csv");
  for (std::string line; std::getline(in, line);) run.trajectory.push_back(line);
  fs::remove_all(options.out_dir);
  return run;
}

// the first n comma-separated fields of a line
std::string first_fields(const std::string& line, int n) {
  std::string out;
  std::stringstream ss(line);
  std::string field;
  for (int k = 0; k < n && std::getline(ss, field, ','); ++k) out += field + ",";
  return out;
}

// a lane's figures without those that depend on the machine's speed
nlohmann::json without_timing(nlohmann::json m) {
  for (const char* key : {"update_ms_median", "update_ms_p99", "update_cpu_ms_median",
                          "update_cpu_ms_p99", "association_us_median", "association_us_p99"})
    m.erase(key);
  return m;
}

// the car drove the same with the shadows as without: every row's truth, command and driving
// estimate to the last digit, and the driving lane's figures
void expect_same_drive(const LaneRun& alone, const LaneRun& shadowed) {
  ASSERT_EQ(alone.trajectory.size(), shadowed.trajectory.size());
  for (size_t i = 1; i < alone.trajectory.size(); ++i)
    ASSERT_EQ(first_fields(alone.trajectory[i], 10), first_fields(shadowed.trajectory[i], 10))
        << "row " << i;
  EXPECT_EQ(without_timing(alone.result.metrics["slam"]["graph"]),
            without_timing(shadowed.result.metrics["slam"]["graph"]));
}

TEST(SlamLanes, ShadowsAreScoredAndLeaveTheDrivenTrajectoryBitIdentical) {
  const LaneRun alone = run_trackdrive({}, "alone");
  const LaneRun shadowed =
      run_trackdrive({"slam.shadow=[ekf, 'ekf:jcbb', 'graph:nn', 'ekf:ideal']"}, "shadowed");
  ASSERT_TRUE(alone.result.referee.completed);

  // the car drove the same: every row's truth, command and driving estimate to the last digit
  ASSERT_EQ(alone.trajectory.size(), shadowed.trajectory.size());
  for (size_t i = 1; i < alone.trajectory.size(); ++i)
    ASSERT_EQ(first_fields(alone.trajectory[i], 10), first_fields(shadowed.trajectory[i], 10))
        << "row " << i;
  EXPECT_EQ(alone.result.referee.final_time_s, shadowed.result.referee.final_time_s);
  EXPECT_EQ(without_timing(alone.result.metrics["slam"]["graph"]),
            without_timing(shadowed.result.metrics["slam"]["graph"]));

  // each shadow has its figures and its estimate columns
  const nlohmann::json& slam = shadowed.result.metrics["slam"];
  for (const char* lane : {"ekf", "ekf-jcbb", "graph-nn", "ekf-ideal"}) {
    ASSERT_TRUE(slam.contains(lane)) << lane;
    EXPECT_EQ(slam[lane]["role"], "shadow");
    EXPECT_GT(slam[lane]["updates"].get<int>(), 500) << lane;
    EXPECT_FALSE(slam[lane]["association_us_median"].is_null()) << lane;
  }
  EXPECT_EQ(slam["graph"]["role"], "drive");
  EXPECT_EQ(shadowed.result.metrics["slam_shadows"],
            nlohmann::json::array({"ekf", "ekf-jcbb", "graph-nn", "ekf-ideal"}));
  // the labels reached the ideal lane only, and its figures say so
  EXPECT_TRUE(slam["ekf-ideal"]["ideal_association"].get<bool>());
  EXPECT_EQ(slam["ekf-ideal"]["association"], "ideal");
  EXPECT_EQ(slam["ekf-ideal"]["da_wrong"].get<int>(), 0);
  for (const char* lane : {"graph", "ekf", "ekf-jcbb", "graph-nn"})
    EXPECT_FALSE(slam[lane]["ideal_association"].get<bool>()) << lane;
  EXPECT_EQ(slam["ekf-jcbb"]["association"], "jcbb");
  EXPECT_NE(shadowed.trajectory[0].find(",ekf_x_m,ekf_y_m,ekf_yaw_rad,ekf-jcbb_x_m"),
            std::string::npos);
  // EKF SLAM in shadow meets the map and association targets of the GraphSLAM scenario
  EXPECT_LE(slam["ekf"]["map_rmse_m"].get<double>(), 0.15);
  EXPECT_GE(slam["ekf"]["da_correct_fraction"].get<double>(), 0.99);
  EXPECT_EQ(slam["ekf"]["loop_closures"].get<int>(), 1);
  EXPECT_EQ(slam["ekf"]["false_loop_closures"].get<int>(), 0);
  EXPECT_EQ(slam["ekf"]["phase"], "localisation");
}

TEST(SlamLanes, FastSlamShadowsLeaveTheDrivenTrajectoryBitIdenticalAndNameTheirParticle) {
  const LaneRun alone = run_trackdrive({"driver.trackdrive_laps=1"}, "fs-alone");
  const LaneRun shadowed = run_trackdrive(
      {"driver.trackdrive_laps=1", "slam.shadow=[fastslam1, fastslam2]"}, "fs-shadowed");
  ASSERT_TRUE(alone.result.referee.completed);
  expect_same_drive(alone, shadowed);
  const nlohmann::json& slam = shadowed.result.metrics["slam"];
  EXPECT_EQ(slam["graph"]["estimate_source"], "state");
  for (const char* lane : {"fastslam1", "fastslam2"}) {
    ASSERT_TRUE(slam.contains(lane)) << lane;
    EXPECT_EQ(slam[lane]["role"], "shadow");
    // the map a particle filter reports is its best particle's, and metrics.json says so
    EXPECT_NE(slam[lane]["estimate_source"].get<std::string>().find("best particle"),
              std::string::npos)
        << lane;
    EXPECT_EQ(slam[lane]["backend_stats"]["particles"].get<double>(), 50.0) << lane;
    EXPECT_GT(slam[lane]["backend_stats"]["resamplings"].get<double>(), 0.0) << lane;
    EXPECT_GE(slam[lane]["da_correct_fraction"].get<double>(), 0.99) << lane;
  }
}

TEST(SlamLanes, AblationShadowsLeaveTheDrivenTrajectoryBitIdenticalAndSayWhatTheyAre) {
  const std::string lanes =
      "slam.shadow=[odometry, 'odometry:none', 'graph:ideal+global_only', "
      "graph+no_landmark_edges, graph+no_icr, 'graph:none', ekf, ekf+no_preliminary]";
  const LaneRun alone = run_trackdrive({}, "abl-alone");
  const LaneRun shadowed = run_trackdrive({lanes}, "abl-shadowed");
  ASSERT_TRUE(alone.result.referee.completed);
  expect_same_drive(alone, shadowed);
  const nlohmann::json& slam = shadowed.result.metrics["slam"];
  using nlohmann::json;
  EXPECT_EQ(slam["graph"]["ablations"], json::array());
  EXPECT_EQ(slam["graph-ideal+global_only"]["ablations"], json::array({"global_only"}));
  EXPECT_EQ(slam["graph+no_landmark_edges"]["ablations"], json::array({"no_landmark_edges"}));
  EXPECT_EQ(slam["graph+no_icr"]["ablations"], json::array({"no_icr"}));
  EXPECT_EQ(slam["graph-none"]["ablations"], json::array({"no_association"}));
  EXPECT_EQ(slam["ekf+no_preliminary"]["ablations"], json::array({"no_preliminary"}));
  EXPECT_EQ(slam["odometry"]["association"], "nn");

  // dead reckoning: no loop closure, yet every cone in view mapped
  EXPECT_EQ(slam["odometry"]["loop_closures"].get<int>(), 0);
  EXPECT_EQ(slam["odometry"]["phase"], "mapping");
  EXPECT_LE(slam["odometry"]["map_missed_fraction"].get<double>(), 0.05);
  // no association: every observation a landmark, far more than there are cones in view
  for (const char* lane : {"odometry-none", "graph-none"}) {
    const int landmarks =
        slam[lane]["map_matched"].get<int>() + slam[lane]["map_spurious"].get<int>();
    EXPECT_GT(landmarks, 10 * slam[lane]["map_cones_in_view"].get<int>()) << lane;
    EXPECT_TRUE(slam[lane]["da_correct_fraction"].is_null()) << lane;
  }
  // the RaceUp simulator set-up: labels pair, the graph is solved once, at the loop closure
  EXPECT_EQ(slam["graph-ideal+global_only"]["da_wrong"].get<int>(), 0);
  EXPECT_EQ(slam["graph-ideal+global_only"]["loop_closures"].get<int>(), 1);
  EXPECT_LE(slam["graph-ideal+global_only"]["map_rmse_m"].get<double>(), 0.15);
  // poses and loop closure only: the loop still closes, and closing it leaves the path better
  // than dead reckoning's, the map not as good as the full graph's (the lap's drift is spread
  // along the odometry, not pulled onto the cones). Its map is not reliably better than dead
  // reckoning's: 0.259 against 0.253 m on this run once the driver's racing line changed
  const json& pose_only = slam["graph+no_landmark_edges"];
  EXPECT_EQ(pose_only["loop_closures"].get<int>(), 1);
  EXPECT_LT(pose_only["ate_rmse_m"].get<double>(), slam["odometry"]["ate_rmse_m"].get<double>());
  EXPECT_GT(pose_only["map_rmse_m"].get<double>(), slam["graph"]["map_rmse_m"].get<double>());
  // the preliminary list keeps candidates out of the filter, and says how many
  EXPECT_GT(slam["ekf"]["backend_stats"]["preliminary_dropped"].get<double>(), 0.0);
  EXPECT_EQ(slam["ekf+no_preliminary"]["backend_stats"]["preliminary_dropped"].get<double>(), 0.0);
  EXPECT_GT(slam["ekf+no_preliminary"]["backend_stats"]["landmarks"].get<double>(),
            slam["ekf"]["backend_stats"]["landmarks"].get<double>());
  // the map error over distance is in metrics.json for every lane
  EXPECT_GT(slam["odometry"]["map_error_over_distance"].size(), 10u);
}

TEST(SlamLanes, ShadowFiguresAreTheSameOnEveryRun) {
  // the shadows run on threads of their own: their figures must not depend on the timing
  const LaneRun a = run_trackdrive({"slam.shadow=[ekf]", "driver.trackdrive_laps=1"}, "a");
  const LaneRun b = run_trackdrive({"slam.shadow=[ekf]", "driver.trackdrive_laps=1"}, "b");
  EXPECT_EQ(without_timing(a.result.metrics["slam"]["ekf"]),
            without_timing(b.result.metrics["slam"]["ekf"]));
  EXPECT_EQ(a.trajectory, b.trajectory);
}

TEST(SlamLanes, EkfSlamDrivesTrackdriveWithoutPenalties) {
  const LaneRun run = run_trackdrive({"slam.drive=ekf"}, "ekf");
  const RunResult& r = run.result;
  EXPECT_TRUE(r.referee.completed) << r.referee.dnf_reason;
  EXPECT_EQ(r.referee.cones_hit.size(), 0u);
  EXPECT_EQ(r.referee.off_course, 0);
  // (the trajectory RMSE of two laps is mostly lap one's drift: the ten-lap scenario's
  // criterion is checked on ten seeds in slam_lanes_slow_test.cpp)
  EXPECT_LE(r.metrics["slam"]["ekf"]["map_rmse_m"].get<double>(), 0.15);
  EXPECT_GE(r.metrics["slam"]["ekf"]["da_correct_fraction"].get<double>(), 0.99);
  EXPECT_EQ(r.metrics["slam_driving"], "ekf");
  EXPECT_EQ(r.metrics["slam"]["ekf"]["role"], "drive");
}

}  // namespace
}  // namespace conesim::sim
