// The soak: a 100-lap trackdrive with the LiDAR and GraphSLAM holds its memory and its SLAM
// update time from the tenth lap to the last (`conesim bench soak`).

#include <gtest/gtest.h>

#include "sim/bench.hpp"

namespace conesim::sim {
namespace {

TEST(Soak, HundredLidarGraphSlamLapsHoldMemoryAndUpdateTime) {
  SoakOptions options;
  options.laps = 100;
  const nlohmann::json soak = bench_soak(options);
  ASSERT_TRUE(soak["completed"].get<bool>()) << soak["dnf_reason"];
  EXPECT_EQ(soak["laps"].get<int>(), 100);
  // memory after lap 100 within 10 % of lap 10's
  EXPECT_LE(soak["rss_growth_fraction"].get<double>(), 0.10) << soak.dump(1);
  // the SLAM update's p99 (CPU time, which other processes do not inflate) of the last ten laps
  // against the first ten's (mapping included: localising laps cost less)
  EXPECT_LE(soak["slam_update_p99_ratio"].get<double>(), 1.25) << soak.dump(1);
}

}  // namespace
}  // namespace conesim::sim
