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

namespace conesim::control {
namespace {

// a lap's trace on a 20 m circle from (0, -20) anticlockwise, every 0.5 m, running `past_m`
// beyond its start
std::vector<Vec2> circle_trace(double past_m) {
  std::vector<Vec2> trace;
  const double r = 20.0, lap = 2.0 * std::numbers::pi * r;
  for (double s = 0.0; s <= lap + past_m; s += 0.5)
    trace.emplace_back(r * std::sin(s / r), -r * std::cos(s / r));
  return trace;
}

// the largest turn between consecutive chords of a closed polyline, radians
double largest_turn(const std::vector<Vec2>& loop) {
  double worst = 0.0;
  const size_t n = loop.size();
  for (size_t i = 0; i < n; ++i) {
    const Vec2 a = loop[(i + 1) % n] - loop[i], b = loop[(i + 2) % n] - loop[(i + 1) % n];
    worst = std::max(worst, std::abs(std::atan2(a.x() * b.y() - a.y() * b.x(), a.dot(b))));
  }
  return worst;
}

TEST(ClosedLap, DropsTheTraceRunOnPastTheStart) {
  // 1.1 m past the start, as a lap counted when the car's front crosses the line: closed as it
  // is, the loop doubles back (a turn of pi); closed_lap ends it behind the start, and the loop
  // turns by a chord's 0.05 rad at most (1 m chords on a 20 m radius)
  const std::vector<Vec2> trace = circle_trace(1.1);
  EXPECT_GT(largest_turn(resample(trace, 1.0, true)), 3.0);
  const std::vector<Vec2> lap = closed_lap(trace);
  EXPECT_LT(lap.size(), trace.size());
  EXPECT_LT(largest_turn(resample(lap, 1.0, true)), 0.06);
}

TEST(ClosedLap, DropsARunOnPastAStartLineThatMovedOn) {
  // the lap line moves from the start pose to the time-keeping cones once they are mapped, 6 m
  // on (generated hard trackdrive 7015 with GraphSLAM: the trace ran 5.25 m past its first point,
  // beyond the 5 m once dropped; the loop doubled back, the racing line took a 0.85 m S-bend
  // over 4 m at the start, and a fast lap hit a cone there)
  for (const double past : {5.3, 6.5, 9.0}) {
    const std::vector<Vec2> lap = closed_lap(circle_trace(past));
    EXPECT_LT(largest_turn(resample(lap, 1.0, true)), 0.06) << past << " m past";
  }
}

TEST(ClosedLap, KeepsATraceThatEndsBehindItsStart) {
  const std::vector<Vec2> trace = circle_trace(-0.7);
  EXPECT_EQ(closed_lap(trace).size(), trace.size());
}

}  // namespace
}  // namespace conesim::control
