// The dead-reckoning baseline: its pose is the odometry and nothing else, its map the
// observations placed on that pose and gathered by nearest neighbour; without association every
// observation stays a landmark of its own.

#include "slam/backends/dead_reckoning.hpp"

#include <gtest/gtest.h>

#include "slam_drive.hpp"
#include "tracks/generator.hpp"

namespace conesim::slam {
namespace {

// one batch: the motion since the previous one and the cones seen (vehicle frame)
SlamInput batch(core::TimeUs from, const core::Pose2& delta, std::vector<core::Vec2> cones) {
  SlamInput in;
  in.odometry.from = from;
  in.odometry.to = from + 100'000;
  in.odometry.delta = delta;
  in.odometry.distance_m = std::hypot(delta.x, delta.y);
  in.observations.stamp = in.odometry.to;
  for (const core::Vec2& c : cones) {
    core::ConeObservation o;
    o.position = c;
    o.cls = core::ConeClass::kBlue;
    in.observations.cones.push_back(o);
  }
  return in;
}

TEST(DeadReckoning, PoseIsTheComposedOdometryAndNothingCorrectsIt) {
  DeadReckoning dr;
  const core::Pose2 start{2.0, -1.0, 0.3};
  dr.reset(start, 0);
  core::Pose2 expected = start;
  const std::vector<core::Pose2> deltas = {{1.0, 0.0, 0.1}, {0.9, 0.05, -0.2}, {1.1, -0.02, 0.05}};
  core::TimeUs t = 0;
  for (const core::Pose2& d : deltas) {
    // a cone right ahead every time: observations never move the pose
    dr.process(batch(t, d, {{5.0, 0.0}}));
    expected = expected.compose(d);
    t += 100'000;
  }
  const core::Estimate e = dr.estimate();
  EXPECT_DOUBLE_EQ(e.pose.x, expected.x);
  EXPECT_DOUBLE_EQ(e.pose.y, expected.y);
  EXPECT_DOUBLE_EQ(e.pose.yaw, expected.yaw);
  EXPECT_EQ(dr.loop_closures(), 0);
  EXPECT_EQ(e.phase, core::SlamPhase::kMapping);
}

TEST(DeadReckoning, NearestNeighbourGathersACone_NoAssociationKeepsEverySighting) {
  // the car stands; one cone seen three times 5 cm apart: one landmark at their mean with nn,
  // three landmarks without association
  const std::vector<core::Vec2> sightings = {{8.0, 1.0}, {8.05, 1.0}, {8.0, 1.05}};
  DeadReckoning nn;
  DeadReckoningConfig none_config;
  none_config.association.method = AssociationMethod::kNone;
  DeadReckoning none(none_config);
  for (DeadReckoning* dr : {&nn, &none}) {
    dr->reset({}, 0);
    for (int k = 0; k < 3; ++k)
      dr->process(batch(k * 100'000, {}, {sightings[static_cast<size_t>(k)]}));
  }
  const core::Estimate a = nn.estimate();
  ASSERT_EQ(a.map.size(), 1u);
  EXPECT_NEAR(a.map[0].position.x(), 8.0 + 0.05 / 3, 1e-12);
  EXPECT_NEAR(a.map[0].position.y(), 1.0 + 0.05 / 3, 1e-12);
  EXPECT_EQ(nn.last_associations()[0].kind, Association::Kind::kMatched);
  EXPECT_EQ(none.estimate().map.size(), 3u);
  EXPECT_EQ(none.last_associations()[0].kind, Association::Kind::kNew);
}

TEST(DeadReckoning, TwoLapsMapEveryConeAndNoAssociationMapsEveryObservation) {
  const tracks::Track track = tracks::generate_circuit(3);
  testing::DriveParams params;
  params.seed = 3;
  DeadReckoning dr;
  const testing::DriveResult r = testing::drive(track, dr, params);
  testing::print("dead reckoning seed 3", r);
  // every cone in view is in the map (nearest neighbour within 1 m gathers it while the
  // odometry's drift stays well below the 3 m between cones) and nothing closes a loop
  EXPECT_EQ(r.loop_closures, 0);
  EXPECT_LE(r.map_missed, r.map_matched / 20);
  EXPECT_GE(r.da_correct_fraction, 0.95);
  EXPECT_FALSE(r.localising_at_end);

  // no association: every observation is a landmark, many times more than there are cones
  DeadReckoningConfig none_config;
  none_config.association.method = AssociationMethod::kNone;
  DeadReckoning none(none_config);
  const testing::DriveResult n = testing::drive(track, none, params);
  EXPECT_GT(n.map_matched + n.map_spurious, 10 * static_cast<int>(track.cones.size()));
  EXPECT_EQ(n.da_correct + n.da_wrong, 0);
  // the same odometry: the same path
  EXPECT_DOUBLE_EQ(n.ate_rmse_m, r.ate_rmse_m);
}

}  // namespace
}  // namespace conesim::slam
