// The SLAM scorer on constructed cases: what it counts is what a user reads in metrics.json.

#include "sim/slam_score.hpp"

#include <gtest/gtest.h>

namespace conesim::sim {
namespace {

using core::ConeClass;
using Kind = slam::Association::Kind;

// four cones along a straight, 5 m apart, blue on the left
tracks::Track straight() {
  tracks::Track t;
  t.name = "straight";
  for (int k = 0; k < 4; ++k)
    t.cones.push_back({k, ConeClass::kBlue, core::Vec2(5.0 * k, 1.5), std::nullopt});
  return t;
}

PerceptionView wide_view() {
  return {0.0, 0.0, 100.0, 360.0};
}

// feeds one update: the car at x, the given cones observed and associated as given
struct Feeder {
  SlamScorer& scorer;
  core::TimeUs t = 0;
  void update(double x, const std::vector<int>& true_ids,
              const std::vector<slam::Association>& associations,
              const std::vector<core::MapCone>& map, int loop_closures = 0,
              core::Pose2 estimate_pose = {}) {
    core::ConeObservations obs;
    obs.stamp = t += 100'000;
    for (size_t i = 0; i < true_ids.size(); ++i)
      obs.cones.push_back(
          {core::Vec2(1.0, 1.5), ConeClass::kBlue, Eigen::Matrix2d::Identity() * 0.01, -1});
    core::Estimate e;
    e.pose = estimate_pose;
    e.pose.x += x;
    e.map = map;
    SlamScorer::Update u;
    u.stamp = obs.stamp;
    u.true_pose = {x, 0.0, 0.0};
    u.observations = &obs;
    u.true_ids = &true_ids;
    u.estimate = &e;
    u.associations = &associations;
    u.loop_closures = loop_closures;
    scorer.score(u);
  }
};

std::vector<core::MapCone> true_map(const tracks::Track& t) {
  std::vector<core::MapCone> map;
  for (const auto& c : t.cones)
    map.push_back({c.id, c.cls, c.position, Eigen::Matrix2d::Identity()});
  return map;
}

TEST(SlamScorer, AWrongAssociationIsCountedAtTheMomentItHappens) {
  const tracks::Track track = straight();
  SlamScorer scorer(track, wide_view());
  Feeder feed{scorer};
  // landmark 7 starts on cone 0 and is matched to it twice: right
  feed.update(0.0, {0}, {{7, Kind::kNew}}, true_map(track));
  feed.update(0.5, {0}, {{7, Kind::kMatched}}, true_map(track));
  feed.update(1.0, {0}, {{7, Kind::kMatched}}, true_map(track));
  EXPECT_EQ(scorer.da_correct(), 2);
  EXPECT_EQ(scorer.da_wrong(), 0);
  // then an observation of cone 1 is matched to it: wrong, and marked where the cone was seen
  feed.update(1.5, {1}, {{7, Kind::kMatched}}, true_map(track));
  EXPECT_EQ(scorer.da_wrong(), 1);
  ASSERT_EQ(scorer.wrong_association_places().size(), 1u);
  EXPECT_NEAR(scorer.wrong_association_places()[0].x(), 2.5, 1e-9);
  // a rejected observation is neither right nor wrong; clutter matched to a landmark is wrong
  feed.update(2.0, {2}, {{slam::Association::kNoLandmark, Kind::kRejected}}, true_map(track));
  feed.update(2.5, {-1}, {{7, Kind::kMatched}}, true_map(track));
  EXPECT_EQ(scorer.da_correct(), 2);
  EXPECT_EQ(scorer.da_wrong(), 2);
  const nlohmann::json m = scorer.metrics({});
  EXPECT_DOUBLE_EQ(m["da_correct_fraction"].get<double>(), 0.5);
}

// A spare cone standing off the track is a real cone: observed again and again as one landmark
// it is associated right; matched to a track cone's landmark (or another's) it is wrong.
TEST(SlamScorer, AConeOffTheTrackKeptAsOneLandmarkIsAssociatedRight) {
  const tracks::Track track = straight();
  SlamScorer scorer(track, wide_view());
  Feeder feed{scorer};
  const int spare = core::ObservationLabels::off_track_cone(0);
  feed.update(0.0, {0, spare}, {{7, Kind::kNew}, {8, Kind::kNew}}, true_map(track));
  feed.update(0.5, {0, spare}, {{7, Kind::kMatched}, {8, Kind::kMatched}}, true_map(track));
  EXPECT_EQ(scorer.da_correct(), 2);
  EXPECT_EQ(scorer.da_wrong(), 0);
  feed.update(1.0, {spare, spare - 1}, {{7, Kind::kMatched}, {8, Kind::kMatched}},
              true_map(track));
  EXPECT_EQ(scorer.da_correct(), 2);
  EXPECT_EQ(scorer.da_wrong(), 2);
}

TEST(SlamScorer, ADuplicateLandmarkIsOneMatchAndOneSpurious) {
  const tracks::Track track = straight();
  SlamScorer scorer(track, wide_view());
  scorer.note_cones_in_view({0.0, 0.0, 0.0});
  core::Estimate e;
  e.map = true_map(track);
  // cone 2 mapped twice, 0.1 and 0.3 m off: the nearer copy matches, the other is spurious
  e.map[2].position += core::Vec2(0.1, 0.0);
  e.map.push_back({9, ConeClass::kBlue, track.cones[2].position + core::Vec2(0.0, 0.3),
                   Eigen::Matrix2d::Identity()});
  const nlohmann::json m = scorer.metrics(e);
  EXPECT_EQ(m["map_matched"].get<int>(), 4);
  EXPECT_EQ(m["map_spurious"].get<int>(), 1);
  EXPECT_EQ(m["map_missed"].get<int>(), 0);
  EXPECT_NEAR(m["map_rmse_m"].get<double>(), std::sqrt(0.01 / 4), 1e-12);
  EXPECT_EQ(m["by_class"]["blue"]["spurious"].get<int>(), 1);
  // a cone in view that the map lacks is missed; one never in view is not
  e.map.erase(e.map.begin());
  EXPECT_EQ(scorer.metrics(e)["map_missed"].get<int>(), 1);
  SlamScorer blind(track, {0.0, 0.0, 1.0, 10.0});
  blind.note_cones_in_view({0.0, 0.0, 0.0});
  EXPECT_EQ(blind.metrics(e)["map_missed"].get<int>(), 0);
  EXPECT_TRUE(blind.metrics(e)["map_missed_fraction"].is_null());
}

TEST(SlamScorer, ALoopClosureAwayFromAnyEarlierPlaceIsFalse) {
  const tracks::Track track = straight();
  // a straight drive of 100 m: no place is passed twice, so a closure there is false
  SlamScorer straight_on(track, wide_view());
  Feeder a{straight_on};
  for (int k = 0; k <= 100; ++k) a.update(k, {}, {}, {}, k >= 90 ? 1 : 0);
  EXPECT_EQ(straight_on.loop_closures(), 1);
  EXPECT_EQ(straight_on.false_loop_closures(), 1);
  // a closure after driving 40 m out and 40 m back (80 m, back within 15 m of the start) is real
  SlamScorer out_and_back(track, wide_view());
  Feeder b{out_and_back};
  for (int k = 0; k <= 80; ++k) b.update(k <= 40 ? k : 80 - k, {}, {}, {}, k >= 78 ? 1 : 0);
  EXPECT_EQ(out_and_back.loop_closures(), 1);
  EXPECT_EQ(out_and_back.false_loop_closures(), 0);
  const nlohmann::json events = out_and_back.metrics({})["loop_closure_events"];
  ASSERT_EQ(events.size(), 1u);
  EXPECT_FALSE(events[0]["false"].get<bool>());
}

TEST(SlamScorer, NothingMeasuredIsNullNotZero) {
  const tracks::Track track = straight();
  const SlamScorer scorer(track, wide_view());
  const nlohmann::json m = scorer.metrics({});
  EXPECT_TRUE(m["map_rmse_m"].is_null());
  EXPECT_TRUE(m["ate_rmse_m"].is_null());
  EXPECT_TRUE(m["da_correct_fraction"].is_null());
  EXPECT_TRUE(m["association_us_median"].is_null());
  EXPECT_EQ(m["updates"].get<int>(), 0);
}

TEST(SlamScorer, TrajectoryErrorIsThePositionErrorAtEachUpdate) {
  const tracks::Track track = straight();
  SlamScorer scorer(track, wide_view());
  Feeder feed{scorer};
  // the estimate 0.3 m to the side at every update
  for (int k = 0; k < 5; ++k) feed.update(k, {}, {}, {}, 0, {0.0, 0.3, 0.0});
  EXPECT_NEAR(scorer.metrics({})["ate_rmse_m"].get<double>(), 0.3, 1e-12);
  // aligned, the constant offset goes away
  EXPECT_NEAR(scorer.metrics({})["ate_rmse_aligned_m"].get<double>(), 0.0, 1e-9);
}

}  // namespace
}  // namespace conesim::sim
