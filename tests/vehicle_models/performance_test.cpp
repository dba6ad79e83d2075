#include "vehicle_models/performance.hpp"

#include <gtest/gtest.h>

namespace conesim::vehicle_models {
namespace {

TEST(PerformanceEnvelope, LateralLimitMatchesTheMeasuredSkidpad) {
  // the feasibility study measured the car at 1.55 g on a 9.125 m circle at 11.8 m/s with aero
  // and 1.43 g without; the envelope must agree within a few per cent
  const PerformanceEnvelope e = PerformanceEnvelope::of(VehicleParams{});
  EXPECT_NEAR(e.lateral_limit_mps2(11.8) / kGravityMps2, 1.55, 0.05);
  EXPECT_NEAR(e.lateral_limit_mps2(0.0) / kGravityMps2, 1.43, 0.03);
}

TEST(PerformanceEnvelope, GripFractionScalesTheTyresOnly) {
  const PerformanceEnvelope full = PerformanceEnvelope::of(VehicleParams{});
  const PerformanceEnvelope half = PerformanceEnvelope::of(VehicleParams{}, 0.5);
  EXPECT_NEAR(half.lateral_limit_mps2(10.0), 0.5 * full.lateral_limit_mps2(10.0), 1e-9);
  // the brakes are stronger than the tyres, so braking halves too (drag and rolling aside)
  EXPECT_LT(half.decel_limit_mps2(10.0), 0.6 * full.decel_limit_mps2(10.0));
}

TEST(PerformanceEnvelope, PowerAndDragLimitTheSpeed) {
  // 80 kW against 0.78 v^2 of drag: the car tops out near 45 m/s, and accelerates less the faster
  // it goes; the 75 m acceleration run reached 35.6 m/s in the study, well below that
  const PerformanceEnvelope e = PerformanceEnvelope::of(VehicleParams{});
  EXPECT_GT(e.top_speed_mps(), 40.0);
  EXPECT_LT(e.top_speed_mps(), 50.0);
  EXPECT_NEAR(e.accel_limit_mps2(e.top_speed_mps()), 0.0, 1e-6);
  EXPECT_GT(e.accel_limit_mps2(5.0), e.accel_limit_mps2(20.0));
  EXPECT_GT(e.accel_limit_mps2(20.0), e.accel_limit_mps2(30.0));
}

TEST(PerformanceEnvelope, ATwoWheelDriveCarPushesWithItsDrivenAxleOnly) {
  VehicleParams rwd;
  rwd.max_torque_front_nm = 0.0;
  const PerformanceEnvelope e = PerformanceEnvelope::of(rwd);
  // traction: the rear's 55 % of the weight times the friction, below the torque limit
  EXPECT_NEAR(e.max_drive_force_n, 0.55 * e.friction * rwd.mass_kg * kGravityMps2, 1e-6);
}

TEST(PerformanceEnvelope, TheTightestTurnGrowsWithSpeed) {
  const PerformanceEnvelope e = PerformanceEnvelope::of(VehicleParams{});
  EXPECT_LT(e.min_radius_m(5.0), e.min_radius_m(10.0));
  // a 4.5 m hairpin radius (FSG minimum outer diameter 9 m) at about 8 m/s
  EXPECT_NEAR(e.min_radius_m(8.0), 8.0 * 8.0 / e.lateral_limit_mps2(8.0), 1e-12);
}

}  // namespace
}  // namespace conesim::vehicle_models
