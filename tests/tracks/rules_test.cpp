// The rule checker on synthetic layouts whose geometry is known exactly: a compliant oval, and
// variants that each break one rule at a known place.

#include "tracks/rules.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "tracks/fsg_layouts.hpp"

namespace conesim::tracks {
namespace {

constexpr double kPi = std::numbers::pi;

// one piece of centre line: a straight (turn 0) or an arc turning by turn_rad (left positive)
struct Piece {
  double length_m;
  double turn_rad;
};

// pose after travelling `distance` along a piece that starts at `from`
core::Pose2 advance(const core::Pose2& from, const Piece& piece, double distance) {
  const double kappa = piece.turn_rad / piece.length_m;
  if (std::abs(kappa) < 1e-12)
    return {from.x + distance * std::cos(from.yaw), from.y + distance * std::sin(from.yaw),
            from.yaw};
  const double yaw = from.yaw + kappa * distance;
  return {from.x + (std::sin(yaw) - std::sin(from.yaw)) / kappa,
          from.y - (std::cos(yaw) - std::cos(from.yaw)) / kappa, yaw};
}

// a layout built by driving the pieces from `start`: blue cones width/2 to the left, yellow to
// the right, each piece's boundary split evenly into gaps of at most spacing_m. Closed circuits
// get four big orange cones 0.5 m outside the boundaries, 6 m ahead of the start.
Track build_track(const std::vector<Piece>& pieces, double width_m, double spacing_m, bool closed,
                  core::Pose2 start = {}) {
  Track track;
  track.name = "synthetic";
  track.closed = closed;
  track.start = start;
  auto add = [&track](ConeClass cls, const Vec2& p) {
    const int id = static_cast<int>(track.cones.size());
    track.cones.push_back({id, cls, p, std::nullopt});
    return id;
  };

  // boundary cones piece by piece
  core::Pose2 pose = start;
  for (const Piece& piece : pieces) {
    const double kappa = piece.turn_rad / piece.length_m;
    for (const double side : {1.0, -1.0}) {
      const double offset = side * 0.5 * width_m;
      const double boundary_length = piece.length_m * (1.0 - kappa * offset);
      const int n = static_cast<int>(std::ceil(boundary_length / spacing_m - 1e-9));
      for (int k = 0; k < n; ++k) {
        const core::Pose2 p = advance(pose, piece, piece.length_m * k / n);
        const int id =
            add(side > 0 ? ConeClass::kBlue : ConeClass::kYellow, p.transform({0.0, offset}));
        (side > 0 ? track.left_lane : track.right_lane).push_back(id);
      }
    }
    pose = advance(pose, piece, piece.length_m);
  }

  // open layouts end with a cone pair; closed ones get their start/finish cones
  if (!closed) {
    track.left_lane.push_back(add(ConeClass::kBlue, pose.transform({0.0, 0.5 * width_m})));
    track.right_lane.push_back(add(ConeClass::kYellow, pose.transform({0.0, -0.5 * width_m})));
  } else {
    for (const double dx : {5.7, 6.3})
      for (const double side : {1.0, -1.0})
        add(ConeClass::kOrangeBig, start.transform({dx, side * (0.5 * width_m + 0.5)}));
  }
  return track;
}

// an oval driven anticlockwise: straights along x, half circles of centre-line radius radius_m
Track make_oval(double straight_m, double radius_m, double width_m = 3.5, double spacing_m = 3.0) {
  return build_track(
      {{straight_m, 0.0}, {kPi * radius_m, kPi}, {straight_m, 0.0}, {kPi * radius_m, kPi}}, width_m,
      spacing_m, true, {0.0, -radius_m, 0.0});
}

// the violations of one rule
std::vector<Violation> of_rule(const std::vector<Violation>& all, const std::string& rule) {
  std::vector<Violation> out;
  std::copy_if(all.begin(), all.end(), std::back_inserter(out),
               [&](const Violation& v) { return v.rule == rule; });
  return out;
}

// every violation as text, for failure messages
std::string describe(const std::vector<Violation>& all) {
  std::string text;
  for (const Violation& v : all) text += v.to_string() + "\n";
  return text;
}

TEST(Rules, CompliantOvalPasses) {
  // 60 m straights, 15 m radius, 3.5 m wide, cones at most 3 m apart: 214 m lap
  const Track oval = make_oval(60.0, 15.0);
  for (const EventType event : {EventType::kTrackdrive, EventType::kAutocross}) {
    const std::vector<Violation> v = check_rules(oval, event);
    EXPECT_TRUE(v.empty()) << describe(v);
  }
}

TEST(Rules, SixMetreGapIsOneSpacingViolationBetweenItsCones) {
  // drop one blue cone from the middle of the first straight: its neighbours are 6 m apart
  Track oval = make_oval(60.0, 15.0);
  const size_t removed = 10;  // the cone at x = 30 m
  const int before = oval.left_lane[removed - 1];
  const int after = oval.left_lane[removed + 1];
  const Vec2 gap_middle = 0.5 * (oval.cone(before).position + oval.cone(after).position);
  oval.left_lane.erase(oval.left_lane.begin() + removed);

  const std::vector<Violation> all = check_rules(oval, EventType::kTrackdrive);
  ASSERT_EQ(all.size(), 1u) << describe(all);
  EXPECT_EQ(all[0].rule, "max_cone_spacing");
  EXPECT_NEAR((all[0].where - gap_middle).norm(), 0.0, 1e-9);
  EXPECT_NE(all[0].message.find(std::to_string(before)), std::string::npos);
  EXPECT_NE(all[0].message.find(std::to_string(after)), std::string::npos);
  EXPECT_NE(all[0].message.find("6.00 m"), std::string::npos) << all[0].message;
}

TEST(Rules, NarrowSectionsAreOneViolationEach) {
  // two narrow places 2.5 m wide: 15 m of the first straight and 9 m of the second, each made
  // by moving yellow cones 1 m towards the blue ones
  Track oval = make_oval(60.0, 15.0);
  auto narrow = [&oval](double y_lane, double x_lo, double x_hi, double shift) {
    for (Cone& c : oval.cones)
      if (c.cls == ConeClass::kYellow && std::abs(c.position.y() - y_lane) < 1e-6 &&
          c.position.x() >= x_lo && c.position.x() <= x_hi)
        c.position.y() += shift;
  };
  narrow(-16.75, 20.0, 35.0, 1.0);  // first straight, outer (yellow) boundary at y = -16.75
  narrow(16.75, 25.0, 34.0, -1.0);  // second straight, driven towards -x

  const std::vector<Violation> all = check_rules(oval, EventType::kTrackdrive);
  const std::vector<Violation> width = of_rule(all, "min_width");
  ASSERT_EQ(width.size(), 2u) << describe(all);
  EXPECT_EQ(all.size(), 2u) << describe(all);
  for (const Violation& v : width) {
    EXPECT_NE(v.message.find("2.50 m wide"), std::string::npos) << v.message;
    EXPECT_GE(v.where.x(), 20.0);
    EXPECT_LE(v.where.x(), 35.0);
  }
  EXPECT_NEAR(std::abs(width[0].where.y()), 14.5, 1e-6);    // between 13.25 and 15.75
  EXPECT_LT(width[0].where.y() * width[1].where.y(), 0.0);  // one on each straight
}

TEST(Rules, ShortLapBreaksLapLength) {
  // 20 m straights and 10 m radius: 40 + 20 pi = 102.8 m
  const std::vector<Violation> all = check_rules(make_oval(20.0, 10.0), EventType::kTrackdrive);
  const std::vector<Violation> lap = of_rule(all, "lap_length");
  ASSERT_EQ(lap.size(), 1u) << describe(all);
  EXPECT_NE(lap[0].message.find("102."), std::string::npos) << lap[0].message;
  EXPECT_EQ(all.size(), 1u) << describe(all);
}

TEST(Rules, ConeAcrossTheOtherBoundaryIsACrossing) {
  // push a blue cone of the first straight 1 m beyond the yellow boundary
  Track oval = make_oval(60.0, 15.0);
  Cone& moved = oval.cones[static_cast<size_t>(oval.left_lane[10])];  // ids are indices
  moved.position.y() = -15.0 - 1.75 - 1.0;

  const std::vector<Violation> all = check_rules(oval, EventType::kTrackdrive);
  const std::vector<Violation> crossings = of_rule(all, "boundary_crossing");
  ASSERT_EQ(crossings.size(), 2u) << describe(all);  // the segments into and out of the cone
  for (const Violation& v : crossings) {
    EXPECT_NEAR(v.where.y(), -16.75, 1e-6);
    EXPECT_NEAR(v.where.x(), 30.0, 3.0);
  }
}

TEST(Rules, LanesCrossingExactlyAtAConeAreACrossing) {
  // the yellow cone nearest a blue one of the first straight moved exactly onto it: the right
  // lane meets the left lane only at segment ends, and is reported all the same
  Track oval = make_oval(60.0, 15.0);
  const Vec2 blue =
      oval.cones[static_cast<size_t>(oval.left_lane[10])].position;  // ids are indices
  int nearest = oval.right_lane.front();
  for (int id : oval.right_lane)
    if ((oval.cones[static_cast<size_t>(id)].position - blue).norm() <
        (oval.cones[static_cast<size_t>(nearest)].position - blue).norm())
      nearest = id;
  oval.cones[static_cast<size_t>(nearest)].position = blue;
  const std::vector<Violation> all = check_rules(oval, EventType::kTrackdrive);
  const std::vector<Violation> crossings = of_rule(all, "boundary_crossing");
  ASSERT_EQ(crossings.size(), 1u) << describe(all);  // once, at the segments leaving the cone
  EXPECT_NEAR((crossings[0].where - blue).norm(), 0.0, 1e-9);

  // a blue cone moved exactly onto another of its lane: the lane runs through itself there
  Track loop = make_oval(60.0, 15.0);
  loop.cones[static_cast<size_t>(loop.left_lane[20])].position =
      loop.cones[static_cast<size_t>(loop.left_lane[5])].position;
  EXPECT_GE(of_rule(check_rules(loop, EventType::kTrackdrive), "boundary_self_crossing").size(),
            1u);
}

TEST(Rules, SwappedConesMakeASelfCrossing) {
  // swap two blue cones of the first half circle in the lane order: chords that cross
  Track oval = make_oval(60.0, 15.0);
  std::swap(oval.left_lane[22], oval.left_lane[23]);
  const std::vector<Violation> all = check_rules(oval, EventType::kTrackdrive);
  EXPECT_EQ(of_rule(all, "boundary_self_crossing").size(), 1u) << describe(all);
}

TEST(Rules, HairpinTighterThanNineMetresOuterDiameter) {
  // half circles of centre-line radius 2.75 m on a 3 m wide track: outer diameter 8.5 m
  const Track tight = build_track({{95.0, 0.0}, {kPi * 2.75, kPi}, {95.0, 0.0}, {kPi * 2.75, kPi}},
                                  3.0, 2.0, true, {0.0, -2.75, 0.0});
  const std::vector<Violation> all = check_rules(tight, EventType::kTrackdrive);
  const std::vector<Violation> hairpins = of_rule(all, "min_hairpin_diameter");
  ASSERT_EQ(hairpins.size(), 2u) << describe(all);
  EXPECT_GT(std::max(hairpins[0].where.x(), hairpins[1].where.x()), 95.0);
  EXPECT_LT(std::min(hairpins[0].where.x(), hairpins[1].where.x()), 0.0);

  // radius 3.5 m: outer diameter 10 m passes
  const Track legal = build_track({{95.0, 0.0}, {kPi * 3.5, kPi}, {95.0, 0.0}, {kPi * 3.5, kPi}},
                                  3.0, 2.0, true, {0.0, -3.5, 0.0});
  const std::vector<Violation> ok = check_rules(legal, EventType::kTrackdrive);
  EXPECT_TRUE(of_rule(ok, "min_hairpin_diameter").empty()) << describe(ok);
}

TEST(Rules, LongStraightsAndWideTurns) {
  // 90 m straights: two straights too long
  const std::vector<Violation> long_straights =
      check_rules(make_oval(90.0, 15.0), EventType::kTrackdrive);
  const std::vector<Violation> straights = of_rule(long_straights, "max_straight");
  ASSERT_EQ(straights.size(), 2u) << describe(long_straights);
  EXPECT_EQ(long_straights.size(), 2u) << describe(long_straights);

  // 30 m radius half circles: two constant turns 60 m across
  const std::vector<Violation> wide = check_rules(make_oval(20.0, 30.0), EventType::kTrackdrive);
  const std::vector<Violation> turns = of_rule(wide, "max_turn_diameter");
  ASSERT_EQ(turns.size(), 2u) << describe(wide);
  EXPECT_EQ(wide.size(), 2u) << describe(wide);
  for (const Violation& v : turns) EXPECT_NEAR(std::abs(v.where.x() - 10.0), 10.0 + 30.0, 2.0);
}

TEST(Rules, StartPoseAndStartFinishCones) {
  // a start pose outside the track
  Track oval = make_oval(60.0, 15.0);
  oval.start = {30.0, -25.0, 0.0};
  std::vector<Violation> all = check_rules(oval, EventType::kTrackdrive);
  EXPECT_EQ(of_rule(all, "start_on_track").size(), 1u) << describe(all);

  // no big orange cones: a warning, the layout stays compliant
  Track unmarked = make_oval(60.0, 15.0);
  std::erase_if(unmarked.cones, [](const Cone& c) { return c.cls == ConeClass::kOrangeBig; });
  all = check_rules(unmarked, EventType::kTrackdrive);
  ASSERT_EQ(all.size(), 1u) << describe(all);
  EXPECT_EQ(all[0].rule, "start_finish_cones");
  EXPECT_TRUE(all[0].warning);
  EXPECT_TRUE(is_compliant(all));
}

TEST(Rules, LaneWithTwoConesIsAViolation) {
  Track oval = make_oval(60.0, 15.0);
  oval.right_lane.resize(2);
  const std::vector<Violation> all = check_rules(oval, EventType::kTrackdrive);
  ASSERT_EQ(all.size(), 1u) << describe(all);
  EXPECT_EQ(all[0].rule, "lane_cones");
  EXPECT_FALSE(is_compliant(all));
}

TEST(Stats, CircleOfKnownRadius) {
  // a ring track of centre-line radius 20 m, 3.5 m wide, cones at most 3 m apart
  const double radius = 20.0;
  const Track ring =
      build_track({{2.0 * kPi * radius, 2.0 * kPi}}, 3.5, 3.0, true, {0.0, -radius, 0.0});

  // derived centre line: radius within 2 %, length within 1 % (the chords of the polygon)
  const TrackStats stats = compute_stats(ring);
  EXPECT_NEAR(stats.min_radius_m, radius, 0.02 * radius);
  EXPECT_NEAR(stats.length_m, 2.0 * kPi * radius, 0.01 * 2.0 * kPi * radius);
  EXPECT_LE(stats.max_spacing_m, 3.0 + 1e-9);
  EXPECT_GT(stats.max_spacing_m, 2.5);
  // cones sit on the 3.5 m offsets; the other side's chords bulge in by at most s^2 / 8r
  EXPECT_LE(stats.min_width_m, 3.5 + 1e-9);
  EXPECT_GE(stats.min_width_m, 3.5 - 9.0 / (8.0 * (radius - 1.75)) - 1e-9);

  // an exact centre line sampled every metre: radius and length to the sampling error
  Track exact = ring;
  const int n = static_cast<int>(std::round(2.0 * kPi * radius));
  for (int i = 0; i < n; ++i) {
    const double phi = 2.0 * kPi * i / n;
    exact.centre_line.push_back(radius * Vec2(std::sin(phi), -std::cos(phi)));
  }
  const TrackStats exact_stats = compute_stats(exact);
  EXPECT_NEAR(exact_stats.min_radius_m, radius, 0.001 * radius);
  const double polygon = n * 2.0 * radius * std::sin(kPi / n);
  EXPECT_NEAR(exact_stats.length_m, polygon, 1e-9);
}

TEST(Stats, StraightHasInfiniteRadius) {
  const Track straight = build_track({{60.0, 0.0}}, 3.0, 5.0, false);
  const TrackStats stats = compute_stats(straight);
  EXPECT_TRUE(std::isinf(stats.min_radius_m));
  EXPECT_NEAR(stats.length_m, 60.0, 1e-6);
  EXPECT_NEAR(stats.min_width_m, 3.0, 1e-9);
  EXPECT_NEAR(stats.max_spacing_m, 5.0, 1e-9);
}

TEST(InferEvent, FromLayout) {
  // closed: trackdrive; open and winding: autocross
  EXPECT_EQ(infer_event(make_oval(60.0, 15.0)), EventType::kTrackdrive);
  const Track winding = build_track({{40.0, 0.0},
                                     {15.0 * kPi / 2, kPi / 2},
                                     {40.0, 0.0},
                                     {15.0 * kPi / 2, -kPi / 2},
                                     {40.0, 0.0}},
                                    3.5, 4.0, false);
  EXPECT_EQ(infer_event(winding), EventType::kAutocross);

  // open and straight: 75 m is acceleration, 150 m is not
  EXPECT_EQ(infer_event(build_track({{75.0, 0.0}}, 3.8, 5.0, false)), EventType::kAcceleration);
  EXPECT_EQ(infer_event(build_track({{150.0, 0.0}}, 3.8, 5.0, false)), EventType::kAutocross);

  // the generated layouts without their event
  Track skidpad = make_skidpad();
  skidpad.event.reset();
  EXPECT_EQ(infer_event(skidpad), EventType::kSkidpad);
  Track acceleration = make_acceleration();
  acceleration.event.reset();
  EXPECT_EQ(infer_event(acceleration), EventType::kAcceleration);

  // a layout's own event wins
  Track labelled = make_oval(60.0, 15.0);
  labelled.event = EventType::kAutocross;
  EXPECT_EQ(infer_event(labelled), EventType::kAutocross);
}

TEST(RuleLimits, Validation) {
  std::string error;
  EXPECT_TRUE(RuleLimits{}.is_valid(&error));
  RuleLimits bad;
  bad.max_lap_m = 100.0;
  EXPECT_FALSE(bad.is_valid(&error));
  EXPECT_FALSE(error.empty());
}

}  // namespace
}  // namespace conesim::tracks
