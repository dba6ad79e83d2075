#include "sensors/sun_shadow.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace conesim::sensors {
namespace {

using Eigen::Vector3d;

constexpr double kPi = std::numbers::pi;
// a circle drawn as a regular 16-gon keeps this share of its area
const double kPolygonShare = 16.0 / (2.0 * kPi) * std::sin(2.0 * kPi / 16.0);

mjvGeom solid(int type, const Vector3d& pos, const Vector3d& size) {
  mjvGeom g{};
  g.type = type;
  g.dataid = -1;
  for (int i = 0; i < 3; ++i) {
    g.pos[i] = static_cast<float>(pos[i]);
    g.size[i] = static_cast<float>(size[i]);
    for (int j = 0; j < 3; ++j) g.mat[3 * i + j] = i == j ? 1.f : 0.f;
  }
  return g;
}

// sunlight from `elevation_deg` above the horizon, travelling along +x
Vector3d light(double elevation_deg) {
  const double e = elevation_deg * kPi / 180.0;
  return {std::cos(e), 0.0, -std::sin(e)};
}

std::vector<Vector3d> shadow_of(const mjvGeom& g, const Vector3d& d) {
  std::vector<Vector3d> points;
  shadow_caster_points(g, nullptr, d, points);
  return cast_shadow(points, d, Vector3d::Zero(), Vector3d::UnitZ());
}

// the area of a polygon on the level ground, positive when counter-clockwise seen from above
double area(const std::vector<Vector3d>& outline) {
  double twice = 0.0;
  for (size_t i = 0; i < outline.size(); ++i) {
    const Vector3d& a = outline[i];
    const Vector3d& b = outline[(i + 1) % outline.size()];
    twice += a.x() * b.y() - b.x() * a.y();
  }
  return 0.5 * twice;
}

// A box standing on the ground casts its footprint under a sun overhead, and a footprint
// stretched away from the sun by its height / tan(elevation) under a lower one; the shadow lies
// on the ground, counter-clockwise seen from above.
TEST(SunShadow, ABoxCastsItsFootprintStretchedAwayFromTheSun) {
  const mjvGeom box = solid(mjGEOM_BOX, {0.0, 0.0, 0.5}, {0.5, 0.5, 0.5});
  const std::vector<Vector3d> overhead = shadow_of(box, {0.0, 0.0, -1.0});
  ASSERT_EQ(overhead.size(), 4u);
  EXPECT_NEAR(area(overhead), 1.0, 1e-6);
  const std::vector<Vector3d> low = shadow_of(box, light(30.0));
  double x_min = 1e9, x_max = -1e9;
  for (const Vector3d& p : low) {
    EXPECT_NEAR(p.z(), 0.0, 1e-6);
    x_min = std::min(x_min, p.x());
    x_max = std::max(x_max, p.x());
  }
  const double reach = 1.0 / std::tan(30.0 * kPi / 180.0);
  EXPECT_NEAR(x_min, -0.5, 1e-6);
  EXPECT_NEAR(x_max, 0.5 + reach, 1e-6);
  EXPECT_NEAR(area(low), 1.0 + reach, 1e-6);
}

// A ball above the ground casts an ellipse 1 / sin(elevation) as long as it is wide, centred
// where the ray through the ball's centre meets the ground; an ellipsoid under a sun overhead
// casts its horizontal section.
TEST(SunShadow, RoundSolidsCastTheirOutlineSeenFromTheSun) {
  const double r = 0.3, h = 1.0, elevation = 40.0;
  const mjvGeom ball = solid(mjGEOM_SPHERE, {0.0, 0.0, h}, {r, 0.0, 0.0});
  const std::vector<Vector3d> shadow = shadow_of(ball, light(elevation));
  ASSERT_EQ(shadow.size(), 16u);
  const double s = std::sin(elevation * kPi / 180.0);
  EXPECT_NEAR(area(shadow), kPolygonShare * kPi * r * r / s, 1e-6);
  Vector3d centre = Vector3d::Zero();
  for (const Vector3d& p : shadow) centre += p / 16.0;
  EXPECT_NEAR(centre.x(), h / std::tan(elevation * kPi / 180.0), 1e-6);
  EXPECT_NEAR(centre.y(), 0.0, 1e-6);

  const mjvGeom egg = solid(mjGEOM_ELLIPSOID, {0.0, 0.0, h}, {0.2, 0.5, 0.3});
  EXPECT_NEAR(area(shadow_of(egg, {0.0, 0.0, -1.0})), kPolygonShare * kPi * 0.2 * 0.5, 1e-6);
  // a capsule lying along x under a sun overhead: a rectangle between two half discs
  mjvGeom capsule = solid(mjGEOM_CAPSULE, {0.0, 0.0, h}, {0.1, 0.4, 0.0});
  // (its local z axis along the world's x)
  capsule.mat[0] = 0.f, capsule.mat[2] = 1.f, capsule.mat[6] = -1.f, capsule.mat[8] = 0.f;
  EXPECT_NEAR(area(shadow_of(capsule, {0.0, 0.0, -1.0})),
              kPolygonShare * kPi * 0.1 * 0.1 + 0.8 * 0.2, 1e-6);
  // a cylinder standing up under a sun overhead: its end disc
  const mjvGeom drum = solid(mjGEOM_CYLINDER, {0.0, 0.0, h}, {0.25, 0.4, 0.0});
  EXPECT_NEAR(area(shadow_of(drum, {0.0, 0.0, -1.0})), kPolygonShare * kPi * 0.25 * 0.25, 1e-6);
}

// No shadow from light that grazes the ground or comes from under it, and none of a plane.
TEST(SunShadow, NoShadowWithoutLightOnTheGround) {
  const mjvGeom box = solid(mjGEOM_BOX, {0.0, 0.0, 0.5}, {0.5, 0.5, 0.5});
  EXPECT_TRUE(shadow_of(box, light(0.0)).empty());
  EXPECT_TRUE(shadow_of(box, light(-30.0)).empty());
  EXPECT_FALSE(shadow_of(box, light(5.0)).empty());
  EXPECT_TRUE(
      shadow_of(solid(mjGEOM_PLANE, {0.0, 0.0, 0.0}, {1.0, 1.0, 1.0}), light(45.0)).empty());
}

}  // namespace
}  // namespace conesim::sensors
