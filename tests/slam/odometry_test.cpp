// Odometry: the arc step's hand-written Jacobians against numerical ones, a circle driven with
// wheel speeds, steering and gyro closes where it started, and the covariance is honest.

#include "slam/odometry.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <numbers>
#include <utility>

#include "core/rng.hpp"

namespace conesim::slam {
namespace {

Eigen::Vector3d as_vector(const core::Pose2& p) {
  return {p.x, p.y, p.yaw};
}

TEST(ArcStep, JacobiansMatchNumerical) {
  const double h = 1e-6;
  for (const double dyaw : {0.0, 1e-6, 0.05, -0.4}) {
    const core::Pose2 pose{1.0, 2.0, 0.8};
    const double ds = 0.9;
    Eigen::Matrix3d f_pose;
    Eigen::Matrix<double, 3, 2> f_motion;
    arc_step_jacobians(pose, ds, dyaw, &f_pose, &f_motion);
    // by the pose
    for (int k = 0; k < 3; ++k) {
      Eigen::Vector3d plus = as_vector(pose), minus = as_vector(pose);
      plus[k] += h;
      minus[k] -= h;
      const Eigen::Vector3d col = (as_vector(arc_step({plus[0], plus[1], plus[2]}, ds, dyaw)) -
                                   as_vector(arc_step({minus[0], minus[1], minus[2]}, ds, dyaw))) /
                                  (2 * h);
      EXPECT_LT((col - f_pose.col(k)).norm(), 1e-6) << "dyaw " << dyaw << " column " << k;
    }
    // by the motion (ds, dyaw)
    const Eigen::Vector3d d_ds =
        (as_vector(arc_step(pose, ds + h, dyaw)) - as_vector(arc_step(pose, ds - h, dyaw))) /
        (2 * h);
    const Eigen::Vector3d d_dyaw =
        (as_vector(arc_step(pose, ds, dyaw + h)) - as_vector(arc_step(pose, ds, dyaw - h))) /
        (2 * h);
    EXPECT_LT((d_ds - f_motion.col(0)).norm(), 1e-6) << "dyaw " << dyaw;
    EXPECT_LT((d_dyaw - f_motion.col(1)).norm(), 1e-6) << "dyaw " << dyaw;
  }
}

// drives a circle of the given radius at the given speed for one turn, with noisy sensors
core::Pose2 drive_circle(MotionModel model, double radius_m, double speed_mps, uint64_t seed,
                         Eigen::Matrix3d* covariance) {
  OdometryConfig config;
  config.model = model;
  Odometry odometry(config);
  odometry.reset(0);
  core::Rng rng(seed);
  const double yaw_rate = speed_mps / radius_m;
  const double steer = std::atan(config.wheelbase_m / radius_m);
  const double omega = speed_mps / config.wheel_radius_m;
  const double period_s = 2.0 * M_PI / yaw_rate;
  const core::TimeUs end_us = core::from_seconds(period_s);
  core::Pose2 pose;
  // 200 Hz IMU, 100 Hz wheels and steering from t = 0, a delta every 100 ms and at the end
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (core::TimeUs t = 0; t <= end_us + 100000; t += 5000) {
    const bool last = t > end_us;
    if (last) t = end_us;
    core::ImuSample imu;
    imu.stamp = t;
    imu.gyro_rps.z() = yaw_rate + core::gaussian(rng, 0.0, 0.002);
    odometry.add_imu(imu);
    if (t % 10000 == 0) {
      core::WheelSpeeds w;
      w.stamp = t;
      for (double& o : w.omega_rps) o = omega + core::gaussian(rng, 0.0, 0.05);
      odometry.add_wheel_speeds(w);
      odometry.add_steering({t, steer + core::gaussian(rng, 0.0, 0.002)});
    }
    if (t % 100000 == 0 || last) {
      const OdometryDelta d = odometry.take_delta(t);
      // compose the delta and its covariance onto the pose
      Eigen::Matrix3d j_pose;
      j_pose << 1, 0, -std::sin(pose.yaw) * d.delta.x - std::cos(pose.yaw) * d.delta.y, 0, 1,
          std::cos(pose.yaw) * d.delta.x - std::sin(pose.yaw) * d.delta.y, 0, 0, 1;
      Eigen::Matrix3d j_delta = Eigen::Matrix3d::Identity();
      j_delta.topLeftCorner<2, 2>() = Eigen::Rotation2Dd(pose.yaw).toRotationMatrix();
      cov = j_pose * cov * j_pose.transpose() + j_delta * d.covariance * j_delta.transpose();
      pose = pose.compose(d.delta);
    }
    if (last) break;
  }
  if (covariance) *covariance = cov;
  return pose;
}

TEST(Odometry, OneTurnOfACircleEndsWhereItStarted) {
  // 10 m radius at 8 m/s: 63 m driven; every model closes the circle within a few decimetres
  for (const MotionModel model :
       {MotionModel::kFused, MotionModel::kUnicycle, MotionModel::kBicycle}) {
    Eigen::Matrix3d cov;
    const core::Pose2 end = drive_circle(model, 10.0, 8.0, 7, &cov);
    EXPECT_LT(end.position().norm(), 0.3) << static_cast<int>(model);
    EXPECT_LT(std::abs(core::normalize_angle(end.yaw)), 0.02) << static_cast<int>(model);
    // and the error is within three sigma of the covariance it reports
    EXPECT_LT(end.position().norm(), 3.0 * std::sqrt(cov(0, 0) + cov(1, 1)))
        << static_cast<int>(model);
  }
}

TEST(Odometry, StraightLineDeltaAndDistance) {
  // 10 m/s straight for 0.1 s: a 1 m delta along x
  Odometry odometry;
  odometry.reset(0);
  for (core::TimeUs t = 0; t <= 100000; t += 10000) {
    core::WheelSpeeds w;
    w.stamp = t;
    w.omega_rps.fill(10.0 / 0.23);
    odometry.add_wheel_speeds(w);
    odometry.add_steering({t, 0.0});
    core::ImuSample imu;
    imu.stamp = t;
    odometry.add_imu(imu);
  }
  const OdometryDelta d = odometry.take_delta(100000);
  EXPECT_NEAR(d.delta.x, 1.0, 1e-9);
  EXPECT_NEAR(d.delta.y, 0.0, 1e-12);
  EXPECT_NEAR(d.distance_m, 1.0, 1e-9);
  EXPECT_NEAR(d.speed_mps, 10.0, 1e-9);
  // the covariance is positive definite and larger along than across the path
  EXPECT_GT(d.covariance.determinant(), 0.0);
  EXPECT_GT(d.covariance(0, 0), d.covariance(1, 1));
}

TEST(Odometry, LearnsTheGyroBiasAtStandstill) {
  Odometry odometry;
  odometry.reset(0);
  for (core::TimeUs t = 5000; t <= 2'000'000; t += 5000) {
    core::WheelSpeeds w;
    w.stamp = t;
    odometry.add_wheel_speeds(w);
    core::ImuSample imu;
    imu.stamp = t;
    imu.gyro_rps.z() = 0.004;
    odometry.add_imu(imu);
  }
  EXPECT_NEAR(odometry.gyro_bias_rps(), 0.004, 1e-9);
  EXPECT_NEAR(odometry.yaw_rate_rps(), 0.0, 1e-9);
}

TEST(EquivalentSteer, RecoversTheSingleTrackAngleOfAnAntiAckermannCar) {
  // the wheels of the default (anti-Ackermann) car disagree; their single-track angle is found
  const vehicle_models::VehicleParams params;
  for (const double delta : {-0.45, -0.1, 0.0, 0.02, 0.3, 0.47}) {
    const vehicle_models::WheelAngles wheels = vehicle_models::split_steering(delta, params);
    if (delta > 0.1) {
      EXPECT_GT(wheels.right_rad, wheels.left_rad);  // the outer wheel steers more
    }
    EXPECT_NEAR(equivalent_steer_rad(wheels, params), delta, 1e-8);  // split dead band 1e-9
  }
}

TEST(OdometryConfig, ValidateNamesTheBadKey) {
  OdometryConfig c;
  EXPECT_EQ(c.validate(), "");
  c.wheelbase_m = -1.0;
  EXPECT_NE(c.validate().find("odometry.wheelbase_m"), std::string::npos);
}

}  // namespace
}  // namespace conesim::slam

namespace conesim::slam {
namespace {

TEST(Odometry, MeanSpeedReadsThroughTheEncoderTeeth) {
  // 8 m/s on 48-tooth rings at 100 Hz: each sample counts 2 or 3 teeth (6.0 or 9.0 m/s with a
  // 0.23 m wheel), the mean over ten samples counts the teeth of 0.1 s
  OdometryConfig config;
  config.wheel_radius_m = 0.23;
  Odometry odometry(config);
  odometry.reset(0);
  const double tooth_rad = 2.0 * std::numbers::pi / 48.0;
  double wheel_rad = 0.0;
  for (core::TimeUs t = 10000; t <= 1'000'000; t += 10000) {
    const double before = std::floor(wheel_rad / tooth_rad);
    wheel_rad += 8.0 / 0.23 * 0.01;
    core::WheelSpeeds w;
    w.stamp = t;
    w.omega_rps.fill((std::floor(wheel_rad / tooth_rad) - before) * tooth_rad / 0.01);
    odometry.add_wheel_speeds(w);
    if (t >= 100'000) {
      // one sample is a whole number of teeth away from the truth; ten are within one tooth
      EXPECT_NEAR(odometry.mean_speed_mps(), 8.0, tooth_rad * 0.23 / 0.1 + 1e-9) << t;
    }
  }
  EXPECT_GT(std::abs(odometry.speed_mps() - 8.0), 0.5);
}

// drives straight for 3 s at `speed(t)` with 48-tooth encoders at 100 Hz and a 200 Hz IMU; the
// rear wheels read `rear_factor` times their speed during [1.0, 1.5) s; returns the distance the
// odometry integrated and the samples it took from the front axle
std::pair<double, int> drive_straight_with_slip(double v0, double accel, double rear_factor) {
  Odometry odometry;
  odometry.reset(0);
  const double r = OdometryConfig{}.wheel_radius_m;
  const double tooth_rad = 2.0 * std::numbers::pi / 48.0;
  std::array<double, 4> wheel_rad{0.0, 0.1, 0.05, 0.15};  // teeth not in phase
  double distance = 0.0;
  const core::TimeUs end = 3'000'000;
  for (core::TimeUs t = 5000; t <= end; t += 5000) {
    const double v = std::max(0.0, v0 + accel * core::to_seconds(t));
    distance += v * 0.005;
    core::ImuSample imu;
    imu.stamp = t;
    imu.accel_mps2.x() = v > 0.0 ? accel : 0.0;
    odometry.add_imu(imu);
    if (t % 10000 == 0) {
      const bool slipping = t >= 1'000'000 && t < 1'500'000;
      core::WheelSpeeds w;
      w.stamp = t;
      for (size_t i = 0; i < 4; ++i) {
        const double factor = (i >= 2 && slipping) ? rear_factor : 1.0;
        const double before = std::floor(wheel_rad[i] / tooth_rad);
        wheel_rad[i] += factor * v / r * 0.01;
        w.omega_rps[i] = (std::floor(wheel_rad[i] / tooth_rad) - before) * tooth_rad / 0.01;
      }
      odometry.add_steering({t, 0.0});
      odometry.add_wheel_speeds(w);
    }
  }
  const OdometryDelta d = odometry.take_delta(end);
  return {d.delta.x - distance, odometry.slip_samples()};
}

TEST(Odometry, RearWheelSpinDoesNotStretchTheDistance) {
  // the rear wheels spin at 1.5 times the car's 10 m/s for half a second: 2.5 m too far if the
  // rear encoders were believed. The spin shows once the window's means differ by the
  // tolerance (about 5 of its 10 samples, each 5 cm too far); then the front axle gives the
  // speed. Compared with the same drive without the spin (its error is the first 10 ms before
  // a wheel sample, and the teeth)
  const auto [clean_error, clean_slipped] = drive_straight_with_slip(10.0, 0.0, 1.0);
  EXPECT_EQ(clean_slipped, 0);
  const auto [error, slipped] = drive_straight_with_slip(10.0, 0.0, 1.5);
  EXPECT_LT(std::abs(error - clean_error), 0.3);
  EXPECT_GT(slipped, 40);
}

TEST(Odometry, RearWheelsLockingUnderBrakingDoNotShortenTheDistance) {
  // braking from 20 m/s at 6 m/s^2, the rear wheels read half their speed for half a second
  // (3.5 m short if believed): the IMU's deceleration says the front axle is the one rolling
  const auto [clean_error, clean_slipped] = drive_straight_with_slip(20.0, -6.0, 1.0);
  EXPECT_EQ(clean_slipped, 0);
  const auto [error, slipped] = drive_straight_with_slip(20.0, -6.0, 0.5);
  EXPECT_LT(std::abs(error - clean_error), 0.3);
  EXPECT_GT(slipped, 40);
}

}  // namespace
}  // namespace conesim::slam
