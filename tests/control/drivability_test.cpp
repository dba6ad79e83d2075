// The pre-run drivability check: it refuses what this car cannot drive, naming the place, and
// accepts the rule-compliant generated circuits.

#include "control/drivability.hpp"

#include <gtest/gtest.h>

#include <numbers>

#include "test_tracks.hpp"
#include "tracks/generator.hpp"

namespace conesim::control {
namespace {

using testing::CentreLine;
using testing::circuit_from_centre;

constexpr double kPi = std::numbers::pi;

// the check on a track's lanes and centre line
Drivability check(const tracks::Track& t) {
  std::vector<core::MapCone> cones;
  for (const tracks::Cone& c : t.cones)
    cones.push_back({c.id, c.cls, c.position, Eigen::Matrix2d::Identity() * 0.01});
  return check_drivability(t.lane_points(t.left_lane), t.lane_points(t.right_lane), t.centre_line,
                           t.closed, cones, VehicleGeometry{});
}

// a rounded rectangle with one narrow stretch: straights of 60 m, corners of 10 m radius
tracks::Track narrowed_circuit(double width_m, double narrow_width_m) {
  CentreLine c;
  c.straight(30).arc(10, kPi / 2).straight(20).arc(10, kPi / 2).straight(60).arc(10, kPi / 2);
  c.straight(20).arc(10, kPi / 2).straight(30);
  tracks::Track t = circuit_from_centre(c.points(), width_m, 3.0);
  // the cones of the far straight (y = 40, x 10..30) pulled in to narrow_width_m
  for (tracks::Cone& cone : t.cones) {
    const Vec2 p = cone.position;
    if (p.y() > 35.0 && p.x() > 10.0 && p.x() < 30.0)
      cone.position.y() = 40.0 + (p.y() > 40.0 ? 0.5 : -0.5) * narrow_width_m;
  }
  return t;
}

TEST(Drivability, RefusesATwoMetreLaneNamingThePlace) {
  const Drivability d = check(narrowed_circuit(3.5, 1.7));
  std::printf("refused: %s\n", d.reason.c_str());
  EXPECT_FALSE(d.drivable);
  EXPECT_NE(d.reason.find("lanes 1.70 m apart at ("), std::string::npos) << d.reason;
  EXPECT_NEAR(d.where.y(), 40.0, 0.5);
  EXPECT_GT(d.where.x(), 9.0);
  EXPECT_LT(d.where.x(), 31.0);
}

TEST(Drivability, AcceptsAThreeMetreLane) {
  const Drivability d = check(narrowed_circuit(3.5, 3.0));
  EXPECT_TRUE(d.drivable) << d.reason;
  EXPECT_NEAR(d.min_width_m, 3.0, 0.05);
}

// a stadium: two straights joined by hairpins of the given outer diameter and lane width
tracks::Track hairpin_stadium(double outer_diameter_m, double width_m) {
  const double r = 0.5 * outer_diameter_m - 0.5 * width_m;
  CentreLine c;
  c.straight(40).arc(r, kPi).straight(40).arc(r, kPi);
  return circuit_from_centre(c.points(), width_m, 2.5);
}

TEST(Drivability, RefusesAHairpinTighterThanTheCarTurns) {
  // 7 m outside diameter with 3 m lanes: the rear axle would have to turn on 2 m, where the
  // car's full lock turns it on 2.9 m (and the front overhang would sweep over the outer cones)
  const Drivability d = check(hairpin_stadium(7.0, 3.0));
  std::printf("refused: %s\n", d.reason.c_str());
  EXPECT_FALSE(d.drivable);
  EXPECT_NE(d.reason.find(" at ("), std::string::npos) << d.reason;
  // the place is in one of the hairpins (x < 0 or x > 40)
  EXPECT_TRUE(d.where.x() < 1.0 || d.where.x() > 39.0) << d.where.transpose();
}

TEST(Drivability, AcceptsTheFsgMinimumHairpinWithThreeMetreLanes) {
  // 9 m outside diameter (FSG's minimum) with 3 m lanes: every FS car must turn it
  const Drivability d = check(hairpin_stadium(9.0, 3.0));
  EXPECT_TRUE(d.drivable) << d.reason;
}

TEST(Drivability, AcceptsAHairpinTheCarCanTurn) {
  const Drivability d = check(hairpin_stadium(14.0, 4.0));
  EXPECT_TRUE(d.drivable) << d.reason;
}

TEST(Drivability, AcceptsEveryRuleCompliantGeneratedCircuit) {
  for (uint64_t seed = 1; seed <= 10; ++seed) {
    for (const core::EventType event :
         {core::EventType::kTrackdrive, core::EventType::kAutocross}) {
      tracks::GeneratorParams gp;
      gp.event = event;
      const Drivability d = check(tracks::generate_circuit(seed, gp));
      EXPECT_TRUE(d.drivable) << "seed " << seed << ": " << d.reason;
    }
  }
}

TEST(Drivability, FullLockRadiusIsTheMeasuredOne) {
  // 1.53 m / tan(36 deg) = 2.1 m kinematic, 2.92 m measured on the MuJoCo car
  EXPECT_NEAR(full_lock_radius_m(VehicleGeometry{}), 2.92, 0.05);
}

}  // namespace
}  // namespace conesim::control
