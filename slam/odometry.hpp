#pragma once
// Odometry for SLAM: speed from the rear wheel encoders (the front ones when the rear slip), yaw
// rate from the IMU gyro and from the steering angle through the kinematic bicycle model,
// integrated between observation batches into an SE(2) delta with its covariance.

#include <Eigen/Core>
#include <array>
#include <string>

#include "core/geometry.hpp"
#include "core/measurements.hpp"
#include "slam/backend.hpp"
#include "vehicle_models/steering.hpp"
#include "vehicle_models/vehicle_params.hpp"

namespace conesim::slam {

/// Where the yaw rate comes from.
enum class MotionModel {
  /// Kinematic bicycle about the rear axle: v tan(delta) / L with the single-track equivalent
  /// angle (for an anti-Ackermann car the steering sensor reports that angle).
  kBicycle,
  /// Unicycle with the gyro's yaw rate: the simpler model, no steering needed.
  kUnicycle,
  /// Both yaw rates, weighted by their variances (gyro dominates, the bicycle model steadies
  /// it); the default.
  kFused,
};

/// Odometry parameters: the car's geometry and the noise figures behind the covariance.
struct OdometryConfig {
  MotionModel model = MotionModel::kFused;
  double wheel_radius_m = 0.23;
  double wheelbase_m = 1.53;
  /// Distance error growing with the square root of distance driven (encoder quantisation,
  /// tyre radius error, longitudinal slip), m per sqrt(m).
  double distance_sigma_m_per_sqrt_m = 0.02;
  /// Lateral error (side slip) per sqrt(m) driven, m per sqrt(m).
  double lateral_sigma_m_per_sqrt_m = 0.01;
  /// Heading random walk of the gyro (white noise and the bias left after learning it at
  /// standstill): the heading variance grows by its square times dt, rad per sqrt(s). The
  /// default has a margin of four over the MEMS IMU's 1.2e-4; a car that never stands still
  /// before driving keeps its turn-on bias (1e-3 rad/s) and needs about 0.003.
  double gyro_sigma_rad_per_sqrt_s = 5e-4;
  /// Heading random walk of the bicycle model (steering noise, slip) per m/s of speed, rad per
  /// sqrt(s) per m/s.
  double bicycle_sigma_rad_per_sqrt_s_per_mps = 0.01;
  /// Below this wheel speed the car is taken as standing and the gyro bias is learnt, m/s.
  double standstill_speed_mps = 0.05;
  /// The rear (driven) and the front axle's speeds, each averaged over kSpeedWindow samples,
  /// differing by more than this plus slip_tolerance_fraction of the speed: one axle slips (the
  /// driven wheels spin, or wheels lock under braking), and the speed comes from the axle that
  /// agrees better with the speed carried forward by the IMU's longitudinal acceleration, m/s.
  double slip_tolerance_mps = 1.0;
  double slip_tolerance_fraction = 0.10;

  /// Empty when usable, otherwise "odometry.key: what was expected".
  std::string validate() const;
};

/// The single-track equivalent angle of measured front wheel angles: the angle whose split by
/// the car's steering geometry (vehicle_models::split_steering, anti-Ackermann included) gives
/// the same mean wheel angle. For cars whose sensors report wheel angles instead of the
/// single-track angle the kinematic bicycle needs.
double equivalent_steer_rad(const vehicle_models::WheelAngles& wheels,
                            const vehicle_models::VehicleParams& params);

/// One step of the arc motion: the pose moved by distance ds along an arc turning by dyaw.
core::Pose2 arc_step(const core::Pose2& pose, double ds, double dyaw);

/// Jacobians of arc_step: d(pose')/d(pose) (3x3) and d(pose')/d(ds, dyaw) (3x2).
void arc_step_jacobians(const core::Pose2& pose, double ds, double dyaw, Eigen::Matrix3d* f_pose,
                        Eigen::Matrix<double, 3, 2>* f_motion);

/// Integrates the vehicle sensors between observation batches. Feed the samples in stamp order
/// as they arrive; call take_delta at each observation batch's stamp.
class Odometry {
 public:
  explicit Odometry(const OdometryConfig& config = {});

  /// Starts integrating at this stamp (the first batch's stamp).
  void reset(core::TimeUs stamp);
  /// Adds a wheel speed sample (rear wheels give the speed; the front ones while the rear slip).
  void add_wheel_speeds(const core::WheelSpeeds& sample);
  /// Adds a steering angle sample (single-track equivalent angle).
  void add_steering(const core::SteeringSample& sample);
  /// Adds an IMU sample (the gyro's z gives the yaw rate; the accelerometer's x carries the
  /// speed across a wheel slip).
  void add_imu(const core::ImuSample& sample);

  /// Integrates up to `stamp` and returns the motion since the last call (or reset), then starts
  /// a new interval there.
  OdometryDelta take_delta(core::TimeUs stamp);

  /// Latest forward speed of the rear axle centre, m/s.
  double speed_mps() const { return speed_mps_; }
  /// Mean forward speed over the last kSpeedWindow wheel samples, m/s: the encoders count whole
  /// teeth, so one sample reads the speed only to about 3 m/s at 100 Hz; the mean over 0.1 s
  /// (a LiDAR sweep) reads it to 0.3 m/s.
  double mean_speed_mps() const;
  /// The forward speed for control, m/s: carried from wheel sample to wheel sample by the IMU's
  /// longitudinal acceleration and pulled to the rolling axle's wheel speed with a time constant
  /// of kCarryTimeS, so that it follows accelerations without lag while the teeth' quantisation
  /// hardly shows in it.
  double filtered_speed_mps() const { return carried_speed_mps_; }
  /// Latest fused yaw rate, rad/s.
  double yaw_rate_rps() const;
  /// The gyro bias learnt at standstill, rad/s.
  double gyro_bias_rps() const { return gyro_bias_rps_; }
  /// Wheel samples whose speed came from the front axle because the rear one slipped (or the
  /// front one from the rear), since construction.
  int slip_samples() const { return slip_samples_; }

 private:
  void integrate_to(core::TimeUs stamp);

  OdometryConfig config_;
  // the held sensor values
  double speed_mps_ = 0.0;
  // the latest wheel-sample speeds, oldest overwritten first
  static constexpr int kSpeedWindow = 10;
  std::array<double, kSpeedWindow> recent_speeds_mps_{};
  // the same window for each axle's own speed (rear axle centre; front axle carried to the rear
  // one through the steering angle)
  std::array<double, kSpeedWindow> recent_rear_mps_{};
  std::array<double, kSpeedWindow> recent_front_mps_{};
  int speed_samples_ = 0;
  // a speed carried by the IMU's acceleration and pulled to the wheels' speed with this time
  // constant, s
  static constexpr double kCarryTimeS = 0.3;
  double carried_speed_mps_ = 0.0;
  core::TimeUs last_wheel_stamp_ = 0;
  double accel_x_mps2_ = 0.0;
  int slip_samples_ = 0;
  double steer_rad_ = 0.0;
  double gyro_z_rps_ = 0.0;
  bool has_gyro_ = false;
  double gyro_bias_rps_ = 0.0;
  bool has_wheels_ = false;
  int standstill_samples_ = 0;
  int bias_samples_ = 0;
  /// IMU samples at standstill before the bias is learnt.
  static constexpr int kSettleSamples = 50;
  // the interval being integrated
  core::TimeUs last_stamp_ = 0;
  core::TimeUs interval_start_ = 0;
  core::Pose2 delta_;
  Eigen::Matrix3d covariance_ = Eigen::Matrix3d::Zero();
  double distance_m_ = 0.0;
};

/// The covariance of `from` composed with the odometry's delta: `covariance` of `from` carried
/// through the composition plus the delta's own, rotated into the map frame.
Eigen::Matrix3d compose_covariance(const core::Pose2& from, const OdometryDelta& odometry,
                                   const Eigen::Matrix3d& covariance);

}  // namespace conesim::slam
