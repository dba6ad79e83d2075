// The driver on hard constructed circuits in the kinematic loop (with the MuJoCo car's yaw loss
// at large steering angles): FSG minimum hairpins, a wide hairpin, a slalom, a chicane with 3 m
// lanes and a stretch with no right boundary. Trackdrive, three laps: the first explores, the
// others drive the racing line; the footprint never comes near a cone.

#include <gtest/gtest.h>

#include <cstdio>
#include <numbers>

#include "kinematic_loop.hpp"
#include "test_tracks.hpp"

namespace conesim::control {
namespace {

using testing::CentreLine;
using testing::circuit_from_centre;
using testing::LoopResult;
using testing::run_loop;

constexpr double kPi = std::numbers::pi;
// the kinematic loop follows the driver without slip, so the footprint keeps most of the
// planned margin (0.25 m); a hit is 0
constexpr double kMinClearanceM = 0.1;

LoopResult drive(const tracks::Track& track, const char* name) {
  DriverParams params;
  params.trackdrive_laps = 3;
  const LoopResult r = run_loop(track, core::EventType::kTrackdrive, params);
  std::printf(
      "%s: finished %d in %.2f s, laps %d, cones hit %d, min clearance %.3f m, "
      "max speed %.2f m/s\n",
      name, r.finished, r.time_s, r.laps_counted, r.cones_hit, r.min_clearance_m, r.max_speed_mps);
  return r;
}

void expect_clean(const LoopResult& r, double min_clearance_m = kMinClearanceM) {
  EXPECT_TRUE(r.finished);
  EXPECT_EQ(r.laps_counted, 3);
  EXPECT_EQ(r.cones_hit, 0);
  EXPECT_GT(r.min_clearance_m, min_clearance_m);
}

TEST(HardTracks, FsgMinimumHairpins) {
  // 9.0 and 9.2 m outside diameter with 3 m lanes (FSG's minimum, the generator's minimum
  // hairpins): the rear axle turns on 2.9-3.1 m at full lock, concentric with the hairpin, where
  // the outer front corner passes the outer cones with 0.16 m at best; the driver turns in at
  // full lock when its roll-outs say so (control/manoeuvre.hpp). Measured: 0.15 m (9.0 m) and
  // 0.11 m (9.2 m, on the exploration lap, whose exit cones come into view late)
  for (const double radius : {3.0, 3.1}) {
    CentreLine c;
    c.straight(40).arc(radius, kPi).straight(40).arc(radius, kPi);
    expect_clean(drive(circuit_from_centre(c.points(), 3.0, 2.0), "FSG minimum hairpin"), 0.0);
  }
}

TEST(HardTracks, WideHairpin) {
  // 14 m outside diameter with 4 m lanes
  CentreLine c;
  c.straight(40).arc(5.0, kPi).straight(40).arc(5.0, kPi);
  expect_clean(drive(circuit_from_centre(c.points(), 4.0, 2.5), "hairpin 14 m / 4 m"));
}

TEST(HardTracks, Slalom) {
  // 2 m either side every 10 m on a 3.5 m lane (S-bends of 4 m over 10 m), a wide return
  CentreLine c;
  c.straight(15).shift(2.0, 10.0).shift(-4.0, 10.0).shift(4.0, 10.0).shift(-4.0, 10.0);
  c.shift(2.0, 10.0).straight(15).arc(12, kPi).straight(80).arc(12, kPi);
  expect_clean(drive(circuit_from_centre(c.points(), 3.5, 3.0), "slalom"));
}

TEST(HardTracks, ChicaneWithThreeMetreLanes) {
  // a 4 m sideways shift over 10 m and back, 3 m lanes
  CentreLine c;
  c.straight(20).shift(4.0, 10.0).straight(10).shift(-4.0, 10.0).straight(20).arc(12, kPi);
  c.straight(70).arc(12, kPi);
  expect_clean(drive(circuit_from_centre(c.points(), 3.0, 3.0), "chicane"));
}

TEST(HardTracks, StretchWithoutRightBoundary) {
  // no yellow cones for 30 m from the end of a straight into a 12 m turn (its outside)
  CentreLine c;
  c.straight(80).arc(12, kPi).straight(80).arc(12, kPi);
  tracks::Track t = circuit_from_centre(c.points(), 3.5, 3.0, 65.0, 95.0);
  expect_clean(drive(t, "one-sided"));
}

}  // namespace
}  // namespace conesim::control
