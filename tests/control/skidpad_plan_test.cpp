#include "control/skidpad_plan.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "tracks/fsg_layouts.hpp"

namespace conesim::control {
namespace {

using core::ConeClass;
using core::MapCone;
using core::Pose2;

constexpr double kPi = std::numbers::pi;

// the FSG skidpad's cones seen from a map frame in which the track frame sits at `track_in_map`
std::vector<MapCone> skidpad_in(const Pose2& track_in_map) {
  std::vector<MapCone> map;
  for (const tracks::Cone& c : tracks::make_skidpad().cones)
    map.push_back({c.id, c.cls, track_in_map.transform(c.position), Eigen::Matrix2d::Identity()});
  return map;
}

TEST(SkidpadPlan, FitsTheCircleCentresOfAMovedLayout) {
  // the layout turned and shifted: the fit finds the moved centres, not the nominal ones
  const Pose2 moved{3.0, -1.5, 0.2};
  const std::vector<MapCone> map = skidpad_in(moved);
  const double d = tracks::kSkidpadStartToTimingLineM;
  const double half_gap = 0.5 * tracks::kSkidpadCentreDistanceM;
  const std::optional<SkidpadGeometry> g = fit_skidpad(map, moved);
  ASSERT_TRUE(g);
  EXPECT_LT((g->right_centre - moved.transform({d, -half_gap})).norm(), 0.01);
  EXPECT_LT((g->left_centre - moved.transform({d, half_gap})).norm(), 0.01);
  EXPECT_NEAR(g->radius_m, half_gap, 0.01);
  EXPECT_LT((g->forward - moved.heading()).norm(), 1e-3);
}

TEST(SkidpadPlan, FitIgnoresColoursMissingConesAndTheBigOranges) {
  // colours swapped (as in fssim's file), four inner cones missing, no big orange cones
  std::vector<MapCone> map = skidpad_in(Pose2{});
  for (MapCone& c : map)
    c.cls = c.cls == ConeClass::kBlue     ? ConeClass::kYellow
            : c.cls == ConeClass::kYellow ? ConeClass::kBlue
                                          : c.cls;
  std::erase_if(map, [](const MapCone& c) {
    return c.cls == ConeClass::kOrangeBig || c.id == 1 || c.id == 2 || c.id == 17 || c.id == 20;
  });
  const std::optional<SkidpadGeometry> g = fit_skidpad(map, Pose2{});
  ASSERT_TRUE(g);
  const double d = tracks::kSkidpadStartToTimingLineM;
  const double half_gap = 0.5 * tracks::kSkidpadCentreDistanceM;
  EXPECT_LT((g->right_centre - Vec2(d, -half_gap)).norm(), 0.01);
  EXPECT_LT((g->left_centre - Vec2(d, half_gap)).norm(), 0.01);
}

TEST(SkidpadPlan, PathDrivesTwoLapsEachWayAndExitsStraight) {
  const std::optional<SkidpadGeometry> g = fit_skidpad(skidpad_in(Pose2{}), Pose2{});
  ASSERT_TRUE(g);
  constexpr double kStopAfterM = 12.0;
  const SkidpadPlan plan = plan_skidpad(*g, Pose2{-2.25, 0.0, 0.0}, kStopAfterM);
  ASSERT_EQ(plan.lap_end_s.size(), 4u);
  const double lap = 2.0 * kPi * g->radius_m;
  for (size_t i = 1; i < 4; ++i) EXPECT_NEAR(plan.lap_end_s[i] - plan.lap_end_s[i - 1], lap, 0.01);
  EXPECT_NEAR(plan.stop_s - plan.lap_end_s[3], kStopAfterM, 0.01);
  EXPECT_TRUE(plan.path.points.back().isApprox(g->timing_point + kStopAfterM * g->forward, 1e-9));

  // the first two laps circle the right centre, the next two the left one
  const std::vector<double> s = plan.path.arc_lengths();
  for (size_t i = 0; i < s.size(); ++i) {
    const Vec2& p = plan.path.points[i];
    if (s[i] > plan.lap_end_s[0] - lap + 0.1 && s[i] < plan.lap_end_s[1] - 0.1) {
      EXPECT_NEAR((p - g->right_centre).norm(), g->radius_m, 1e-6);
    }
    if (s[i] > plan.lap_end_s[1] + 0.1 && s[i] < plan.lap_end_s[3] - 0.1) {
      EXPECT_NEAR((p - g->left_centre).norm(), g->radius_m, 1e-6);
    }
  }
  // clockwise on the right: 2 m into the first lap the path is right of the entry line
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] < plan.lap_end_s[0] - lap + 2.0) continue;
    EXPECT_LT(core::cross(g->forward, plan.path.points[i] - g->timing_point), -0.1);
    break;
  }
}

TEST(SkidpadPlan, TooFewConesGiveNoFit) {
  EXPECT_FALSE(fit_skidpad({}, Pose2{}));
}

}  // namespace
}  // namespace conesim::control
