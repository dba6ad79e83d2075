// The ground's height model (issue 17): flat by default, a grade that rises as asked, a crown
// highest on the driving line, bumps as high as asked, the same ground for the same seed.

#include "tracks/ground.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace conesim::tracks {
namespace {

// a straight of cones 60 m long along x, the driving line on y = 0
Track straight() {
  Track track;
  track.name = "straight";
  int id = 0;
  for (int i = 0; i <= 20; ++i) {
    track.cones.push_back({id, core::ConeClass::kBlue, Vec2(3.0 * i, 1.5), {}});
    track.left_lane.push_back(id++);
    track.cones.push_back({id, core::ConeClass::kYellow, Vec2(3.0 * i, -1.5), {}});
    track.right_lane.push_back(id++);
    track.centre_line.push_back(Vec2(3.0 * i, 0.0));
  }
  track.start = {0.0, 0.0, 0.0};
  return track;
}

TEST(Ground, FlatByDefault) {
  const GroundModel ground(straight(), GroundConfig{}, 1);
  EXPECT_TRUE(ground.flat());
  EXPECT_EQ(ground.height(12.0, -40.0), 0.0);
  EXPECT_EQ(ground.normal(3.0, 4.0), Eigen::Vector3d::UnitZ());
  // bumps of no height, or none per area, are no bumps
  GroundConfig no_bumps;
  no_bumps.bump_height_m = 0.05;
  EXPECT_TRUE(GroundModel(straight(), no_bumps, 1).flat());
}

// 2 % towards +y: 0.2 m over 10 m, the normal leaning back by atan(0.02); zero at the start
TEST(Ground, AGradeRisesAlongItsHeading) {
  GroundConfig c;
  c.grade_percent = 2.0;
  c.grade_heading_deg = 90.0;
  const GroundModel ground(straight(), c, 1);
  ASSERT_FALSE(ground.flat());
  EXPECT_NEAR(ground.height(0.0, 0.0), 0.0, 1e-5);
  EXPECT_NEAR(ground.height(30.0, 10.0) - ground.height(30.0, 0.0), 0.2, 1e-5);
  EXPECT_NEAR(ground.height(50.0, 0.0) - ground.height(10.0, 0.0), 0.0, 1e-5);
  const Eigen::Vector3d n = ground.normal(20.3, 4.1);
  EXPECT_NEAR(n.y(), -std::sin(std::atan(0.02)), 1e-5);
  EXPECT_NEAR(n.x(), 0.0, 1e-5);
  // beyond the grid, the edge's height
  const GroundGrid& g = ground.grid();
  const double edge_y = g.y0 + (g.ny - 1) * g.cell_m;
  EXPECT_GT(edge_y, 40.0);
  EXPECT_NEAR(ground.height(30.0, 500.0), ground.height(30.0, edge_y), 1e-5);
}

// the heading of the grade, when not given, comes from the seed: another seed, another heading
TEST(Ground, TheSameSeedGivesTheSameGround) {
  GroundConfig c;
  c.grade_percent = 2.0;
  c.undulation_amplitude_m = 0.1;
  c.bump_height_m = 0.03;
  c.bumps_per_100m2 = 2.0;
  const GroundModel a(straight(), c, 5), b(straight(), c, 5), other(straight(), c, 6);
  EXPECT_EQ(a.grid().z, b.grid().z);
  EXPECT_NE(a.grid().z, other.grid().z);
  c.seed_offset = 1;
  EXPECT_NE(GroundModel(straight(), c, 5).grid().z, a.grid().z);
}

// 2 % cross fall: the driving line is the crest, 5 m off it the ground is 2 % x (5 - 0.75) m lower
TEST(Ground, ACrownFallsAwayFromTheDrivingLine) {
  GroundConfig c;
  c.crown_percent = 2.0;
  const GroundModel ground(straight(), c, 1);
  EXPECT_NEAR(ground.height(30.0, 0.0), 0.0, 1e-5);
  EXPECT_NEAR(ground.height(30.0, 5.0), -0.02 * 4.25, 1e-3);
  EXPECT_NEAR(ground.height(30.0, -5.0), -0.02 * 4.25, 1e-3);
  // past 8 m it falls no more
  EXPECT_NEAR(ground.height(30.0, 12.0), ground.height(30.0, 9.0), 1e-5);
}

// bumps: none higher than asked, the highest at least half of it, and a grid fine enough to
// hold their shape (four cells across a radius)
TEST(Ground, BumpsAreAsHighAsAsked) {
  GroundConfig c;
  c.bump_height_m = 0.04;
  c.bump_radius_m = 0.6;
  c.bumps_per_100m2 = 3.0;
  const GroundModel ground(straight(), c, 2);
  EXPECT_LE(ground.grid().max_z, 0.04 * 2.0);  // two may overlap
  EXPECT_GE(ground.grid().max_z, 0.02);
  EXPECT_GE(ground.grid().min_z, 0.0);
  EXPECT_LE(ground.grid().cell_m, 0.6 / 2.0 + 1e-9);
}

TEST(Ground, BadKeysAreNamedWithTheirRange) {
  GroundConfig c;
  c.grade_percent = 7.0;
  EXPECT_EQ(c.validate(), "grade_percent: expected a number in [0, 5], got 7");
  c = {};
  c.bumps_per_100m2 = std::nan("");
  EXPECT_NE(c.validate().find("bumps_per_100m2: expected a number in [0, 10]"), std::string::npos);
  EXPECT_THROW(GroundModel(straight(), c, 1), std::invalid_argument);
}

}  // namespace
}  // namespace conesim::tracks
