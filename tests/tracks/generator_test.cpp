#include "tracks/generator.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "tracks/rules.hpp"

namespace conesim::tracks {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
constexpr int kSeeds = 200;

// feature thresholds from the generator's design: hairpins are 150-200 deg at a centre-line
// radius of 5-7 m, the start straight is at least 38 m
constexpr double kHairpinMaxRadiusM = 8.0;
constexpr double kHairpinMinTurnDeg = 120.0;
constexpr double kLongStraightM = 30.0;
constexpr double kStraightTurnPerMetreDeg = 0.2;

// turning angle at each vertex of a closed polyline (left positive) and the arc around it
struct Turns {
  std::vector<double> angle;
  std::vector<double> arc_m;
};

Turns turns_of(const std::vector<Vec2>& line) {
  const size_t n = line.size();
  Turns t{std::vector<double>(n), std::vector<double>(n)};
  for (size_t i = 0; i < n; ++i) {
    const Vec2 in = line[i] - line[(i + n - 1) % n];
    const Vec2 out = line[(i + 1) % n] - line[i];
    t.angle[i] = std::atan2(core::cross(in, out), in.dot(out));
    t.arc_m[i] = 0.5 * (in.norm() + out.norm());
  }
  return t;
}

// hairpins: runs of vertices turning one way at a radius under kHairpinMaxRadiusM whose
// turning adds up to more than kHairpinMinTurnDeg
int count_hairpins(const std::vector<Vec2>& line) {
  const Turns t = turns_of(line);
  int hairpins = 0;
  double run = 0.0;                            // turning of the current run
  for (size_t i = 0; i <= line.size(); ++i) {  // the last step ends the last run
    const size_t k = i % line.size();
    const double curvature = t.angle[k] / t.arc_m[k];
    const bool tight = i < line.size() && std::abs(curvature) > 1.0 / kHairpinMaxRadiusM;
    if (tight && (run == 0.0 || (curvature > 0.0) == (run > 0.0))) {
      run += t.angle[k];
      continue;
    }
    if (std::abs(run) > kHairpinMinTurnDeg * kDeg) ++hairpins;
    run = tight ? t.angle[k] : 0.0;
  }
  return hairpins;
}

// longest run of the closed line that turns less than kStraightTurnPerMetreDeg per metre
double longest_straight_m(const std::vector<Vec2>& line) {
  const Turns t = turns_of(line);
  const size_t n = line.size();
  double best = 0.0, run = 0.0;
  for (size_t i = 0; i < 2 * n; ++i) {  // twice round: the start straight wraps
    const size_t k = i % n;
    const bool straight = std::abs(t.angle[k]) < kStraightTurnPerMetreDeg * kDeg * t.arc_m[k];
    run = straight ? run + (line[(k + 1) % n] - line[k]).norm() : 0.0;
    best = std::max(best, run);
  }
  return best;
}

// length of a closed polyline
double closed_length_m(const std::vector<Vec2>& pts) {
  double length = 0.0;
  for (size_t i = 0; i < pts.size(); ++i) length += (pts[(i + 1) % pts.size()] - pts[i]).norm();
  return length;
}

// largest gap between consecutive cones of a closed lane
double max_gap_m(const Track& track, const std::vector<int>& lane) {
  const std::vector<Vec2> pts = track.lane_points(lane);
  double gap = 0.0;
  for (size_t i = 0; i < pts.size(); ++i)
    gap = std::max(gap, (pts[(i + 1) % pts.size()] - pts[i]).norm());
  return gap;
}

// signed distance of p to the left of the nearest segment of the closed line
double lateral_offset_m(const Vec2& p, const std::vector<Vec2>& line) {
  double best = 1e9, signed_best = 0.0;
  for (size_t i = 0; i < line.size(); ++i) {
    const Vec2& a = line[i];
    const Vec2& b = line[(i + 1) % line.size()];
    const double d = core::distance_to_segment(p, a, b);
    if (d < best) {
      best = d;
      signed_best = core::cross(b - a, p - a) > 0.0 ? d : -d;
    }
  }
  return signed_best;
}

// the violations that are more than warnings, one per line
std::string describe(const std::vector<Violation>& violations) {
  std::string out;
  for (const Violation& v : violations)
    if (!v.warning) out += v.to_string() + "\n";
  return out;
}

TEST(Generator, TwoHundredSeedsGiveCompliantRealisticCircuits) {
  const GeneratorParams params;
  for (uint64_t seed = 0; seed < kSeeds; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const Track track = generate_circuit(seed, params);

    // the referee's rules hold
    const std::vector<Violation> violations = check_rules(track, EventType::kTrackdrive);
    EXPECT_TRUE(is_compliant(violations)) << describe(violations);

    // one lap of the designed centre line, sampled every metre
    const double lap_m = closed_length_m(track.centre_line);
    EXPECT_GE(lap_m, params.min_lap_m);
    EXPECT_LE(lap_m, params.max_lap_m);
    EXPECT_NEAR(lap_m / static_cast<double>(track.centre_line.size()), 1.0, 0.01);

    // no boundary gap longer than 5 m, closing gap included
    EXPECT_LE(max_gap_m(track, track.left_lane), 5.0);
    EXPECT_LE(max_gap_m(track, track.right_lane), 5.0);

    // the feature mix: a hairpin and a long straight on every track
    EXPECT_GE(count_hairpins(track.centre_line), 1);
    EXPECT_GE(longest_straight_m(track.centre_line), kLongStraightM);
  }
}

TEST(Generator, TrackHasConesLanesStartZoneAndName) {
  const Track track = generate_circuit(7);
  EXPECT_EQ(track.name, "generated-7");
  EXPECT_TRUE(track.closed);
  ASSERT_TRUE(track.event.has_value());
  EXPECT_EQ(*track.event, EventType::kTrackdrive);

  // every cone has its own id; the lanes hold every blue and yellow cone once
  std::set<int> ids;
  for (const Cone& c : track.cones) ids.insert(c.id);
  EXPECT_EQ(ids.size(), track.cones.size());
  EXPECT_EQ(static_cast<int>(track.left_lane.size()), track.count(ConeClass::kBlue));
  EXPECT_EQ(static_cast<int>(track.right_lane.size()), track.count(ConeClass::kYellow));
  for (int id : track.left_lane) EXPECT_EQ(track.cone(id).cls, ConeClass::kBlue);
  for (int id : track.right_lane) EXPECT_EQ(track.cone(id).cls, ConeClass::kYellow);

  // blue on the left of the driving line, yellow on the right
  for (int id : track.left_lane)
    EXPECT_GT(lateral_offset_m(track.cone(id).position, track.centre_line), 1.0);
  for (int id : track.right_lane)
    EXPECT_LT(lateral_offset_m(track.cone(id).position, track.centre_line), -1.0);

  // start pose at the origin facing +x, the start line 6 m ahead with two big orange cones
  // each side and the timing gate across it; the lanes and the centre line begin there
  EXPECT_EQ(track.start.x, 0.0);
  EXPECT_EQ(track.start.y, 0.0);
  EXPECT_EQ(track.start.yaw, 0.0);
  EXPECT_EQ(track.count(ConeClass::kOrangeBig), 4);
  int left_big = 0;
  for (const Cone& c : track.cones) {
    if (c.cls != ConeClass::kOrangeBig) continue;
    EXPECT_NEAR(c.position.x(), 6.0, 1.5);
    if (c.position.y() > 0.0) ++left_big;
  }
  EXPECT_EQ(left_big, 2);
  ASSERT_EQ(track.timing_gates.size(), 1u);
  const Gate& gate = track.timing_gates.front();
  EXPECT_NEAR(0.5 * (gate.left + gate.right).x(), 6.0, 1e-6);
  EXPECT_NEAR(0.5 * (gate.left + gate.right).y(), 0.0, 1e-6);
  EXPECT_GT(gate.left.y(), 0.0);
  EXPECT_LT((track.centre_line.front() - Vec2(6.0, 0.0)).norm(), 1e-6);
  EXPECT_LT((track.cone(track.left_lane.front()).position - Vec2(6.0, 0.0)).norm(), 3.0);
  EXPECT_LT((track.cone(track.right_lane.front()).position - Vec2(6.0, 0.0)).norm(), 3.0);
}

TEST(Generator, SameSeedGivesTheSameTrack) {
  const Track a = generate_circuit(42);
  const Track b = generate_circuit(42);
  ASSERT_EQ(a.cones.size(), b.cones.size());
  for (size_t i = 0; i < a.cones.size(); ++i) {
    EXPECT_EQ(a.cones[i].id, b.cones[i].id);
    EXPECT_EQ(a.cones[i].cls, b.cones[i].cls);
    EXPECT_EQ(a.cones[i].position, b.cones[i].position);
  }
  EXPECT_EQ(a.left_lane, b.left_lane);
  EXPECT_EQ(a.right_lane, b.right_lane);
  EXPECT_EQ(a.centre_line, b.centre_line);
}

TEST(Generator, DifferentSeedsGiveDifferentTracks) {
  std::vector<Track> tracks;
  for (uint64_t seed = 0; seed < 10; ++seed) tracks.push_back(generate_circuit(seed));
  for (size_t i = 0; i < tracks.size(); ++i) {
    for (size_t j = i + 1; j < tracks.size(); ++j) {
      const bool same_count = tracks[i].cones.size() == tracks[j].cones.size();
      const bool same_shape =
          same_count && std::equal(tracks[i].cones.begin(), tracks[i].cones.end(),
                                   tracks[j].cones.begin(), [](const Cone& a, const Cone& b) {
                                     return (a.position - b.position).norm() < 0.5;
                                   });
      EXPECT_FALSE(same_shape) << "seeds " << i << " and " << j;
    }
  }
}

TEST(Generator, AutocrossTracksFollowTheSameRules) {
  GeneratorParams params;
  params.event = EventType::kAutocross;
  for (uint64_t seed = 0; seed < 10; ++seed) {
    const Track track = generate_circuit(seed, params);
    ASSERT_TRUE(track.event.has_value());
    EXPECT_EQ(*track.event, EventType::kAutocross);
    const std::vector<Violation> violations = check_rules(track, EventType::kAutocross);
    EXPECT_TRUE(is_compliant(violations)) << "seed " << seed << "\n" << describe(violations);
  }
}

TEST(Generator, ReportCountsAttemptsAndFeatures) {
  GenerationReport report;
  const Track track = generate_circuit(3, {}, &report);
  EXPECT_GE(report.attempts, 1);
  EXPECT_EQ(report.attempts, 1 + report.rejected_geometry + report.rejected_rules);
  EXPECT_GE(report.hairpins, 1);
  EXPECT_NEAR(report.lap_m, closed_length_m(track.centre_line), 1.0);
}

TEST(Generator, GivesUpAfterMaxAttempts) {
  // a seed whose first layout is rejected cannot be generated with a single attempt
  uint64_t seed = 0;
  GenerationReport report;
  for (; seed < 50; ++seed) {
    generate_circuit(seed, {}, &report);
    if (report.attempts > 1) break;
  }
  ASSERT_GT(report.attempts, 1);
  GeneratorParams params;
  params.max_attempts = 1;
  EXPECT_THROW(generate_circuit(seed, params), std::runtime_error);
}

TEST(Generator, RejectsParametersTheRulesCannotAllow) {
  GeneratorParams narrow;
  narrow.width_m = 2.5;
  EXPECT_THROW(generate_circuit(0, narrow), std::invalid_argument);
  GeneratorParams sparse;
  sparse.cone_spacing_m = 6.0;
  EXPECT_THROW(generate_circuit(0, sparse), std::invalid_argument);
  GeneratorParams skidpad;
  skidpad.event = EventType::kSkidpad;
  EXPECT_THROW(generate_circuit(0, skidpad), std::invalid_argument);
}

}  // namespace
}  // namespace conesim::tracks
