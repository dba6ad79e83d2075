#include "control/speed_profile.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "test_tracks.hpp"

namespace conesim::control {
namespace {

constexpr double kPi = std::numbers::pi;

// straight of length a, a left hairpin (180 degrees) of radius r, straight of length b;
// points every 0.5 m. Returns the path and the arc length where the hairpin begins.
Path straight_hairpin_straight(double a, double r, double b, double* hairpin_s) {
  constexpr double kStepM = 0.5;
  Path path;
  for (double x = 0.0; x < a; x += kStepM) path.points.push_back({x, 0.0});
  *hairpin_s = a;
  const int n = static_cast<int>(std::ceil(kPi * r / kStepM));
  for (int i = 0; i < n; ++i) {
    const double phi = -0.5 * kPi + kPi * i / n;
    path.points.push_back(Vec2(a, r) + r * Vec2(std::cos(phi), std::sin(phi)));
  }
  for (double x = a; x > a - b; x -= kStepM) path.points.push_back({x, 2.0 * r});
  return path;
}

TEST(SpeedProfile, PointCapsHoldWithBrakingBeforeThem) {
  // a 100 m straight capped at 7 m/s from 60 to 70 m: at most 7 there, braking reaches it
  // from the 20 m/s cap at the braking limit, and the car speeds up again after it
  Path path;
  for (int i = 0; i <= 200; ++i) path.points.push_back({0.5 * i, 0.0});
  SpeedLimits limits;
  limits.max_speed_mps = 20.0;
  std::vector<double> caps(path.points.size(), std::numeric_limits<double>::infinity());
  for (int i = 120; i <= 140; ++i) caps[static_cast<size_t>(i)] = 7.0;
  const SpeedProfile p = plan_speed(path, limits, 20.0, std::nullopt, caps);
  for (int i = 120; i <= 140; ++i) EXPECT_LE(p.speed_mps[static_cast<size_t>(i)], 7.0 + 1e-9);
  const double braking_m = (20.0 * 20.0 - 7.0 * 7.0) / (2.0 * limits.max_decel_mps2);
  EXPECT_NEAR(p.speed_at(60.0 - braking_m - 1.0), 20.0, 1e-6);
  EXPECT_GT(p.speed_at(90.0), 15.0);
  // a cap vector of another length is ignored
  const SpeedProfile q = plan_speed(path, limits, 20.0, std::nullopt, {7.0});
  EXPECT_NEAR(q.speed_at(65.0), 20.0, 1e-6);
}

TEST(SpeedProfile, RespectsTheLateralLimitOnAKnownCurvature) {
  // a closed circle of radius 10 m: v = sqrt(a_lat r) everywhere, below the cap
  constexpr double kRadiusM = 10.0;
  Path path;
  path.closed = true;
  for (int i = 0; i < 126; ++i) {
    const double phi = 2.0 * kPi * i / 126;
    path.points.push_back(kRadiusM * Vec2(std::cos(phi), std::sin(phi)));
  }
  SpeedLimits limits;
  limits.max_speed_mps = 30.0;
  const SpeedProfile profile = plan_speed(path, limits);
  ASSERT_EQ(profile.speed_mps.size(), path.points.size());
  for (double v : profile.speed_mps) {
    // the chords' circle is the circle: the lateral acceleration is the limit within 0.5 %
    EXPECT_LE(v * v / kRadiusM, limits.max_lateral_accel_mps2 * 1.005);
    EXPECT_GE(v * v / kRadiusM, limits.max_lateral_accel_mps2 * 0.995);
  }
}

TEST(SpeedProfile, DeceleratesBeforeAHairpinWithinTheLimits) {
  double hairpin_s = 0.0;
  constexpr double kHairpinRadiusM = 5.0;
  const Path path = straight_hairpin_straight(80.0, kHairpinRadiusM, 40.0, &hairpin_s);
  SpeedLimits limits;
  limits.max_speed_mps = 16.0;
  const SpeedProfile profile = plan_speed(path, limits, 0.0, std::nullopt);
  const std::vector<double>& s = profile.s_m;
  const std::vector<double>& v = profile.speed_mps;
  const double v_hairpin = std::sqrt(limits.max_lateral_accel_mps2 * kHairpinRadiusM);

  // the longitudinal limits hold between every two points
  for (size_t i = 0; i + 1 < v.size(); ++i) {
    const double a = (v[i + 1] * v[i + 1] - v[i] * v[i]) / (2.0 * (s[i + 1] - s[i]));
    EXPECT_LE(a, limits.max_accel_mps2 + 1e-9) << "at s " << s[i];
    EXPECT_GE(a, -limits.max_decel_mps2 - 1e-9) << "at s " << s[i];
  }

  // inside the hairpin the lateral limit holds (the curvature stencil blurs its ends by 1 m)
  for (size_t i = 0; i < v.size(); ++i)
    if (s[i] > hairpin_s + 1.0 && s[i] < hairpin_s + kPi * kHairpinRadiusM - 1.0) {
      EXPECT_LE(v[i], v_hairpin * 1.01) << "at s " << s[i];
    }

  // braking starts before the hairpin: slow just before it, at the cap well before it
  const double braking_m = (limits.max_speed_mps * limits.max_speed_mps - v_hairpin * v_hairpin) /
                           (2.0 * limits.max_decel_mps2);
  // (1 m before it: braking from the hairpin speed over that metre and the stencil's 1 m blur)
  EXPECT_LT(profile.speed_at(hairpin_s - 1.0),
            std::sqrt(v_hairpin * v_hairpin + 2.0 * limits.max_decel_mps2 * 2.0));
  EXPECT_LT(profile.speed_at(hairpin_s - 0.5 * braking_m), limits.max_speed_mps - 1.0);
  EXPECT_NEAR(profile.speed_at(hairpin_s - braking_m - 10.0), limits.max_speed_mps, 1e-9);
  // starts from rest
  EXPECT_DOUBLE_EQ(v.front(), 0.0);
}

TEST(SpeedProfile, TightTurnSpeedHoldsFromBeforeAFullLockHairpinOnTheRacingLine) {
  // a hairpin at the car's full-lock radius on a closed path (a racing line): the car is at the
  // tight-turn speed before the line reaches it (it turns in ahead of the line's tightest point),
  // not only on it; the exploration's open paths get no lead; a hairpin wider than the tight-turn
  // share of full lock is not capped at all
  double hairpin_s = 0.0;
  SpeedLimits limits;
  limits.max_speed_mps = 16.0;
  limits.max_lateral_accel_mps2 = 30.0;  // the cap, not the grip, limits the tight turn
  limits.max_curvature = 1.0 / 3.0;
  Path line = straight_hairpin_straight(60.0, 3.0, 30.0, &hairpin_s);
  line.closed = true;  // back from the end of the second straight to the start
  const SpeedProfile p = plan_speed(line, limits);
  // (the curvature stencil blurs the hairpin's start by up to 1 m either way)
  for (double before : {0.0, 0.25})
    EXPECT_LE(p.speed_at(hairpin_s - before, line.length()), limits.tight_turn_speed_mps + 1e-9)
        << before << " m before the hairpin";
  EXPECT_GT(p.speed_at(hairpin_s - 4.0, line.length()), limits.tight_turn_speed_mps + 1.0);
  line.closed = false;
  EXPECT_GT(plan_speed(line, limits, 16.0, std::nullopt).speed_at(hairpin_s - 0.25),
            limits.tight_turn_speed_mps + 0.5);
  const Path wide = straight_hairpin_straight(60.0, 6.0, 30.0, &hairpin_s);
  EXPECT_GT(plan_speed(wide, limits, 16.0, std::nullopt).speed_at(hairpin_s + 3.0),
            2.0 * limits.tight_turn_speed_mps);
}

TEST(SpeedProfile, AChicaneIsTakenSlowlyEnoughForTheSteeringToSwingAcross) {
  // a straight, 60 degrees left at radius 4 m, at once 60 degrees right at radius 4 m, a
  // straight: the curvature swings by 0.5 1/m at the joint. With the steering able to change the
  // curvature by 0.5 1/m per second, the car must spend at least 1 s about the joint; the
  // lateral limit alone (6 m/s at radius 4 m) would give the 2.5 m about it 0.42 s
  constexpr double kRadiusM = 4.0, kRatePerS = 0.5;
  testing::CentreLine c;
  c.straight(20.0).arc(kRadiusM, kPi / 3.0).arc(kRadiusM, -kPi / 3.0).straight(20.0);
  Path path;
  path.points = c.points();
  const double joint_s = 20.0 + kPi / 3.0 * kRadiusM;

  SpeedLimits limits;
  limits.max_speed_mps = 16.0;
  // the time the profile gives the stretch about the joint over which the curvature's change is
  // measured (1 m either side, rounded up to the points' spacing of 0.1 m), and a little more
  auto time_near_joint = [&](const SpeedProfile& p) {
    double t = 0.0;
    for (double s = joint_s - 1.25; s < joint_s + 1.25; s += 0.01) t += 0.01 / p.speed_at(s);
    return t;
  };
  const double free_time = time_near_joint(plan_speed(path, limits, 16.0));
  limits.max_curvature_rate_per_s = kRatePerS;
  const SpeedProfile p = plan_speed(path, limits, 16.0);
  EXPECT_LT(free_time, 0.5);
  // (the curvature stencil spreads the swing over a little more than its 0.5 1/m)
  EXPECT_GE(time_near_joint(p), 2.0 / kRadiusM / kRatePerS * 0.9);
  // the straights before and after are not slowed beyond braking for the joint
  EXPECT_GT(p.speed_at(5.0), 10.0);
  EXPECT_GT(p.speed_at(joint_s + 15.0), 10.0);
}

TEST(SpeedProfile, OpenPathEndsAtTheEndSpeed) {
  Path path;
  for (int i = 0; i <= 100; ++i) path.points.push_back({0.5 * i, 0.0});
  SpeedLimits limits;
  const SpeedProfile profile = plan_speed(path, limits, 10.0, 0.0);
  EXPECT_DOUBLE_EQ(profile.speed_mps.back(), 0.0);
  // braking to rest from the cap takes v^2 / 2 a: the profile is at the cap before that
  const double braking_m =
      limits.max_speed_mps * limits.max_speed_mps / (2.0 * limits.max_decel_mps2);
  EXPECT_NEAR(profile.speed_at(50.0 - braking_m - 0.5), limits.max_speed_mps, 1e-9);
  EXPECT_NEAR(profile.speed_at(50.0 - 0.5 * braking_m),
              std::sqrt(2.0 * limits.max_decel_mps2 * 0.5 * braking_m), 0.05);
}

// limits that only the car's envelope at `grip_fraction` binds (the constant caps far above it)
SpeedLimits envelope_only(const vehicle_models::VehicleParams& car, double grip_fraction) {
  SpeedLimits limits;
  limits.max_speed_mps = 60.0;
  limits.max_lateral_accel_mps2 = 100.0;
  limits.max_accel_mps2 = 100.0;
  limits.max_decel_mps2 = 100.0;
  limits.envelope = vehicle_models::PerformanceEnvelope::of(car, grip_fraction);
  return limits;
}

TEST(SpeedProfile, RespectsTheEnvelopeAtTheGripFraction) {
  // the car's envelope at 0.8 of its measured grip: on the hairpin the lateral acceleration is
  // the envelope's at that speed, and between points the speed changes within the envelope's
  // drive and braking limits (with the lateral share taken off: friction ellipse)
  double hairpin_s = 0.0;
  constexpr double kHairpinRadiusM = 6.0;
  const Path path = straight_hairpin_straight(120.0, kHairpinRadiusM, 80.0, &hairpin_s);
  vehicle_models::VehicleParams car;
  SpeedLimits limits = envelope_only(car, 0.8);
  const SpeedProfile profile = plan_speed(path, limits, 0.0, std::nullopt);
  const std::vector<double>& s = profile.s_m;
  const std::vector<double>& v = profile.speed_mps;
  const auto& e = *limits.envelope;
  const std::vector<double> k = curvatures(path.points, false);
  for (size_t i = 0; i + 1 < v.size(); ++i) {
    EXPECT_LE(v[i] * v[i] * std::abs(k[i]), e.lateral_limit_mps2(v[i]) * 1.001) << i;
    const double a = (v[i + 1] * v[i + 1] - v[i] * v[i]) / (2.0 * (s[i + 1] - s[i]));
    EXPECT_LE(a, e.accel_limit_mps2(v[i]) + 1e-6) << i;
    EXPECT_GE(a, -e.decel_limit_mps2(v[i + 1]) - 1e-6) << i;
  }
  // mid-hairpin the car runs at the envelope's corner speed, faster than 0.8 g would allow
  // without downforce, and on the straight it reaches well over 16 m/s
  const size_t mid = static_cast<size_t>(
      std::lower_bound(s.begin(), s.end(), hairpin_s + 0.5 * kPi * kHairpinRadiusM) - s.begin());
  const double v_corner = v[mid];
  EXPECT_NEAR(v_corner * v_corner / kHairpinRadiusM, e.lateral_limit_mps2(v_corner),
              0.02 * e.lateral_limit_mps2(v_corner));
  EXPECT_GT(*std::max_element(v.begin(), v.end()), 20.0);
  // at full grip the same corner is faster
  SpeedLimits full = limits;
  full.envelope = vehicle_models::PerformanceEnvelope::of(car, 1.0);
  EXPECT_GT(plan_speed(path, full, 0.0, std::nullopt).speed_mps[mid], v_corner * 1.05);
}

TEST(SpeedProfile, ALateralShareSlowsTheCornerAndKeepsTheBraking) {
  // lap 1 turns with a share of the grip and brakes with all of it: the hairpin's speed falls
  // to the share's corner speed, while on the straight before it the car brakes as hard as
  // without the share
  double hairpin_s = 0.0;
  constexpr double kHairpinRadiusM = 6.0;
  const Path path = straight_hairpin_straight(120.0, kHairpinRadiusM, 80.0, &hairpin_s);
  const SpeedLimits limits = envelope_only(vehicle_models::VehicleParams{}, 0.7);
  SpeedLimits shared = limits;
  shared.lateral_share = 0.55 / 0.7;
  const SpeedProfile all = plan_speed(path, limits, 0.0, std::nullopt);
  const SpeedProfile part = plan_speed(path, shared, 0.0, std::nullopt);
  const std::vector<double>& s = part.s_m;
  const size_t mid = static_cast<size_t>(
      std::lower_bound(s.begin(), s.end(), hairpin_s + 0.5 * kPi * kHairpinRadiusM) - s.begin());
  const double v = part.speed_mps[mid];
  EXPECT_NEAR(v * v / kHairpinRadiusM,
              shared.lateral_share * limits.envelope->lateral_limit_mps2(v),
              0.02 * limits.envelope->lateral_limit_mps2(v));
  EXPECT_LT(v, all.speed_mps[mid] * 0.95);
  // the hardest braking on the straight is the envelope's, with or without the share
  auto hardest = [&](const SpeedProfile& p) {
    double d = 0.0;
    for (size_t i = 0; i + 1 < p.s_m.size() && p.s_m[i + 1] < hairpin_s; ++i)
      d = std::max(d, (p.speed_mps[i] * p.speed_mps[i] - p.speed_mps[i + 1] * p.speed_mps[i + 1]) /
                          (2.0 * (p.s_m[i + 1] - p.s_m[i])));
    return d;
  };
  EXPECT_NEAR(hardest(part), hardest(all), 0.02 * hardest(all));
  EXPECT_GT(hardest(part), 0.9 * limits.envelope->decel_limit_mps2(10.0));
}

}  // namespace
}  // namespace conesim::control
