#include "slam/odometry.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/validate.hpp"

namespace conesim::slam {

namespace {

std::string check(const std::string& key, double v, double lo, double hi) {
  return core::check_range("odometry." + key, v, lo, hi);
}

// the chord of an arc in the frame at its start, and its derivatives by (ds, dyaw)
void arc_chord(double ds, double a, Eigen::Vector2d* chord, Eigen::Matrix2d* d_chord) {
  double sinc, cosc, d_sinc, d_cosc;  // sin(a)/a, (1-cos(a))/a and their derivatives by a
  if (std::abs(a) < 1e-4) {
    sinc = 1.0 - a * a / 6.0;
    cosc = a / 2.0 - a * a * a / 24.0;
    d_sinc = -a / 3.0;
    d_cosc = 0.5 - a * a / 8.0;
  } else {
    const double s = std::sin(a), c = std::cos(a);
    sinc = s / a;
    cosc = (1.0 - c) / a;
    d_sinc = (a * c - s) / (a * a);
    d_cosc = (a * s - (1.0 - c)) / (a * a);
  }
  *chord = {ds * sinc, ds * cosc};
  if (d_chord) *d_chord << sinc, ds * d_sinc, cosc, ds * d_cosc;
}

}  // namespace

std::string OdometryConfig::validate() const {
  for (const std::string& e :
       {check("wheel_radius_m", wheel_radius_m, 0.05, 1.0),
        check("wheelbase_m", wheelbase_m, 0.5, 5.0),
        check("distance_sigma_m_per_sqrt_m", distance_sigma_m_per_sqrt_m, 0.0, 1.0),
        check("lateral_sigma_m_per_sqrt_m", lateral_sigma_m_per_sqrt_m, 0.0, 1.0),
        check("gyro_sigma_rad_per_sqrt_s", gyro_sigma_rad_per_sqrt_s, 1e-6, 1.0),
        check("bicycle_sigma_rad_per_sqrt_s_per_mps", bicycle_sigma_rad_per_sqrt_s_per_mps, 1e-6,
              1.0),
        check("standstill_speed_mps", standstill_speed_mps, 0.0, 1.0),
        check("slip_tolerance_mps", slip_tolerance_mps, 0.0, 100.0),
        check("slip_tolerance_fraction", slip_tolerance_fraction, 0.0, 10.0)}) {
    if (!e.empty()) return e;
  }
  return {};
}

double equivalent_steer_rad(const vehicle_models::WheelAngles& wheels,
                            const vehicle_models::VehicleParams& params) {
  // the mean wheel angle grows with the single-track angle: bisect for the measured one
  const double target = 0.5 * (wheels.left_rad + wheels.right_rad);
  const auto mean_angle = [&](double delta) {
    const vehicle_models::WheelAngles w = vehicle_models::split_steering(delta, params);
    return 0.5 * (w.left_rad + w.right_rad);
  };
  double lo = -1.2, hi = 1.2;
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    (mean_angle(mid) < target ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

core::Pose2 arc_step(const core::Pose2& pose, double ds, double dyaw) {
  Eigen::Vector2d chord;
  arc_chord(ds, dyaw, &chord, nullptr);
  return pose.compose({chord.x(), chord.y(), dyaw});
}

void arc_step_jacobians(const core::Pose2& pose, double ds, double dyaw, Eigen::Matrix3d* f_pose,
                        Eigen::Matrix<double, 3, 2>* f_motion) {
  Eigen::Vector2d chord;
  Eigen::Matrix2d d_chord;
  arc_chord(ds, dyaw, &chord, &d_chord);
  const double c = std::cos(pose.yaw), s = std::sin(pose.yaw);
  Eigen::Matrix2d rot;
  rot << c, -s, s, c;
  // the position moves with the rotated chord; the heading adds dyaw
  *f_pose << 1, 0, -s * chord.x() - c * chord.y(), 0, 1, c * chord.x() - s * chord.y(), 0, 0, 1;
  f_motion->topRows<2>() = rot * d_chord;
  f_motion->row(2) << 0, 1;
}

Odometry::Odometry(const OdometryConfig& config) : config_(config) {}

void Odometry::reset(core::TimeUs stamp) {
  last_stamp_ = stamp;
  interval_start_ = stamp;
  delta_ = {};
  covariance_.setZero();
  distance_m_ = 0.0;
}

double Odometry::yaw_rate_rps() const {
  // each source with its variance; the fused rate is their inverse-variance mean
  const double bicycle = speed_mps_ * std::tan(steer_rad_) / config_.wheelbase_m;
  const double gyro = gyro_z_rps_ - gyro_bias_rps_;
  if (config_.model == MotionModel::kBicycle || !has_gyro_) return bicycle;
  if (config_.model == MotionModel::kUnicycle) return gyro;
  const double var_gyro = std::pow(config_.gyro_sigma_rad_per_sqrt_s, 2);
  const double var_bicycle =
      std::pow(config_.bicycle_sigma_rad_per_sqrt_s_per_mps * std::abs(speed_mps_), 2) + 1e-12;
  return (gyro / var_gyro + bicycle / var_bicycle) / (1.0 / var_gyro + 1.0 / var_bicycle);
}

void Odometry::integrate_to(core::TimeUs stamp) {
  if (stamp <= last_stamp_) return;
  const double dt = core::to_seconds(stamp - last_stamp_);
  last_stamp_ = stamp;

  // the step's motion from the held speed and yaw rate
  const double ds = speed_mps_ * dt;
  const double dyaw = yaw_rate_rps() * dt;

  // heading variance of the step: gyro, bicycle model, or both fused
  const double var_gyro = std::pow(config_.gyro_sigma_rad_per_sqrt_s, 2);
  const double var_bicycle =
      std::pow(config_.bicycle_sigma_rad_per_sqrt_s_per_mps * std::abs(speed_mps_), 2) + 1e-12;
  double var_rate = var_bicycle;
  if (has_gyro_ && config_.model == MotionModel::kUnicycle) var_rate = var_gyro;
  if (has_gyro_ && config_.model == MotionModel::kFused)
    var_rate = 1.0 / (1.0 / var_gyro + 1.0 / var_bicycle);

  // propagate the covariance through the arc step, then move the delta
  Eigen::Matrix3d f_pose;
  Eigen::Matrix<double, 3, 2> f_motion;
  arc_step_jacobians(delta_, ds, dyaw, &f_pose, &f_motion);
  const Eigen::Vector2d motion_var(std::pow(config_.distance_sigma_m_per_sqrt_m, 2) * std::abs(ds),
                                   var_rate * dt);
  const Eigen::Vector3d lateral(-std::sin(delta_.yaw), std::cos(delta_.yaw), 0.0);
  covariance_ = f_pose * covariance_ * f_pose.transpose() +
                f_motion * motion_var.asDiagonal() * f_motion.transpose() +
                lateral * lateral.transpose() *
                    (std::pow(config_.lateral_sigma_m_per_sqrt_m, 2) * std::abs(ds));
  delta_ = arc_step(delta_, ds, dyaw);
  distance_m_ += std::abs(ds);
}

void Odometry::add_wheel_speeds(const core::WheelSpeeds& sample) {
  integrate_to(sample.stamp);
  // the rear axle centre moves at the mean of the rear wheels; the front axle centre at the
  // rear one's speed over cos(steer) (kinematic bicycle)
  const double rear = 0.5 * (sample.omega_rps[2] + sample.omega_rps[3]) * config_.wheel_radius_m;
  const double front = 0.5 * (sample.omega_rps[0] + sample.omega_rps[1]) * config_.wheel_radius_m *
                       std::cos(steer_rad_);
  const size_t slot = static_cast<size_t>(speed_samples_ % kSpeedWindow);
  recent_rear_mps_[slot] = rear;
  recent_front_mps_[slot] = front;
  const int n = std::min(speed_samples_ + 1, kSpeedWindow);
  double rear_mean = 0.0, front_mean = 0.0;
  for (int i = 0; i < n; ++i) {
    rear_mean += recent_rear_mps_[static_cast<size_t>(i)];
    front_mean += recent_front_mps_[static_cast<size_t>(i)];
  }
  rear_mean /= n;
  front_mean /= n;
  const double dt =
      has_wheels_ ? std::max(0.0, core::to_seconds(sample.stamp - last_wheel_stamp_)) : 0.0;
  last_wheel_stamp_ = sample.stamp;
  has_wheels_ = true;
  // one sample reads the speed only to a few m/s (whole teeth), so the axles are compared over
  // a full window; while they agree the rear axle gives the speed as it always did. The IMU's
  // acceleration carries a speed from sample to sample, pulled slowly to the wheels' (so that
  // the few samples a slip needs to show in the window barely move it)
  const double predicted = std::max(0.0, carried_speed_mps_ + accel_x_mps2_ * dt);
  const double tolerance = config_.slip_tolerance_mps +
                           config_.slip_tolerance_fraction * std::max(rear_mean, front_mean);
  if (n < kSpeedWindow || std::abs(rear_mean - front_mean) <= tolerance) {
    speed_mps_ = rear;
  } else {
    // one axle slips: the one nearer the carried speed is rolling
    const bool front_rolls = std::abs(front_mean - predicted) < std::abs(rear_mean - predicted);
    speed_mps_ = front_rolls ? front : rear;
    ++slip_samples_;
  }
  carried_speed_mps_ = n < kSpeedWindow
                           ? speed_mps_
                           : predicted + std::min(1.0, dt / kCarryTimeS) * (speed_mps_ - predicted);
  recent_speeds_mps_[slot] = speed_mps_;
  ++speed_samples_;
}

double Odometry::mean_speed_mps() const {
  const int n = std::min(speed_samples_, kSpeedWindow);
  if (n == 0) return speed_mps_;
  double sum = 0.0;
  for (int i = 0; i < n; ++i) sum += recent_speeds_mps_[static_cast<size_t>(i)];
  return sum / n;
}

void Odometry::add_steering(const core::SteeringSample& sample) {
  integrate_to(sample.stamp);
  steer_rad_ = sample.steer_rad;
}

void Odometry::add_imu(const core::ImuSample& sample) {
  integrate_to(sample.stamp);
  gyro_z_rps_ = sample.gyro_rps.z();
  accel_x_mps2_ = sample.accel_mps2.x();
  has_gyro_ = true;
  // standing still for a while (not just started): the gyro reads its bias, learnt as a mean
  if (!has_wheels_ || std::abs(speed_mps_) >= config_.standstill_speed_mps) {
    standstill_samples_ = 0;
    return;
  }
  if (++standstill_samples_ > kSettleSamples) {
    ++bias_samples_;
    gyro_bias_rps_ += (gyro_z_rps_ - gyro_bias_rps_) / std::min(bias_samples_, 1000);
  }
}

OdometryDelta Odometry::take_delta(core::TimeUs stamp) {
  integrate_to(stamp);
  OdometryDelta out;
  out.from = interval_start_;
  out.to = std::max(stamp, interval_start_);
  out.delta = delta_;
  // a floor keeps the covariance invertible when the car stands still
  out.covariance = covariance_ + Eigen::Vector3d(1e-6, 1e-6, 1e-8).asDiagonal().toDenseMatrix();
  out.distance_m = distance_m_;
  out.speed_mps = speed_mps_;
  out.yaw_rate_rps = yaw_rate_rps();
  reset(out.to);
  return out;
}

Eigen::Matrix3d compose_covariance(const core::Pose2& from, const OdometryDelta& odometry,
                                   const Eigen::Matrix3d& covariance) {
  const double c = std::cos(from.yaw), s = std::sin(from.yaw);
  const core::Pose2& d = odometry.delta;
  Eigen::Matrix3d f_pose;
  f_pose << 1, 0, -s * d.x - c * d.y, 0, 1, c * d.x - s * d.y, 0, 0, 1;
  Eigen::Matrix3d f_delta = Eigen::Matrix3d::Identity();
  f_delta.topLeftCorner<2, 2>() << c, -s, s, c;
  return f_pose * covariance * f_pose.transpose() +
         f_delta * odometry.covariance * f_delta.transpose();
}

}  // namespace conesim::slam
