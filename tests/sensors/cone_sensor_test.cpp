#include "sensors/cone_sensor.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace conesim::sensors {
namespace {

using core::ConeClass;

// a track with one cone at a known place
tracks::Track one_cone(double x, double y, ConeClass cls) {
  tracks::Track t;
  t.name = "one-cone";
  t.cones.push_back({0, cls, {x, y}, std::nullopt});
  return t;
}

TEST(ConeSensor, RangeAndBearingNoiseHaveTheConfiguredSigma) {
  ConeSensorConfig config;
  config.false_positives_per_frame = 0.0;
  config.detection_probability_near = 1.0;
  ConeSensor sensor(config, 5);
  // a cone 8 m ahead of the mount, 3 m to the left
  const double mx = config.mount_x_m;
  const tracks::Track track = one_cone(mx + 8.0, 3.0, ConeClass::kBlue);
  const double true_range = std::hypot(8.0, 3.0);
  const double true_bearing = std::atan2(3.0, 8.0);
  double sr = 0, sr2 = 0, sb = 0, sb2 = 0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    const auto [obs, labels] = sensor.sample(track, {}, 0, nullptr);
    ASSERT_EQ(obs.cones.size(), 1u);
    EXPECT_EQ(labels.cone_id[0], 0);
    const core::Vec2 p = obs.cones[0].position - core::Vec2(mx, 0.0);
    const double dr = p.norm() - true_range;
    const double db = std::atan2(p.y(), p.x()) - true_bearing;
    sr += dr, sr2 += dr * dr, sb += db, sb2 += db * db;
  }
  const double range_sd = std::sqrt(sr2 / n - (sr / n) * (sr / n));
  const double bearing_sd = std::sqrt(sb2 / n - (sb / n) * (sb / n));
  EXPECT_NEAR(range_sd, config.range_sigma_m, 0.03 * config.range_sigma_m);
  EXPECT_NEAR(bearing_sd, config.bearing_sigma_rad, 0.03 * config.bearing_sigma_rad);
  EXPECT_NEAR(sr / n, 0.0, 4.0 * config.range_sigma_m / std::sqrt(n));
}

TEST(ConeSensor, CovarianceDescribesTheScatter) {
  ConeSensorConfig config;
  config.false_positives_per_frame = 0.0;
  config.detection_probability_near = 1.0;
  ConeSensor sensor(config, 9);
  const tracks::Track track = one_cone(config.mount_x_m + 4.0, -7.0, ConeClass::kYellow);
  // normalised squared errors average to the dimension (2) when the covariance is right
  double nees = 0.0;
  const int n = 5000;
  for (int i = 0; i < n; ++i) {
    const auto [obs, labels] = sensor.sample(track, {}, 0, nullptr);
    const core::Vec2 e = obs.cones[0].position - track.cones[0].position;
    nees += e.dot(obs.cones[0].covariance.inverse() * e);
  }
  EXPECT_NEAR(nees / n, 2.0, 0.15);
}

TEST(ConeSensor, ColourIsKnownOnlyCloseBy) {
  ConeSensorConfig config;
  config.false_positives_per_frame = 0.0;
  config.detection_probability_near = 1.0;
  config.detection_probability_far = 1.0;
  ConeSensor sensor(config, 2);
  const tracks::Track near = one_cone(config.mount_x_m + 6.0, 0.0, ConeClass::kBlue);
  const tracks::Track far = one_cone(config.mount_x_m + 13.0, 0.0, ConeClass::kBlue);
  int near_blue = 0, near_wrong = 0, far_known = 0;
  const int n = 10000;
  for (int i = 0; i < n; ++i) {
    const ConeClass a = sensor.sample(near, {}, 0, nullptr).first.cones[0].cls;
    near_blue += a == ConeClass::kBlue;
    near_wrong += a == ConeClass::kYellow;
    far_known += sensor.sample(far, {}, 0, nullptr).first.cones[0].cls != ConeClass::kUnknown;
  }
  const double p = config.colour_probability * (1.0 - config.colour_confusion_probability);
  EXPECT_NEAR(static_cast<double>(near_blue) / n, p, 4.0 * std::sqrt(p * (1 - p) / n));
  EXPECT_GT(near_wrong, 0);
  EXPECT_EQ(far_known, 0);
}

TEST(ConeSensor, DetectionFallsWithRangeAndFieldOfViewIsRespected) {
  ConeSensorConfig config;
  config.false_positives_per_frame = 0.0;
  ConeSensor sensor(config, 4);
  const tracks::Track edge = one_cone(config.mount_x_m + 14.5, 0.0, ConeClass::kBlue);
  const tracks::Track behind = one_cone(config.mount_x_m - 5.0, 0.0, ConeClass::kBlue);
  const tracks::Track outside = one_cone(config.mount_x_m + 16.0, 0.0, ConeClass::kBlue);
  int seen = 0;
  const int n = 10000;
  for (int i = 0; i < n; ++i) {
    seen += !sensor.sample(edge, {}, 0, nullptr).first.cones.empty();
    EXPECT_TRUE(sensor.sample(behind, {}, 0, nullptr).first.cones.empty());
    EXPECT_TRUE(sensor.sample(outside, {}, 0, nullptr).first.cones.empty());
  }
  const double p = sensor.detection_probability(14.5);
  EXPECT_LT(p, config.detection_probability_near);
  EXPECT_NEAR(static_cast<double>(seen) / n, p, 4.0 * std::sqrt(p * (1 - p) / n));
}

TEST(ConeSensor, FalsePositivesAreLabelledAndKnockedConesUnseen) {
  ConeSensorConfig config;
  config.false_positives_per_frame = 0.5;
  ConeSensor sensor(config, 8);
  const tracks::Track track = one_cone(config.mount_x_m + 5.0, 0.0, ConeClass::kYellow);
  int spurious = 0;
  const int n = 4000;
  for (int i = 0; i < n; ++i) {
    const auto [obs, labels] = sensor.sample(track, {}, 0, [](int) { return true; });
    for (int id : labels.cone_id) {
      EXPECT_EQ(id, core::ObservationLabels::kFalsePositive);
      ++spurious;
    }
  }
  EXPECT_NEAR(static_cast<double>(spurious) / n, 0.5, 4.0 * std::sqrt(0.5 / n));
}

TEST(ConeSensor, ObservationsAreInTheVehicleFrame) {
  ConeSensorConfig config;
  config.false_positives_per_frame = 0.0;
  config.detection_probability_near = 1.0;
  config.range_sigma_m = 0.0;
  config.bearing_sigma_rad = 0.0;
  ConeSensor sensor(config, 1);
  const core::Pose2 pose{10.0, 5.0, std::numbers::pi / 2};
  const tracks::Track track = one_cone(10.0, 5.0 + config.mount_x_m + 6.0, ConeClass::kBlue);
  const auto obs = sensor.sample(track, pose, 0, nullptr).first;
  ASSERT_EQ(obs.cones.size(), 1u);
  EXPECT_NEAR(obs.cones[0].position.x(), config.mount_x_m + 6.0, 1e-9);
  EXPECT_NEAR(obs.cones[0].position.y(), 0.0, 1e-9);
}

}  // namespace
}  // namespace conesim::sensors
