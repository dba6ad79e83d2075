// The generated FSG skidpad and acceleration layouts: handbook geometry, their own event's rules,
// and the public fssim, PacSim and EUFS layouts of the same events.

#include "tracks/fsg_layouts.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include "tracks/io.hpp"
#include "tracks/rules.hpp"

namespace conesim::tracks {
namespace {

constexpr double kPi = std::numbers::pi;
const std::string kData = std::string(CONESIM_TEST_DATA) + "/tracks/";

// every violation as text, for failure messages
std::string describe(const std::vector<Violation>& all) {
  std::string text;
  for (const Violation& v : all) text += v.to_string() + "\n";
  return text;
}

// the cone of `track` nearest to p
const Cone& nearest_cone(const Track& track, const Vec2& p) {
  const Cone* best = &track.cones.front();
  for (const Cone& c : track.cones)
    if ((c.position - p).norm() < (best->position - p).norm()) best = &c;
  return *best;
}

// distance from p to the polyline
double distance_to_path(const Vec2& p, const std::vector<Vec2>& path) {
  double d = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i + 1 < path.size(); ++i)
    d = std::min(d, core::distance_to_segment(p, path[i], path[i + 1]));
  return d;
}

// the same layout moved by `offset`
Track shifted(Track track, const Vec2& offset) {
  for (Cone& c : track.cones) c.position += offset;
  return track;
}

// ---------------------------------------------------------------------------------------------
// skidpad

TEST(Skidpad, HandbookGeometry) {
  const Track t = make_skidpad();
  ASSERT_TRUE(t.event.has_value());
  EXPECT_EQ(*t.event, EventType::kSkidpad);
  EXPECT_FALSE(t.closed);
  EXPECT_EQ(t.start.position(), Vec2(0.0, 0.0));
  EXPECT_EQ(t.start.yaw, 0.0);

  // two circles 18.25 m apart on the timing line, cone rings 0.15 m outside the driving area
  const std::vector<SkidpadCircleFit> circles = fit_skidpad_circles(t);
  ASSERT_EQ(circles.size(), 2u);
  const double d = kSkidpadStartToTimingLineM;
  for (const SkidpadCircleFit& c : circles) {
    EXPECT_NEAR(c.centre.x(), d, 1e-9);
    EXPECT_NEAR(std::abs(c.centre.y()), 9.125, 1e-9);
    EXPECT_NEAR(c.inner_radius_m, 15.25 / 2 - 0.15, 1e-9);
    EXPECT_NEAR(c.outer_radius_m, 21.25 / 2 + 0.15, 1e-9);
    EXPECT_EQ(c.inner_cones, 16);
    EXPECT_EQ(c.outer_cones, 13);
  }
  EXPECT_NEAR((circles[0].centre - circles[1].centre).norm(), 18.25, 1e-9);

  // cone classes: 29 blue, 29 yellow, 11 small orange (entry, exit, stop line), 4 big orange
  EXPECT_EQ(t.count(ConeClass::kBlue), 29);
  EXPECT_EQ(t.count(ConeClass::kYellow), 29);
  EXPECT_EQ(t.count(ConeClass::kOrangeSmall), 11);
  EXPECT_EQ(t.count(ConeClass::kOrangeBig), 4);

  // timing gate across the timing line, where the circles touch
  ASSERT_EQ(t.timing_gates.size(), 1u);
  EXPECT_NEAR(0.5 * (t.timing_gates[0].left + t.timing_gates[0].right).x(), d, 1e-9);
  EXPECT_GT(t.timing_gates[0].left.y(), 0.0);

  // the layout passes its own event's rules
  const std::vector<Violation> v = check_rules(t, EventType::kSkidpad);
  EXPECT_TRUE(v.empty()) << describe(v);
}

TEST(Skidpad, YellowInsideTheRightCircleBlueInsideTheLeft) {
  // driving clockwise round the right circle its inside is on the car's right: yellow; the
  // left circle is driven anticlockwise, its inside on the left: blue
  const Track t = make_skidpad();
  const Vec2 right_centre(kSkidpadStartToTimingLineM, -9.125);
  const Vec2 left_centre(kSkidpadStartToTimingLineM, 9.125);
  for (const Cone& c : t.cones) {
    if (c.cls != ConeClass::kBlue && c.cls != ConeClass::kYellow) continue;
    const double r_right = (c.position - right_centre).norm();
    const double r_left = (c.position - left_centre).norm();
    if (std::abs(r_right - kSkidpadInnerConeRadiusM) < 1e-6)
      EXPECT_EQ(c.cls, ConeClass::kYellow) << "inner right, cone " << c.id;
    else if (std::abs(r_left - kSkidpadInnerConeRadiusM) < 1e-6)
      EXPECT_EQ(c.cls, ConeClass::kBlue) << "inner left, cone " << c.id;
    else if (std::abs(r_right - kSkidpadOuterConeRadiusM) < 1e-6)
      EXPECT_EQ(c.cls, ConeClass::kBlue) << "outer right, cone " << c.id;
    else if (std::abs(r_left - kSkidpadOuterConeRadiusM) < 1e-6)
      EXPECT_EQ(c.cls, ConeClass::kYellow) << "outer left, cone " << c.id;
    else
      ADD_FAILURE() << "cone " << c.id << " is on no ring";
  }
}

TEST(Skidpad, CentreLineIsEntryTwoRightLapsTwoLeftLapsExit) {
  const Track t = make_skidpad();
  const std::vector<Vec2>& path = t.centre_line;
  const double d = kSkidpadStartToTimingLineM;
  const double r = 9.125;
  ASSERT_GT(path.size(), 100u);
  EXPECT_EQ(path.front(), Vec2(0.0, 0.0));
  EXPECT_NEAR((path.back() - Vec2(d + 20.0, 0.0)).norm(), 0.0, 1e-9);

  // samples at most 0.5 m apart, and the length of entry, four laps and exit (each 0.5 m chord
  // of a 9.125 m circle is shorter than its arc by a factor 1 - (0.5 / r)^2 / 24)
  double length = 0.0;
  for (size_t i = 0; i + 1 < path.size(); ++i) {
    const double step = (path[i + 1] - path[i]).norm();
    EXPECT_LE(step, 0.5 + 1e-9);
    EXPECT_GE(step, 0.4);
    length += step;
  }
  const double expected = d + 8.0 * kPi * r + 20.0;
  EXPECT_NEAR(length, expected, expected * (0.5 / r) * (0.5 / r) / 24.0 + 1e-6);

  // turning: two full turns clockwise (negative), then two anticlockwise back to heading +x
  double turn = 0.0, least = 0.0, most = 0.0;
  for (size_t i = 0; i + 2 < path.size(); ++i) {
    const Vec2 a = path[i + 1] - path[i], b = path[i + 2] - path[i + 1];
    turn += std::atan2(core::cross(a, b), a.dot(b));
    least = std::min(least, turn);
    most = std::max(most, turn);
  }
  // chords see the switch of circles half a 0.5 m step late: within 0.5 / r of -4 pi
  EXPECT_NEAR(least, -4.0 * kPi, 0.5 / r);
  EXPECT_NEAR(most, 0.0, 1e-6);
  EXPECT_NEAR(turn, 0.0, 1e-6);
  EXPECT_LT(path[static_cast<size_t>(d / 0.5) + 5].y(), 0.0);  // into the right circle first

  // the path keeps clear of every cone: 1.65 m from the rings and lane cones, 1 m short of the
  // stop-line cone (the car is 1.5 m wide)
  for (const Cone& c : t.cones) {
    const double clearance = distance_to_path(c.position, path);
    if (c.position == Vec2(d + 21.0, 0.0)) {
      EXPECT_NEAR(clearance, 1.0, 1e-9);
    } else {
      EXPECT_GT(clearance, 1.5) << "cone " << c.id;
    }
  }
}

TEST(Skidpad, MatchesFssimAndPacsim) {
  const Track ours = make_skidpad();
  const Vec2 to_ours(kSkidpadStartToTimingLineM, 0.0);  // the files put the timing line at x = 0

  // fssim: every cone at one of ours; its rings are coloured the other way round (see
  // SOURCES.md), so only the orange classes are compared
  const Track fssim = shifted(read_track(kData + "fssim/skidpad.yaml"), to_ours);
  for (const Cone& c : fssim.cones) {
    const Cone& mine = nearest_cone(ours, c.position);
    EXPECT_NEAR((mine.position - c.position).norm(), 0.0, 1e-6) << "fssim cone " << c.id;
    if (c.cls == ConeClass::kOrangeSmall || c.cls == ConeClass::kOrangeBig) {
      EXPECT_EQ(mine.cls, c.cls) << "fssim cone " << c.id;
    }
  }
  EXPECT_EQ(fssim.count(ConeClass::kBlue) + fssim.count(ConeClass::kYellow), 58);
  EXPECT_EQ(fssim.count(ConeClass::kOrangeBig), 4);

  // PacSim: same classes everywhere; it moves the outer rings' end cones onto the lane lines
  // (7.76 m from the timing line instead of 7.62 m: 0.2 m away)
  const Track pacsim = shifted(read_track(kData + "pacsim/skidpad.yaml"), to_ours);
  for (const Cone& c : pacsim.cones) {
    const Cone& mine = nearest_cone(ours, c.position);
    EXPECT_LT((mine.position - c.position).norm(), 0.21) << "PacSim cone " << c.id;
    EXPECT_EQ(mine.cls, c.cls) << "PacSim cone " << c.id;
  }
  for (const ConeClass cls :
       {ConeClass::kBlue, ConeClass::kYellow, ConeClass::kOrangeSmall, ConeClass::kOrangeBig})
    EXPECT_EQ(pacsim.count(cls), ours.count(cls)) << core::to_string(cls);

  // the fitted circles agree: 18.25 m apart, rings 7.475 m and 10.775 m
  for (const Track* file : {&fssim, &pacsim}) {
    const std::vector<SkidpadCircleFit> circles = fit_skidpad_circles(*file);
    ASSERT_EQ(circles.size(), 2u) << file->name;
    EXPECT_NEAR((circles[0].centre - circles[1].centre).norm(), 18.25, 1e-6);
    for (const SkidpadCircleFit& c : circles) {
      EXPECT_NEAR(c.inner_radius_m, kSkidpadInnerConeRadiusM, 1e-6) << file->name;
      EXPECT_NEAR(c.outer_radius_m, kSkidpadOuterConeRadiusM, 1e-6) << file->name;
    }
  }

  // the start pose: 16.5 m before the timing line as fssim's front wing (PacSim 16.68 m)
  EXPECT_NEAR(-fssim.start.x, kSkidpadStartToTimingLineM, 1e-9);
  EXPECT_NEAR(-pacsim.start.x, kSkidpadStartToTimingLineM, 0.2);
}

TEST(Skidpad, PublicLayoutsPassTheSkidpadRules) {
  // fssim and PacSim (cones 0.15 m outside the driving area) and EUFS (cones on its edge:
  // rings 7.61 m and 10.61 m, centres 18.5 m apart) are all within the tolerances
  for (const char* file : {"fssim/skidpad.yaml", "pacsim/skidpad.yaml", "eufs/skidpad.csv"}) {
    const Track t = read_track(kData + file);
    const std::vector<Violation> v = check_rules(t, EventType::kSkidpad);
    EXPECT_TRUE(v.empty()) << file << "\n" << describe(v);
    Track unlabelled = t;
    unlabelled.event.reset();
    EXPECT_EQ(infer_event(unlabelled), EventType::kSkidpad) << file;
  }
}

TEST(Skidpad, BrokenGeometryIsReported) {
  // the left circle 1 m further out: centres 19.25 m apart
  Track apart = make_skidpad();
  for (Cone& c : apart.cones)
    if (c.position.y() > 1.0 && (c.cls == ConeClass::kBlue || c.cls == ConeClass::kYellow))
      c.position.y() += 1.0;
  std::vector<Violation> v = check_rules(apart, EventType::kSkidpad);
  ASSERT_EQ(v.size(), 1u) << describe(v);
  EXPECT_EQ(v[0].rule, "skidpad_centre_distance");
  EXPECT_NE(v[0].message.find("19.25"), std::string::npos) << v[0].message;

  // inner rings on the driving-area edge shrunk by 0.5 m: both inner radii out of tolerance
  Track small = make_skidpad();
  for (const double side : {1.0, -1.0}) {
    const Vec2 centre(kSkidpadStartToTimingLineM, side * 9.125);
    for (Cone& c : small.cones) {
      const Vec2 r = c.position - centre;
      if (std::abs(r.norm() - kSkidpadInnerConeRadiusM) < 1e-6)
        c.position = centre + r * (kSkidpadInnerConeRadiusM - 0.5) / r.norm();
    }
  }
  v = check_rules(small, EventType::kSkidpad);
  ASSERT_EQ(v.size(), 2u) << describe(v);
  EXPECT_EQ(v[0].rule, "skidpad_inner_radius");
  EXPECT_EQ(v[1].rule, "skidpad_inner_radius");

  // no timing gate
  Track ungated = make_skidpad();
  ungated.timing_gates.clear();
  v = check_rules(ungated, EventType::kSkidpad);
  ASSERT_EQ(v.size(), 1u) << describe(v);
  EXPECT_EQ(v[0].rule, "timing_gate");
}

// ---------------------------------------------------------------------------------------------
// acceleration

TEST(Acceleration, HandbookGeometry) {
  const Track t = make_acceleration();
  ASSERT_TRUE(t.event.has_value());
  EXPECT_EQ(*t.event, EventType::kAcceleration);
  EXPECT_FALSE(t.closed);

  // start pose 0.3 m behind the start line, facing +x; gates at 0 and 75 m
  EXPECT_NEAR(t.start.x, -0.3, 1e-12);
  EXPECT_EQ(t.start.y, 0.0);
  EXPECT_EQ(t.start.yaw, 0.0);
  ASSERT_EQ(t.timing_gates.size(), 2u);
  EXPECT_NEAR(t.timing_gates[0].left.x(), 0.0, 1e-12);
  EXPECT_NEAR(t.timing_gates[1].left.x(), 75.0, 1e-12);

  // 14 blue and 14 yellow cones every 5 m, 4 big orange cones at each gate, a 75 m braking
  // zone of 15 small orange pairs and a stop-line cone
  EXPECT_EQ(t.count(ConeClass::kBlue), 14);
  EXPECT_EQ(t.count(ConeClass::kYellow), 14);
  EXPECT_EQ(t.count(ConeClass::kOrangeBig), 8);
  EXPECT_EQ(t.count(ConeClass::kOrangeSmall), 31);
  for (const Cone& c : t.cones) {
    if (c.cls == ConeClass::kBlue) {
      EXPECT_NEAR(c.position.y(), 1.9, 1e-12);
    } else if (c.cls == ConeClass::kYellow) {
      EXPECT_NEAR(c.position.y(), -1.9, 1e-12);
    } else if (c.cls == ConeClass::kOrangeSmall) {
      EXPECT_GT(c.position.x(), 75.0);
    }
    EXPECT_LE(c.position.x(), 75.0 + kAccelerationBrakingZoneM + 1e-9);
  }

  // 3.8 m wide, cones at most 5 m apart, a straight centre line from the start to the end
  const TrackStats stats = compute_stats(t);
  EXPECT_NEAR(stats.min_width_m, 3.8, 1e-9);
  EXPECT_NEAR(stats.max_spacing_m, 5.0, 1e-9);
  EXPECT_TRUE(std::isinf(stats.min_radius_m));
  EXPECT_NEAR(stats.length_m, 0.3 + 75.0 + kAccelerationBrakingZoneM, 1e-6);

  const std::vector<Violation> v = check_rules(t, EventType::kAcceleration);
  EXPECT_TRUE(v.empty()) << describe(v);
}

TEST(Acceleration, BrokenGeometryIsReported) {
  // finish gate at 70 m: 5 m short
  Track short_run = make_acceleration();
  short_run.timing_gates[1].left.x() = 70.0;
  short_run.timing_gates[1].right.x() = 70.0;
  std::vector<Violation> v = check_rules(short_run, EventType::kAcceleration);
  ASSERT_EQ(v.size(), 1u) << describe(v);
  EXPECT_EQ(v[0].rule, "acceleration_length");

  // no braking zone: the small orange cones gone from the layout and the lanes
  Track no_brakes = make_acceleration();
  std::erase_if(no_brakes.cones, [](const Cone& c) { return c.cls == ConeClass::kOrangeSmall; });
  for (std::vector<int>* lane : {&no_brakes.left_lane, &no_brakes.right_lane})
    std::erase_if(*lane, [&](int id) {
      return std::none_of(no_brakes.cones.begin(), no_brakes.cones.end(),
                          [id](const Cone& c) { return c.id == id; });
    });
  no_brakes.centre_line = derive_centre_line(no_brakes);
  v = check_rules(no_brakes, EventType::kAcceleration);
  ASSERT_EQ(v.size(), 1u) << describe(v);
  EXPECT_EQ(v[0].rule, "braking_zone");

  // 2.8 m wide: one narrow place along the whole straight
  Track narrow = make_acceleration();
  for (Cone& c : narrow.cones) c.position.y() *= 1.4 / 1.9;
  v = check_rules(narrow, EventType::kAcceleration);
  ASSERT_EQ(v.size(), 1u) << describe(v);
  EXPECT_EQ(v[0].rule, "min_width");
  EXPECT_NE(v[0].message.find("2.80 m wide"), std::string::npos) << v[0].message;
}

TEST(Acceleration, MatchesPacsimAndFssim) {
  const Track ours = make_acceleration();

  // PacSim: the same cones with the same classes, one for one
  const Track pacsim = read_track(kData + "pacsim/acceleration.yaml");
  EXPECT_EQ(pacsim.cones.size(), ours.cones.size());
  for (const Cone& c : pacsim.cones) {
    const Cone& mine = nearest_cone(ours, c.position);
    EXPECT_NEAR((mine.position - c.position).norm(), 0.0, 1e-9) << "PacSim cone " << c.id;
    EXPECT_EQ(mine.cls, c.cls) << "PacSim cone " << c.id;
  }

  // fssim: the same up to 150 m; its braking zone runs on to 175 m (100 m, the older rule)
  const Track fssim = read_track(kData + "fssim/acceleration.yaml");
  int beyond = 0;
  for (const Cone& c : fssim.cones) {
    if (c.position.x() > 75.0 + kAccelerationBrakingZoneM + 1e-9) {
      ++beyond;
      continue;
    }
    const Cone& mine = nearest_cone(ours, c.position);
    EXPECT_NEAR((mine.position - c.position).norm(), 0.0, 1e-9) << "fssim cone " << c.id;
    EXPECT_EQ(mine.cls, c.cls) << "fssim cone " << c.id;
  }
  EXPECT_GT(beyond, 0);
}

TEST(Acceleration, PublicLayoutsPassTheAccelerationRules) {
  // fssim, PacSim (3.8 m wide) and EUFS (3 m wide, gates 75 m apart at x = -50 and 25)
  for (const char* file :
       {"fssim/acceleration.yaml", "pacsim/acceleration.yaml", "eufs/acceleration.csv"}) {
    const Track t = read_track(kData + file);
    const std::vector<Violation> v = check_rules(t, EventType::kAcceleration);
    EXPECT_TRUE(v.empty()) << file << "\n" << describe(v);
  }
}

}  // namespace
}  // namespace conesim::tracks
