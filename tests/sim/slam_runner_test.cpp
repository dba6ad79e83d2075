// SLAM in the loop: an update's latency on the sim clock.

#include <gtest/gtest.h>

#include <string>

#include "sim/run.hpp"
#include "sim/scenario.hpp"
#include "sim/slam_runner.hpp"
#include "sim/vehicle_sim.hpp"

namespace conesim::sim {
namespace {

using core::TimeUs;

// the acceleration track's car standing at the start, with SLAM of the given latency
struct StandingCar {
  explicit StandingCar(const std::string& latency_s)
      : scenario(load_scenario(find_scenario("acceleration-graphslam"),
                               {"slam_latency_s=" + latency_s})),
        track(scenario_track(scenario)),
        car(scenario.vehicle,
            track.start.compose({-scenario.vehicle.front_overhang_from_rear_axle_m, 0.0, 0.0})),
        slam(scenario, track, car) {}

  // the vehicle sensors sampled every physics step up to t
  void run_sensors_to(TimeUs t) {
    for (; now < t;) slam.step(now += 2000, car);
  }

  // the true cones 2-14 m ahead as seen from the car, stamped t
  DeliveredDetections frame(TimeUs t) const {
    DeliveredDetections d;
    d.capture_pose = car.truth().pose;
    d.observations.stamp = t;
    for (const tracks::Cone& c : track.cones) {
      const core::Vec2 local = d.capture_pose.inverse_transform(c.position);
      if (local.x() < 2.0 || local.x() > 14.0) continue;
      d.observations.cones.push_back({local, c.cls, Eigen::Matrix2d::Identity() * 0.01, -1});
      d.labels.cone_id.push_back(c.id);
    }
    return d;
  }

  Scenario scenario;
  tracks::Track track;
  VehicleSim car;
  SlamRunner slam;
  TimeUs now = 0;
};

TEST(SlamRunner, AnUpdateTakesEffectOnlyOnceItsLatencyHasPassed) {
  StandingCar at_once("0"), late("0.05");
  // three frames confirm the cones ahead: at once without a latency...
  for (TimeUs t : {100'000, 200'000, 300'000}) {
    for (StandingCar* c : {&at_once, &late}) {
      c->run_sensors_to(t);
      c->slam.catch_up(t);
      c->slam.process(c->frame(t), t);
    }
  }
  const core::Estimate now = at_once.slam.estimate_now(300'000);
  ASSERT_GE(now.map.size(), 4u);

  // ...and 50 ms later with one: not a step before
  EXPECT_TRUE(late.slam.estimate_now(300'000).map.empty());
  late.run_sensors_to(348'000);
  late.slam.catch_up(348'000);
  EXPECT_TRUE(late.slam.estimate_now(348'000).map.empty());
  late.run_sensors_to(350'000);
  late.slam.catch_up(350'000);
  const core::Estimate then = late.slam.estimate_now(350'000);

  // the same update on the same input: the same map, and the pose carried forward meanwhile
  ASSERT_EQ(then.map.size(), now.map.size());
  for (size_t i = 0; i < now.map.size(); ++i) {
    EXPECT_EQ(then.map[i].position, now.map[i].position);
    EXPECT_EQ(then.map[i].cls, now.map[i].cls);
  }
  EXPECT_NEAR(then.pose.x, now.pose.x, 1e-3);
  EXPECT_NEAR(then.pose.y, now.pose.y, 1e-3);
}

TEST(SlamRunner, FinishTakesInTheUpdatesStillRunning) {
  StandingCar late("0.5");
  for (TimeUs t : {100'000, 200'000, 300'000}) {
    late.run_sensors_to(t);
    late.slam.catch_up(t);
    late.slam.process(late.frame(t), t);
  }
  EXPECT_EQ(late.slam.metrics()["updates"].get<int>(), 0);
  late.slam.finish();
  EXPECT_EQ(late.slam.metrics()["updates"].get<int>(), 3);
  EXPECT_FALSE(late.slam.estimate_now(late.now).map.empty());
}

TEST(SlamRunner, AnUpdateProcessedAheadTakesEffectAtItsTickAsIfRunThere) {
  // frames captured at t and taken at the next tick, 50 ms later: processed there, or ahead
  // as soon as their input is final (the vehicle sensors' samples arrive 2 ms late)
  StandingCar at_tick("0"), ahead("0");
  for (TimeUs t : {100'000, 200'000, 300'000}) {
    const TimeUs tick = t + 50'000;
    at_tick.run_sensors_to(tick);
    at_tick.slam.catch_up(tick);
    at_tick.slam.process(at_tick.frame(t), tick);

    ahead.run_sensors_to(t);
    const DeliveredDetections frame = ahead.frame(t);
    ASSERT_FALSE(ahead.slam.input_final(frame, t));
    ahead.run_sensors_to(t + 2000);
    ASSERT_TRUE(ahead.slam.input_final(frame, t + 2000));
    ahead.slam.process_ahead(frame, tick);
    ahead.run_sensors_to(tick - 2000);
    ahead.slam.catch_up(tick - 2000);
    // not a step before its tick: the third frame confirms the cones
    if (t == 300'000) {
      EXPECT_TRUE(ahead.slam.estimate_now(tick - 2000).map.empty());
    }
    ahead.run_sensors_to(tick);
    ahead.slam.catch_up(tick);
  }
  const core::Estimate expected = at_tick.slam.estimate_now(350'000);
  const core::Estimate got = ahead.slam.estimate_now(350'000);
  ASSERT_GE(expected.map.size(), 4u);
  ASSERT_EQ(got.map.size(), expected.map.size());
  for (size_t i = 0; i < got.map.size(); ++i) {
    EXPECT_EQ(got.map[i].position, expected.map[i].position);
    EXPECT_EQ(got.map[i].covariance, expected.map[i].covariance);
  }
  EXPECT_EQ(got.pose.x, expected.pose.x);
  EXPECT_EQ(got.pose.y, expected.pose.y);
  EXPECT_EQ(got.pose.yaw, expected.pose.yaw);
  EXPECT_EQ(ahead.slam.odometry_pose_now(350'000).x, at_tick.slam.odometry_pose_now(350'000).x);
}

TEST(SlamRunner, AnUpdateProcessedAheadForATickNeverReachedIsDropped) {
  StandingCar ahead("0");
  for (TimeUs t : {100'000, 200'000}) {
    ahead.run_sensors_to(t + 2000);
    ahead.slam.process_ahead(ahead.frame(t), t + 50'000);
    ahead.run_sensors_to(t + 50'000);
    ahead.slam.catch_up(t + 50'000);
  }
  // the run ends before the third frame's tick
  ahead.run_sensors_to(302'000);
  ahead.slam.process_ahead(ahead.frame(300'000), 350'000);
  ahead.slam.finish();
  EXPECT_EQ(ahead.slam.metrics()["updates"].get<int>(), 2);
}

}  // namespace
}  // namespace conesim::sim
