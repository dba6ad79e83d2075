#pragma once
// The residuals of the pose graph: one small functor per edge, each with a static Create().
// Poses are parameter blocks (x, y, yaw) in the map frame, landmarks (x, y). Angles are
// normalised inside the residuals; residuals are whitened with the upper Cholesky factor of the
// information matrix (STYLE.md: matrixL is wrong for non-diagonal information).

#include <ceres/ceres.h>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

#include "core/geometry.hpp"

namespace conesim::slam {

/// Wraps an angle to [-pi, pi) for doubles and Ceres jets alike.
template <typename T>
T normalize_angle_jet(const T& a) {
  using std::floor;
  const T two_pi(2.0 * M_PI);
  return a - two_pi * floor((a + T(M_PI)) / two_pi);
}

/// The whitening factor of a covariance: the upper Cholesky factor U of the information
/// matrix (U^T U = covariance^-1), so that |U e|^2 is the Mahalanobis distance of e.
template <int N>
Eigen::Matrix<double, N, N> sqrt_information(const Eigen::Matrix<double, N, N>& covariance) {
  const Eigen::Matrix<double, N, N> information = covariance.inverse();
  return information.llt().matrixU();
}

/// Odometry edge: the relative pose of b in the frame of a against the measured delta, with the
/// gyro bias left after the standstill calibration taken out of the measured heading change.
/// The bias turns the heading by bias * dt over the interval (a few 1e-5 rad); its effect on the
/// translation (the chord turning by half of that) is below a micrometre and left out.
struct OdometryResidual {
  OdometryResidual(const core::Pose2& delta, const Eigen::Matrix3d& sqrt_information,
                   double dt_s = 0.0)
      : delta_(delta), sqrt_information_(sqrt_information), dt_s_(dt_s) {}

  template <typename T>
  bool operator()(const T* a, const T* b, const T* gyro_bias, T* residual) const {
    // relative pose of b in a's frame
    const T c = cos(a[2]), s = sin(a[2]);
    const T dx = b[0] - a[0], dy = b[1] - a[1];
    const T measured_yaw = T(delta_.yaw) - gyro_bias[0] * T(dt_s_);
    Eigen::Matrix<T, 3, 1> error;
    error << c * dx + s * dy - T(delta_.x), -s * dx + c * dy - T(delta_.y),
        normalize_angle_jet(b[2] - a[2] - measured_yaw);
    // whiten
    Eigen::Map<Eigen::Matrix<T, 3, 1>> whitened(residual);
    whitened = sqrt_information_.cast<T>() * error;
    return true;
  }

  /// A cost function with 3 residuals over pose a, pose b and the gyro bias (rad/s); dt_s is
  /// the length of the interval, s.
  static ceres::CostFunction* Create(const core::Pose2& delta,
                                     const Eigen::Matrix3d& sqrt_information, double dt_s) {
    return new ceres::AutoDiffCostFunction<OdometryResidual, 3, 3, 3, 1>(
        new OdometryResidual(delta, sqrt_information, dt_s));
  }

 private:
  core::Pose2 delta_;
  Eigen::Matrix3d sqrt_information_;
  double dt_s_;
};

/// Prior on the gyro bias: what remains after the standstill calibration is zero-mean with this
/// sigma.
struct GyroBiasPrior {
  explicit GyroBiasPrior(double sigma_rps) : inv_sigma_(1.0 / sigma_rps) {}

  template <typename T>
  bool operator()(const T* gyro_bias, T* residual) const {
    residual[0] = T(inv_sigma_) * gyro_bias[0];
    return true;
  }

  /// A cost function with 1 residual over the gyro bias.
  static ceres::CostFunction* Create(double sigma_rps) {
    return new ceres::AutoDiffCostFunction<GyroBiasPrior, 1, 1>(new GyroBiasPrior(sigma_rps));
  }

 private:
  double inv_sigma_;
};

/// Observation edge: a landmark seen from a pose, Cartesian in the vehicle frame.
struct ObservationResidual {
  ObservationResidual(const core::Vec2& measured, const Eigen::Matrix2d& sqrt_information)
      : measured_(measured), sqrt_information_(sqrt_information) {}

  template <typename T>
  bool operator()(const T* pose, const T* landmark, T* residual) const {
    // the landmark in the vehicle frame
    const T c = cos(pose[2]), s = sin(pose[2]);
    const T dx = landmark[0] - pose[0], dy = landmark[1] - pose[1];
    Eigen::Matrix<T, 2, 1> error;
    error << c * dx + s * dy - T(measured_.x()), -s * dx + c * dy - T(measured_.y());
    // whiten
    Eigen::Map<Eigen::Matrix<T, 2, 1>> whitened(residual);
    whitened = sqrt_information_.cast<T>() * error;
    return true;
  }

  /// A cost function with 2 residuals over a pose and a landmark.
  static ceres::CostFunction* Create(const core::Vec2& measured,
                                     const Eigen::Matrix2d& sqrt_information) {
    return new ceres::AutoDiffCostFunction<ObservationResidual, 2, 3, 2>(
        new ObservationResidual(measured, sqrt_information));
  }

 private:
  core::Vec2 measured_;
  Eigen::Matrix2d sqrt_information_;
};

/// Adds an observation of a landmark from a pose held fixed to a running sum: with the pose
/// fixed, the observation's whitened residual A l - b is linear in the landmark l (A = U R^T,
/// b = U (R^T p + z)), so any number of them sum to one quadratic, information A^T A and
/// information-weighted mean A^T b.
inline void fold_observation(const core::Pose2& pose, const core::Vec2& measured,
                             const Eigen::Matrix2d& sqrt_information, Eigen::Matrix2d& information,
                             Eigen::Vector2d& weighted_mean) {
  const Eigen::Matrix2d rotation_t = Eigen::Rotation2Dd(pose.yaw).toRotationMatrix().transpose();
  const Eigen::Matrix2d a = sqrt_information * rotation_t;
  const Eigen::Vector2d b = sqrt_information * (rotation_t * pose.position() + measured);
  information += a.transpose() * a;
  weighted_mean += a.transpose() * b;
}

/// The observations folded by fold_observation() as one prior on the landmark: U (l - m) with
/// U^T U the summed information and m its mean. Its squared norm differs from the sum of the
/// folded residuals' squares by a constant only.
class LandmarkPriorResidual : public ceres::SizedCostFunction<2, 2> {
 public:
  LandmarkPriorResidual(const Eigen::Matrix2d& information, const Eigen::Vector2d& weighted_mean)
      : sqrt_information_(information.llt().matrixU()),
        mean_(information.llt().solve(weighted_mean)) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const Eigen::Map<const Eigen::Vector2d> landmark(parameters[0]);
    Eigen::Map<Eigen::Vector2d> residual(residuals);
    residual = sqrt_information_ * (landmark - mean_);
    // d residual / d landmark = U (row-major, as Ceres lays it out)
    if (jacobians && jacobians[0]) {
      Eigen::Map<Eigen::Matrix<double, 2, 2, Eigen::RowMajor>> jacobian(jacobians[0]);
      jacobian = sqrt_information_;
    }
    return true;
  }

 private:
  Eigen::Matrix2d sqrt_information_;
  Eigen::Vector2d mean_;
};

/// Instantaneous-centre-of-rotation edge (RaceUp): with no lateral velocity at the rear axle the
/// car moves on an arc, whose chord points half the heading change to the side. The residual is
/// the part of the relative translation across that chord direction.
struct IcrResidual {
  explicit IcrResidual(double sigma_m) : inv_sigma_(1.0 / sigma_m) {}

  template <typename T>
  bool operator()(const T* a, const T* b, T* residual) const {
    // relative translation and heading change in a's frame
    const T c = cos(a[2]), s = sin(a[2]);
    const T dx = b[0] - a[0], dy = b[1] - a[1];
    const T forward = c * dx + s * dy, left = -s * dx + c * dy;
    const T half_turn = normalize_angle_jet(b[2] - a[2]) / T(2.0);
    // lateral offset from the chord of the arc
    residual[0] = T(inv_sigma_) * (left * cos(half_turn) - forward * sin(half_turn));
    return true;
  }

  /// A cost function with 1 residual over pose a and pose b.
  static ceres::CostFunction* Create(double sigma_m) {
    return new ceres::AutoDiffCostFunction<IcrResidual, 1, 3, 3>(new IcrResidual(sigma_m));
  }

 private:
  double inv_sigma_;
};

}  // namespace conesim::slam
