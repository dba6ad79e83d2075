// The driver on hard constructed circuits in the kinematic loop (with the MuJoCo car's yaw loss
// at large steering angles): FSG minimum hairpins, a wide hairpin, a slalom, a chicane with 3 m
// lanes and a stretch with no right boundary. Trackdrive, three laps: the first explores, the
// others drive the racing line; the footprint never comes near a cone.

#include <gtest/gtest.h>

#include <cstdio>
#include <limits>
#include <numbers>
#include <string>

#include "control/path_planner.hpp"
#include "control/racing_line.hpp"
#include "kinematic_loop.hpp"
#include "test_tracks.hpp"
#include "tracks/generator.hpp"

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

tracks::Track hard_trackdrive(uint64_t seed) {
  tracks::GeneratorParams g;
  g.profile = tracks::GeneratorProfile::kHard;
  return tracks::generate_circuit(seed, g);
}

// the generated hard-profile trackdrive of a seed, driven clean and inside the lanes throughout
LoopResult drive_hard_trackdrive(uint64_t seed) {
  const std::string name = "hard trackdrive " + std::to_string(seed);
  const LoopResult r = drive(hard_trackdrive(seed), name.c_str());
  expect_clean(r);
  EXPECT_EQ(r.max_outside_m, 0.0) << name << ": outside the lanes at (" << r.max_outside_at.x()
                                  << ", " << r.max_outside_at.y() << ")";
  return r;
}

TEST(HardTracks, FsgMinimumHairpins) {
  // 9.0 and 9.2 m outside diameter with 3 m lanes (FSG's minimum, the generator's minimum
  // hairpins): the rear axle turns on 2.9-3.1 m at full lock, concentric with the hairpin, where
  // the outer front corner passes the outer cones with 0.16 m at best; the driver turns in at
  // full lock when its roll-outs say so (control/manoeuvre.hpp). Measured: 0.16 m (9.0 m) and
  // 0.15 m (9.2 m); 0.15 and 0.11 m while the roll-outs turned in a step before the car
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

TEST(HardTracks, NarrowStretchIsDrivenSlowlyAndClean) {
  // two blue cones pushed in on the first straight leave a 2.3 m gap over 3 m (below the rules' 3
  // m, as in EUFS small_track_2): the fast laps pass it at 7 m/s at most, where they run 20+ m/s
  // elsewhere on the straight, and touch no cone
  CentreLine c;
  c.straight(80).arc(12, kPi).straight(80).arc(12, kPi);
  tracks::Track t = circuit_from_centre(c.points(), 3.5, 3.0);
  int pushed = 0;
  for (tracks::Cone& cone : t.cones)
    if (cone.cls == core::ConeClass::kBlue && cone.position.x() > 38.0 &&
        cone.position.x() < 44.0 && std::abs(cone.position.y() - 1.75) < 0.01)
      cone.position.y() = -1.75 + 2.3, ++pushed;
  ASSERT_EQ(pushed, 2);
  DriverParams params;
  params.trackdrive_laps = 3;
  testing::LoopParams loop;
  double narrow_speed = 0.0, straight_speed = 0.0;
  double fast_clearance = std::numeric_limits<double>::infinity();
  std::vector<core::MapCone> cones;
  for (const tracks::Cone& cone : t.cones)
    cones.push_back({cone.id, cone.cls, cone.position, Eigen::Matrix2d::Zero()});
  const Footprint car{loop.front_m, loop.rear_m, loop.half_width_m, 0.0};
  loop.on_update = [&](double, const core::Pose2& pose, const DriverStatus& status) {
    if (status.state != "fast") return;
    fast_clearance = std::min(fast_clearance, footprint_clearance(pose, cones, car));
    if (std::abs(pose.y) > 3.0) return;
    const double front_x = pose.x + 2.25 * std::cos(pose.yaw);
    if (front_x > 38.0 && pose.x < 44.0)
      narrow_speed = std::max(narrow_speed, status.target_speed_mps);
    if (pose.x > 60.0 && pose.x < 75.0)
      straight_speed = std::max(straight_speed, status.target_speed_mps);
  };
  const LoopResult r = run_loop(t, core::EventType::kTrackdrive, params, loop);
  std::printf(
      "narrow stretch: cones hit %d, min clearance %.3f m (fast laps %.3f m), speed %.1f m/s "
      "there, %.1f after\n",
      r.cones_hit, r.min_clearance_m, fast_clearance, narrow_speed, straight_speed);
  // lap 1 explores on the centre line between the cones in sight (its footprint is not
  // planned: 0.005 m at the gap's exit); the fast laps' line, yawed through a 0.6 m sideways
  // step with 0.34 m of room a side, keeps 0.07 m
  expect_clean(r, 0.0);
  EXPECT_GT(fast_clearance, 0.05);
  EXPECT_LE(narrow_speed, 7.0 + 1e-6);
  EXPECT_GT(straight_speed, 10.0);
}

TEST(HardTracks, FastLapsDriveTheWholeLapWhereTwoPartsOfTheTrackPassClose) {
  // a generated hard trackdrive (seed 7059) where the lanes into and out of a 60 m loop pass 2-3
  // m apart: boundary chains through the whole map close across that gap and leave the loop out.
  // Unchecked, every fast lap cut through the cones there (26.5 s laps against 47 s for lap 1,
  // five cones hit); the driver now keeps only a circuit that passes near all of its own lap 1
  const LoopResult r = drive_hard_trackdrive(7059);
  ASSERT_EQ(r.gate_crossings.size(), 1u);
  ASSERT_GE(r.gate_crossings[0].size(), 4u);
  // the fast laps are as long as lap 1 would allow, not a shortcut's length
  const double lap2 = r.gate_crossings[0][2] - r.gate_crossings[0][1];
  const double lap3 = r.gate_crossings[0][3] - r.gate_crossings[0][2];
  EXPECT_GT(std::min(lap2, lap3), 0.6 * (r.gate_crossings[0][1] - r.gate_crossings[0][0]));
}

TEST(HardTracks, ExplorationFollowsAHairpinTipBesideAnotherPartOfTheTrack) {
  // a generated hard trackdrive (seed 7195) where the outer cones of a minimum hairpin stand 2 m
  // from the blue cones of another part of the track: the inner cones turn by 1.4 rad from link
  // to link, and a chain that could not follow them jumped 9.7 m to a yellow cone of that other
  // part; the exploration's path then crossed the hairpin's outer boundary (in the MuJoCo car:
  // three cones hit, two off-courses, and no lap within the time limit)
  drive_hard_trackdrive(7195);
}

// the cones the exploration plans from: those within 30 m of the car
std::vector<core::MapCone> cones_in_reach(const tracks::Track& track, const core::Pose2& pose) {
  std::vector<core::MapCone> cones;
  for (const tracks::Cone& c : track.cones)
    if ((c.position - pose.position()).norm() <= 30.0) cones.push_back({c.id, c.cls, c.position});
  return cones;
}

// each link of a chain joins cones next to each other along their boundary (or one apart, a
// missed cone), in the direction of travel
void expect_along_lane(const tracks::Track& track, const std::vector<Vec2>& chain,
                       const std::vector<int>& lane, const std::string& name) {
  auto index_of = [&](const Vec2& p) {
    for (size_t i = 0; i < lane.size(); ++i)
      if ((track.cones[static_cast<size_t>(lane[i])].position - p).norm() < 1e-9)
        return static_cast<int>(i);
    return -1;
  };
  for (size_t k = 1; k < chain.size(); ++k) {
    const int a = index_of(chain[k - 1]), b = index_of(chain[k]);
    EXPECT_GE(a, 0);
    EXPECT_GE(b, 0);
    const int n = static_cast<int>(lane.size());
    const int step = ((b - a) % n + n) % n;
    EXPECT_TRUE(step == 1 || step == 2)
        << name << ": link (" << chain[k - 1].x() << ", " << chain[k - 1].y() << ") -> ("
        << chain[k].x() << ", " << chain[k].y() << ") is not to the next cone along its boundary";
  }
}

TEST(HardTracks, ABoundaryLeavingAMinimumHairpinKeepsToItsOwnLeg) {
  // generated hard trackdrive 7125: a 75 m start straight ends in a minimum hairpin whose exit
  // leg runs back 5.5 m beside the straight. Seen from the car at the hairpin's entry, the
  // yellow chain came out of the turn and, guessing the turn went on, linked 3.9 m to the
  // straight's own yellow cones instead of 2.0 m along its leg; the exploration's path bent to
  // 1.07 m from the inner cones of the leg, and with the LiDAR the car hit two outer cones at the
  // entry (the full-lock manoeuvres scored a hit on that path at the exit and left the turn-in
  // late)
  const tracks::Track track = hard_trackdrive(7125);
  const core::Pose2 pose{70.5, 0.0, 0.0};
  const std::vector<core::MapCone> cones = cones_in_reach(track, pose);
  ASSERT_GT(cones.size(), 40u);
  const Boundaries b = chain_boundaries(cones, pose, {}, 25.0, false);
  ASSERT_GE(b.left.size(), 10u);
  ASSERT_GE(b.right.size(), 10u);
  expect_along_lane(track, b.left, track.left_lane, "7125 left");
  expect_along_lane(track, b.right, track.right_lane, "7125 right");

  // the path keeps to the lanes' middle: 1.6 m from the cones in the straights, 1.43 m at the
  // closest (round the hairpin)
  const Path path = plan_local_path(cones, pose, {}, 25.0);
  ASSERT_GE(path.length(), 20.0);
  double closest = std::numeric_limits<double>::infinity();
  for (const core::MapCone& c : cones)
    closest = std::min(closest, project_onto(path, c.position, 0, path.segment_count()).distance_m);
  std::printf("path to the nearest cone: %.3f m\n", closest);
  EXPECT_GT(closest, 1.3);
}

TEST(HardTracks, AChainStartedInsideATurnFollowsItsBoundary) {
  // a chain starts at the cone beside the car; the car's heading lags the boundary's inside a
  // turn. Hard trackdrive 7069 (LiDAR, lap 1), the car at the apex of a minimum hairpin: the
  // blue chain took the inner cones' turn for a bend and linked 8.6 m on to the start's big
  // orange cones; the path looped back on itself and the car unwound its lock mid-hairpin (three
  // cones). Hard trackdrive 7131 (GraphSLAM, lap 1), in a bend beside a lane 2 m away: the blue
  // chain linked 3.3 m across to that lane's cone instead of 4.0 m along its own (one cone). The
  // boundary's direction and turn at its first cone now come from the cones before it
  const std::vector<std::pair<uint64_t, core::Pose2>> cases = {{7069, {14.975, -8.751, 2.2819}},
                                                               {7131, {-6.4, 61.0, -1.83}}};
  for (const auto& [seed, pose] : cases) {
    const tracks::Track track = hard_trackdrive(seed);
    const Boundaries b = chain_boundaries(cones_in_reach(track, pose), pose, {}, 25.0, false);
    const std::string name = "hard trackdrive " + std::to_string(seed);
    ASSERT_GE(b.left.size(), 6u) << name;
    ASSERT_GE(b.right.size(), 6u) << name;
    expect_along_lane(track, b.left, track.left_lane, name + " left");
    expect_along_lane(track, b.right, track.right_lane, name + " right");
  }
}

TEST(HardTracks, AChainAtTheStartGoesOnStraightPastConesOfAnotherLane) {
  // hard trackdrive 7109, 2.5 s after the start (ground truth): the yellow cone behind the
  // start's first is not in view, but two of the lane 4.6 m below are; the chain's start took
  // the turn through one of them (1.2 rad) for the boundary's and left the start straight for
  // an orange cone and that lane; the path pulled the car over the straight's yellow cones (two
  // hit). The cones are those a 20 m, 200 degree sensor saw from the start line on
  const tracks::Track track = hard_trackdrive(7109);
  const core::Pose2 pose{6.375, -0.169, -0.208};
  ASSERT_NEAR(track.start.yaw, 0.0, 1e-9);  // the start line looks along +x
  std::vector<core::MapCone> seen;
  for (const tracks::Cone& c : track.cones) {
    for (double x = track.start.x; x <= pose.x; x += 0.5) {
      const Vec2 d = c.position - Vec2(x, track.start.y);
      if (d.norm() <= 20.0 && std::abs(std::atan2(d.y(), d.x())) <= 100.0 * kPi / 180.0) {
        seen.push_back({c.id, c.cls, c.position});
        break;
      }
    }
  }
  const Boundaries b = chain_boundaries(seen, pose, {}, 25.0, false);
  ASSERT_GE(b.left.size(), 4u);
  ASSERT_GE(b.right.size(), 4u);
  expect_along_lane(track, b.left, track.left_lane, "7109 left");
  expect_along_lane(track, b.right, track.right_lane, "7109 right");
}

TEST(HardTracks, AChainNeverPassesOneOfItsOwnConesOnTheTrackSide) {
  // hard autocross 7108 (ground truth), 14.5 s in: the lane runs west 2 m below the start
  // straight, whose yellow cones face its own. Leaving a right-hand bend, the guess that the bend
  // went on sent the yellow chain 4.3 m across to the straight's yellow cones instead of 3.8 m
  // along its own boundary, which bends left there; it passed its own next cone 1.9 m on the
  // track's side, the path ran 1 m towards the straight, and the car hit two of its own cones
  tracks::GeneratorParams g;
  g.profile = tracks::GeneratorProfile::kHard;
  g.event = core::EventType::kAutocross;
  const tracks::Track track = tracks::generate_circuit(7108, g);
  const core::Pose2 pose{53.364, -7.669, 2.810};
  const Boundaries b = chain_boundaries(cones_in_reach(track, pose), pose, {}, 25.0, false);
  ASSERT_GE(b.left.size(), 6u);
  ASSERT_GE(b.right.size(), 6u);
  expect_along_lane(track, b.left, track.left_lane, "7108 left");
  expect_along_lane(track, b.right, track.right_lane, "7108 right");
}

}  // namespace
}  // namespace conesim::control
