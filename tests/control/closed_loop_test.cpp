// The driver in a closed loop with a kinematic bicycle on the FSG layouts and generated
// circuits: every mission finishes without touching a cone.

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>

#include "kinematic_loop.hpp"
#include "tracks/fsg_layouts.hpp"
#include "tracks/generator.hpp"

namespace conesim::control {
namespace {

using testing::LoopResult;
using testing::run_loop;

// the footprint may not come closer to a cone than this (a hit is 0), metres
constexpr double kMinClearanceM = 0.15;

// prints the figures of a run for the report
void print(const char* name, const LoopResult& r) {
  std::printf(
      "%s: finished %d in %.2f s, laps %d, cones hit %d, min clearance %.3f m, "
      "max deviation %.3f m (at %.1f %.1f, t %.2f s), footprint outside the lanes %.3f m (at "
      "%.1f %.1f), max speed %.2f m/s\n",
      name, r.finished, r.time_s, r.laps_counted, r.cones_hit, r.min_clearance_m, r.max_deviation_m,
      r.max_deviation_at.x(), r.max_deviation_at.y(), r.max_deviation_time_s, r.max_outside_m,
      r.max_outside_at.x(), r.max_outside_at.y(), r.max_speed_mps);
}

// lap times from the crossings of one gate
std::vector<double> lap_times(const std::vector<double>& crossings) {
  std::vector<double> laps;
  for (size_t i = 1; i < crossings.size(); ++i) laps.push_back(crossings[i] - crossings[i - 1]);
  return laps;
}

TEST(ClosedLoop, AccelerationStopsInsideTheBrakingZone) {
  const tracks::Track track = tracks::make_acceleration();
  const LoopResult r = run_loop(track, core::EventType::kAcceleration, DriverParams{});
  print("acceleration", r);
  ASSERT_EQ(track.timing_gates.size(), 2u);
  ASSERT_EQ(r.gate_crossings[0].size(), 1u);
  ASSERT_EQ(r.gate_crossings[1].size(), 1u);
  std::printf("acceleration: 75 m in %.3f s\n", r.gate_crossings[1][0] - r.gate_crossings[0][0]);

  EXPECT_TRUE(r.finished);
  EXPECT_EQ(r.cones_hit, 0);
  EXPECT_GT(r.min_clearance_m, kMinClearanceM);
  // the whole car stands between the finish line and the end of the braking zone
  const double front_x = r.final_pose.transform({2.25, 0.0}).x();
  const double rear_x = r.final_pose.transform({-0.65, 0.0}).x();
  EXPECT_GT(rear_x, tracks::kAccelerationLengthM);
  EXPECT_LT(front_x, tracks::kAccelerationLengthM + tracks::kAccelerationBrakingZoneM);
}

TEST(ClosedLoop, SkidpadDrivesTwoRightAndTwoLeftLapsAndStops) {
  const tracks::Track track = tracks::make_skidpad();
  std::vector<core::MapCone> prior;
  for (const tracks::Cone& c : track.cones)
    prior.push_back({c.id, c.cls, c.position, Eigen::Matrix2d::Identity() * 0.01});
  const LoopResult r = run_loop(track, core::EventType::kSkidpad, DriverParams{}, {}, prior);
  print("skidpad", r);
  ASSERT_EQ(track.timing_gates.size(), 1u);
  const std::vector<double> laps = lap_times(r.gate_crossings[0]);
  for (double t : laps) std::printf("skidpad lap %.3f s\n", t);

  EXPECT_TRUE(r.finished);
  EXPECT_EQ(r.laps_counted, 4);
  // entry plus four laps end on the timing line
  EXPECT_EQ(r.gate_crossings[0].size(), 5u);
  EXPECT_EQ(r.cones_hit, 0);
  EXPECT_GT(r.min_clearance_m, kMinClearanceM);
  // the car stops on the exit lane, before the stop line 21 m past the timing line
  const double timing_x = tracks::kSkidpadStartToTimingLineM;
  EXPECT_GT(r.final_pose.x, timing_x + 5.0);
  EXPECT_LT(r.final_pose.transform({2.25, 0.0}).x(), timing_x + 21.0 - 0.5);
  EXPECT_NEAR(r.final_pose.y, 0.0, 0.5);
}

// the circuit events on generated tracks
class ClosedLoopCircuit : public ::testing::TestWithParam<uint64_t> {};

TEST_P(ClosedLoopCircuit, AutocrossExploresOneLapAndStops) {
  tracks::GeneratorParams gp;
  gp.event = core::EventType::kAutocross;
  const tracks::Track track = tracks::generate_circuit(GetParam(), gp);
  const LoopResult r = run_loop(track, core::EventType::kAutocross, DriverParams{});
  print(("autocross seed " + std::to_string(GetParam())).c_str(), r);
  const std::vector<double> laps = lap_times(r.gate_crossings[0]);
  for (double t : laps) std::printf("autocross lap %.3f s\n", t);

  EXPECT_TRUE(r.finished);
  EXPECT_EQ(r.laps_counted, 1);
  EXPECT_EQ(laps.size(), 1u);
  EXPECT_EQ(r.cones_hit, 0);
  EXPECT_GT(r.min_clearance_m, kMinClearanceM);
  // the whole car stays between the lanes
  EXPECT_EQ(r.max_outside_m, 0.0);
}

TEST_P(ClosedLoopCircuit, TrackdriveCountsTenLapsAndStops) {
  const tracks::Track track = tracks::generate_circuit(GetParam());
  const DriverParams params;
  const LoopResult r = run_loop(track, core::EventType::kTrackdrive, params);
  print(("trackdrive seed " + std::to_string(GetParam())).c_str(), r);
  const std::vector<double> laps = lap_times(r.gate_crossings[0]);
  for (double t : laps) std::printf("trackdrive lap %.3f s\n", t);

  EXPECT_TRUE(r.finished);
  EXPECT_EQ(r.laps_counted, params.trackdrive_laps);
  EXPECT_EQ(static_cast<int>(laps.size()), params.trackdrive_laps);
  EXPECT_EQ(r.cones_hit, 0);
  EXPECT_GT(r.min_clearance_m, kMinClearanceM);
  EXPECT_EQ(r.max_outside_m, 0.0);
  // the known circuit is driven faster than the exploration lap
  ASSERT_GE(laps.size(), 2u);
  EXPECT_LT(laps[1], laps[0]);
}

TEST(ClosedLoop, ImperfectPerceptionStillDrivesCleanly) {
  // every 11th cone never seen and every 13th seen with the other colour (seed 1; the sweep in
  // closed_loop_slow_test shows where this still fails)
  const tracks::Track track = tracks::generate_circuit(1);
  testing::LoopParams loop;
  loop.missing_every = 11;
  loop.recolour_every = 13;
  DriverParams params;
  params.trackdrive_laps = 3;
  const LoopResult r = run_loop(track, core::EventType::kTrackdrive, params, loop);
  print("imperfect trackdrive seed 1", r);
  for (double t : lap_times(r.gate_crossings[0]))
    std::printf("imperfect trackdrive lap %.3f s\n", t);

  EXPECT_TRUE(r.finished);
  EXPECT_EQ(r.laps_counted, params.trackdrive_laps);
  EXPECT_EQ(r.cones_hit, 0);
  EXPECT_GT(r.min_clearance_m, kMinClearanceM);
}

TEST(ClosedLoop, RacingLineFollowsTheMapWhenALoopClosureMovesIt) {
  // until shortly after lap 1 (SLAM's loop closure lands a few metres past the line) the map
  // has the cones of the track's far half 0.5 m off to one side; then it is right. A racing
  // line kept from the old map would run 0.5 m off the lane there (a footprint margin of 0.3 m)
  const tracks::Track track = tracks::generate_circuit(1);
  double xmin = 1e9, xmax = -1e9;
  for (const tracks::Cone& c : track.cones) {
    xmin = std::min(xmin, c.position.x());
    xmax = std::max(xmax, c.position.x());
  }
  const double x_far = 0.5 * (xmin + xmax);
  double lap1_end_s = -1.0;
  int replans = 0;
  testing::LoopParams loop;
  loop.on_update = [&](double t, const core::Pose2&, const DriverStatus& status) {
    if (lap1_end_s < 0.0 && status.laps_counted >= 1) lap1_end_s = t;
    replans = status.line_replans;
  };
  constexpr double kClosureAfterS = 1.5;
  loop.map_error = [&](double t, const Vec2& p) -> Vec2 {
    const bool closed = lap1_end_s >= 0.0 && t >= lap1_end_s + kClosureAfterS;
    return !closed && p.x() > x_far ? Vec2(0.0, 0.5) : Vec2::Zero();
  };
  DriverParams params;
  params.trackdrive_laps = 3;
  const LoopResult r = run_loop(track, core::EventType::kTrackdrive, params, loop);
  print("trackdrive seed 1, map moved at loop closure", r);

  EXPECT_EQ(replans, 1);  // once, when the map moved; never on the unchanged map after it
  EXPECT_TRUE(r.finished);
  EXPECT_EQ(r.laps_counted, params.trackdrive_laps);
  EXPECT_EQ(r.cones_hit, 0);
  EXPECT_GT(r.min_clearance_m, kMinClearanceM);
}

TEST(ClosedLoop, SameInputsGiveTheSameRun) {
  const tracks::Track track = tracks::generate_circuit(1);
  const LoopResult a = run_loop(track, core::EventType::kAutocross, DriverParams{});
  const LoopResult b = run_loop(track, core::EventType::kAutocross, DriverParams{});
  EXPECT_EQ(a.time_s, b.time_s);
  EXPECT_EQ(a.final_pose.x, b.final_pose.x);
  EXPECT_EQ(a.final_pose.y, b.final_pose.y);
  EXPECT_EQ(a.final_pose.yaw, b.final_pose.yaw);
}

INSTANTIATE_TEST_SUITE_P(Seeds, ClosedLoopCircuit, ::testing::Values(1u, 2u));

}  // namespace
}  // namespace conesim::control
