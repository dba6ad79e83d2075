// EKF SLAM and FastSLAM 2.0 driving the shipped ten-lap GraphSLAM trackdrive on generated circuits
// 1-10: every run completes with no penalty (EKF SLAM also meets the scenario's SLAM criteria).

#include <gtest/gtest.h>
#include <unistd.h>

#include "sim/run.hpp"
#include "sim/scenario.hpp"

namespace conesim::sim {
namespace {

namespace fs = std::filesystem;

TEST(SlamLanesSlow, EkfSlamDrivesTenGeneratedCircuitsWithoutPenalties) {
  for (uint64_t seed = 1; seed <= 10; ++seed) {
    const Scenario s =
        load_scenario(find_scenario("trackdrive-graphslam"), {"slam.drive=ekf"}, seed);
    RunOptions options;
    options.out_dir = fs::temp_directory_path() / ("conesim-ekf-drive-" + std::to_string(seed) +
                                                   "-" + std::to_string(::getpid()));
    options.plot = false;
    const RunResult r = run_scenario(s, scenario_track(s), options);
    fs::remove_all(options.out_dir);
    const nlohmann::json& ekf = r.metrics["slam"]["ekf"];
    std::printf(
        "seed %2llu: %s, %zu cones hit, %d off-course, map RMSE %.3f m, ATE %.3f m, DA %.5f\n",
        static_cast<unsigned long long>(seed), r.referee.completed ? "completed" : "DNF",
        r.referee.cones_hit.size(), r.referee.off_course, ekf["map_rmse_m"].get<double>(),
        ekf["ate_rmse_m"].get<double>(), ekf["da_correct_fraction"].get<double>());
    EXPECT_TRUE(r.referee.completed) << "seed " << seed << ": " << r.referee.dnf_reason;
    EXPECT_EQ(r.referee.cones_hit.size(), 0u) << "seed " << seed;
    EXPECT_EQ(r.referee.off_course, 0) << "seed " << seed;
    EXPECT_TRUE(r.passed) << "seed " << seed << ": "
                          << (r.failures.empty() ? "" : r.failures.front());
  }
}

TEST(SlamLanesSlow, FastSlam2DrivesTenGeneratedCircuitsWithoutPenalties) {
  // the shipped ten-lap trackdrive (mapping lap, then Monte Carlo localisation on the best
  // particle's map) on generated circuits 1-10, FastSLAM 2.0 driving. The map's error limit:
  // FastSLAM does not spread the lap's drift back over the map when the loop closes (GraphSLAM
  // does), so each cone keeps the error of the pose it was mapped from. That pose error is the
  // odometry's drift corrected only by the local map: the graph's own pose error before its
  // closure reaches about 0.35 m on these circuits, and its RMS over the lap is about half that;
  // the cone sensor's noise (5 cm range, 7 mrad bearing, averaged over tens of sightings) adds
  // little. Hence 0.3 m, not the scenario's 0.15 m (set for GraphSLAM), which is not asked here.
  for (uint64_t seed = 1; seed <= 10; ++seed) {
    const Scenario s =
        load_scenario(find_scenario("trackdrive-graphslam"), {"slam.drive=fastslam2"}, seed);
    RunOptions options;
    options.out_dir = fs::temp_directory_path() / ("conesim-fs2-drive-" + std::to_string(seed) +
                                                   "-" + std::to_string(::getpid()));
    options.plot = false;
    const RunResult r = run_scenario(s, scenario_track(s), options);
    fs::remove_all(options.out_dir);
    const nlohmann::json& fs2 = r.metrics["slam"]["fastslam2"];
    std::printf(
        "seed %2llu: %s, %d laps, %zu cones hit, %d off-course, map RMSE %.3f m, ATE %.3f m, "
        "DA %.5f, loop closures %d\n",
        static_cast<unsigned long long>(seed), r.referee.completed ? "completed" : "DNF",
        r.referee.laps, r.referee.cones_hit.size(), r.referee.off_course,
        fs2["map_rmse_m"].get<double>(), fs2["ate_rmse_m"].get<double>(),
        fs2["da_correct_fraction"].get<double>(), fs2["loop_closures"].get<int>());
    EXPECT_TRUE(r.referee.completed) << "seed " << seed << ": " << r.referee.dnf_reason;
    EXPECT_EQ(r.referee.laps, s.referee.trackdrive_laps) << "seed " << seed;
    EXPECT_EQ(r.referee.cones_hit.size(), 0u) << "seed " << seed;
    EXPECT_EQ(r.referee.off_course, 0) << "seed " << seed;
    EXPECT_LE(fs2["map_rmse_m"].get<double>(), 0.3) << "seed " << seed;
    EXPECT_EQ(fs2["loop_closures"].get<int>(), 1) << "seed " << seed;
    EXPECT_EQ(fs2["false_loop_closures"].get<int>(), 0) << "seed " << seed;
  }
}

}  // namespace
}  // namespace conesim::sim
