#include "control/path_planner.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "tracks/generator.hpp"

namespace conesim::control {
namespace {

using core::ConeClass;
using core::MapCone;
using core::Pose2;

constexpr double kHalfWidthM = 1.75;
constexpr double kPi = std::numbers::pi;

// a cone of the map with a nominal covariance
MapCone cone(ConeClass cls, const Vec2& p) {
  return {0, cls, p, Eigen::Matrix2d::Identity() * 0.01};
}

// a straight corridor along +x, a cone pair every 5 m from x0 to x1
std::vector<MapCone> corridor(double x0, double x1, bool left = true, bool right = true) {
  std::vector<MapCone> cones;
  for (double x = x0; x <= x1 + 1e-9; x += 5.0) {
    if (left) cones.push_back(cone(ConeClass::kBlue, {x, kHalfWidthM}));
    if (right) cones.push_back(cone(ConeClass::kYellow, {x, -kHalfWidthM}));
  }
  return cones;
}

// largest |y| of the path points beyond x_from (the car itself may be off the middle)
double max_abs_y_beyond(const Path& path, double x_from, double y_ref = 0.0) {
  double worst = 0.0;
  for (const Vec2& p : path.points)
    if (p.x() >= x_from) worst = std::max(worst, std::abs(p.y() - y_ref));
  return worst;
}

TEST(PathPlanner, StraightCorridorGivesTheMiddleLine) {
  // the car a little off the middle; the path joins the middle within a few metres
  const Path path = plan_local_path(corridor(-5.0, 30.0), Pose2{0.0, 0.4, 0.0}, {}, 25.0);
  ASSERT_GE(path.points.size(), 10u);
  EXPECT_TRUE(path.points.front().isApprox(Vec2(0.0, 0.4)));
  EXPECT_LT(max_abs_y_beyond(path, 3.0), 0.02);
  EXPECT_GT(path.points.back().x(), 20.0);
}

TEST(PathPlanner, SingleVisibleSideIsOffsetByTheAssumedHalfWidth) {
  PlannerParams params;
  params.assumed_half_width_m = 1.6;
  // blue only: the middle is 1.6 m right of the blue cones; yellow only: 1.6 m left
  const Path left_only = plan_local_path(corridor(-5.0, 30.0, true, false), Pose2{}, params, 25.0);
  ASSERT_GE(left_only.points.size(), 10u);
  EXPECT_LT(max_abs_y_beyond(left_only, 3.0, kHalfWidthM - 1.6), 0.02);
  const Path right_only = plan_local_path(corridor(-5.0, 30.0, false, true), Pose2{}, params, 25.0);
  ASSERT_GE(right_only.points.size(), 10u);
  EXPECT_LT(max_abs_y_beyond(right_only, 3.0, -kHalfWidthM + 1.6), 0.02);
}

TEST(PathPlanner, MissingConeIsBridged) {
  // the blue cone at x = 10 is missing: the left chain links 5 to 15 and the middle holds
  std::vector<MapCone> cones = corridor(-5.0, 30.0);
  std::erase_if(cones,
                [](const MapCone& c) { return c.position.isApprox(Vec2(10.0, kHalfWidthM)); });
  const Path path = plan_local_path(cones, Pose2{}, {}, 25.0);
  EXPECT_LT(max_abs_y_beyond(path, 1.0), 0.02);
  EXPECT_GT(path.points.back().x(), 20.0);
}

TEST(PathPlanner, WrongColourAndSpuriousConeDoNotPullThePathAcross) {
  // the blue cone at x = 10 is seen yellow, and a spurious yellow cone stands 3 m outside
  std::vector<MapCone> cones = corridor(-5.0, 30.0);
  for (MapCone& c : cones)
    if (c.position.isApprox(Vec2(10.0, kHalfWidthM))) c.cls = ConeClass::kYellow;
  cones.push_back(cone(ConeClass::kYellow, {17.0, -kHalfWidthM - 3.0}));
  const Path path = plan_local_path(cones, Pose2{}, {}, 25.0);
  EXPECT_LT(max_abs_y_beyond(path, 1.0), 0.05);
  EXPECT_GT(path.points.back().x(), 20.0);
}

// cones on both sides of a left-hand circle of centre-line radius r, every spacing_m along it
std::vector<MapCone> ring(double r, double spacing_m) {
  std::vector<MapCone> cones;
  const int n = static_cast<int>(std::ceil(2.0 * kPi * r / spacing_m));
  for (int i = 0; i < n; ++i) {
    const double phi = -0.5 * kPi + 2.0 * kPi * i / n;
    const Vec2 u(std::cos(phi), std::sin(phi));
    cones.push_back(cone(ConeClass::kBlue, (r - kHalfWidthM) * u));
    cones.push_back(cone(ConeClass::kYellow, (r + kHalfWidthM) * u));
  }
  return cones;
}

TEST(PathPlanner, CurveIsFollowedBetweenTheBoundaries) {
  // a left turn of centre radius 10 m, cones 3.5 m apart along the centre line; the car at the
  // bottom facing +x. The boundary chords cut 0.1-0.2 m inside the circles.
  constexpr double kRadiusM = 10.0;
  const Path path = plan_local_path(ring(kRadiusM, 3.5), Pose2{0.0, -kRadiusM, 0.0}, {}, 25.0);
  ASSERT_GE(path.points.size(), 15u);
  for (size_t i = 2; i < path.points.size(); ++i)
    EXPECT_NEAR(path.points[i].norm(), kRadiusM, 0.25) << "point " << i;
  // and it goes round the turn, not across it
  EXPECT_GT(path.length(), 20.0);
}

TEST(PathPlanner, WholeCircuitClosesIntoOneLoop) {
  constexpr double kRadiusM = 15.0;
  const std::optional<Path> circuit =
      plan_circuit(ring(kRadiusM, 4.0), Pose2{0.0, -kRadiusM, 0.0}, {});
  ASSERT_TRUE(circuit);
  EXPECT_TRUE(circuit->closed);
  EXPECT_NEAR(circuit->length(), 2.0 * kPi * kRadiusM, 0.02 * 2.0 * kPi * kRadiusM);
  for (const Vec2& p : circuit->points) EXPECT_NEAR(p.norm(), kRadiusM, 0.25);
}

TEST(PathPlanner, GeneratedCircuitFromItsWholeMapFollowsTheCentreLine) {
  // every cone of a generated circuit, the car behind the start line: the planned loop lies on
  // the designed centre line within the boundary chords' sag and has its length
  const tracks::Track track = tracks::generate_circuit(1);
  std::vector<MapCone> map;
  for (const tracks::Cone& c : track.cones) map.push_back(cone(c.cls, c.position));
  const std::optional<Path> circuit = plan_circuit(map, track.start.compose({-2.25, 0.0, 0.0}), {});
  ASSERT_TRUE(circuit);
  const Path designed{track.centre_line, true};
  // the boundary chords and the smoothing cut the turns a little: 2 % shorter at most
  EXPECT_NEAR(circuit->length(), designed.length(), 0.02 * designed.length());
  double worst = 0.0;
  for (const Vec2& p : circuit->points)
    worst = std::max(worst, project_onto(designed, p, 0, designed.segment_count()).distance_m);
  EXPECT_LT(worst, 0.3);
}

TEST(PathPlanner, OpenBoundariesGiveNoCircuit) {
  EXPECT_FALSE(plan_circuit(corridor(-5.0, 100.0), Pose2{}, {}));
}

TEST(PathPlanner, NoConesNoPath) {
  EXPECT_TRUE(plan_local_path({}, Pose2{}, {}, 25.0).points.empty());
}

}  // namespace
}  // namespace conesim::control
