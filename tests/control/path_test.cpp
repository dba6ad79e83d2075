#include "control/path.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "test_tracks.hpp"

namespace conesim::control {
namespace {

constexpr double kPi = std::numbers::pi;

Path circle(double radius, double spacing_m) {
  return testing::circle_path(radius, spacing_m);
}

TEST(JoinFrom, StartsAtTheCarAndEndsOnThePath) {
  // a car 1.2 m outside a circle of radius 40 (the lap-1 path beside the racing line)
  const Path line = circle(40.0, 1.0);
  const Vec2 car(0.0, -41.2);
  const PathProjection at = project_onto(line, car, 0, line.segment_count());
  const double join_m = 18.0;
  const Path joined = join_from(line, car, at, join_m);
  ASSERT_EQ(joined.points.size(), line.points.size());
  EXPECT_TRUE(joined.closed);

  const std::vector<double> s = line.arc_lengths();
  const double s_at = s[at.segment] + at.t * (s[at.segment + 1] - s[at.segment]);
  size_t moved = 0;
  for (size_t i = 0; i < line.points.size(); ++i) {
    double d = s[i] - s_at;
    if (d < 0.0) d += s.back();
    const double shift = (joined.points[i] - line.points[i]).norm();
    if (d > s.back() - 8.0) {
      const double behind = s.back() - d;
      EXPECT_NEAR(shift, 1.2 * 0.5 * (1.0 + std::cos(kPi * behind / 8.0)), 1e-6)
          << "point " << i << " " << behind << " m behind the car";
    } else if (d > join_m + 1e-9) {
      EXPECT_EQ(shift, 0.0) << "point " << i << " at " << d << " m past the car";
    } else {
      ++moved;
      // the share of the 1.2 m offset falls along a half cosine from the car to the join's end
      EXPECT_NEAR(shift, 1.2 * 0.5 * (1.0 + std::cos(kPi * d / join_m)), 1e-6);
    }
  }
  EXPECT_GE(moved, 17u);  // one point per metre over the 18 m
  EXPECT_LE(moved, 19u);
  // the car starts on the joined path
  EXPECT_LT(project_onto(joined, car, 0, joined.segment_count()).distance_m, 0.05);
}

TEST(JoinFrom, HasNoKinkThatWouldKickTheSteering) {
  // joining a straight 1 m to the side over 15 m: the curvature stays near the half cosine's
  // largest, offset * (pi / L)^2 / 2 = 0.022 1/m ahead of the car and 0.077 1/m over the 8 m
  // behind it, with no spike at either end of the join
  Path line;
  line.closed = true;
  for (int i = 0; i < 100; ++i) line.points.emplace_back(i, 0.0);
  for (int i = 99; i >= 0; --i) line.points.emplace_back(i, 30.0);
  const Vec2 car(10.0, 1.0);
  const PathProjection at = project_onto(line, car, 0, line.segment_count());
  const Path joined = join_from(line, car, at, 15.0);
  const std::vector<double> k = curvatures(joined.points, true, 1);
  double largest = 0.0;
  for (size_t i = 0; i < 40; ++i) largest = std::max(largest, std::abs(k[i]));
  EXPECT_GT(largest, 0.06);
  EXPECT_LT(largest, 0.09);
  double ahead = 0.0;
  for (size_t i = 11; i < 40; ++i) ahead = std::max(ahead, std::abs(k[i]));
  EXPECT_GT(ahead, 0.015);
  EXPECT_LT(ahead, 0.03);
}

TEST(JoinFrom, OnThePathChangesNothing) {
  const Path line = circle(20.0, 0.5);
  const Vec2 car = line.points[7];
  const PathProjection at = project_onto(line, car, 0, line.segment_count());
  const Path joined = join_from(line, car, at, 12.0);
  for (size_t i = 0; i < line.points.size(); ++i)
    EXPECT_LT((joined.points[i] - line.points[i]).norm(), 1e-9);
}

// A car 0.5 m beside a straight path and heading 0.25 rad further away from it: the joined path
// leaves the car along its heading (it goes on away from the path for a while) and meets the
// path with the path's heading at the join's end; joined without the heading, the path's
// direction at the car is the path's own, 0.25 rad off the car's.
TEST(JoinFrom, LeavesTheCarAlongItsHeading) {
  Path line;
  line.closed = true;
  for (int i = 0; i < 100; ++i) line.points.emplace_back(i, 0.0);
  for (int i = 99; i >= 0; --i) line.points.emplace_back(i, 30.0);
  const Vec2 car(10.3, -0.5);
  const double heading = -0.25;
  const PathProjection at = project_onto(line, car, 0, line.segment_count());
  const double join_m = 12.0;
  const auto direction_at_car = [&](const Path& p) {
    const PathProjection on = project_onto(p, car, 0, p.segment_count());
    const Vec2 d = p.segment_end(on.segment) - p.points[on.segment];
    return std::atan2(d.y(), d.x());
  };
  const Path joined = join_from(line, car, at, join_m, heading);
  EXPECT_LT(project_onto(joined, car, 0, joined.segment_count()).distance_m, 0.05);
  EXPECT_NEAR(direction_at_car(joined), heading, 0.03);
  EXPECT_NEAR(direction_at_car(join_from(line, car, at, join_m)), 0.0, 0.02);
  // away from the path first, back on it (with its heading) at the join's end
  double furthest = 0.0;
  for (int x = 11; x <= 22; ++x) furthest = std::min(furthest, joined.points[x].y());
  EXPECT_LT(furthest, -0.7);
  for (int x = 23; x < 30; ++x) EXPECT_LT(std::abs(joined.points[x].y()), 1e-9) << x;
  EXPECT_LT(std::abs(joined.points[22].y()), 0.01);
}

}  // namespace
}  // namespace conesim::control
