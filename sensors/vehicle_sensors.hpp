#pragma once
// The car's own sensors: IMU, wheel encoders, steering angle sensor and GNSS. Each has a rate,
// a latency and noise from configuration, a generator of its own (so adding a sensor does not
// change another's noise) and stamps its samples on the sim clock.

#include <Eigen/Core>
#include <array>
#include <string>

#include "core/measurements.hpp"
#include "core/rng.hpp"
#include "core/time.hpp"

namespace conesim::sensors {

/// What the vehicle sensors measure, exactly, at one instant (filled by the harness).
struct VehicleSensorTruth {
  core::TimeUs stamp = 0;
  /// Vehicle frame in the track frame.
  core::Pose3 vehicle_pose;
  /// Angular rate in the vehicle frame, rad/s.
  Eigen::Vector3d angular_rate_rps = Eigen::Vector3d::Zero();
  /// Specific force at the IMU in the vehicle frame, m/s^2.
  Eigen::Vector3d specific_force_mps2 = Eigen::Vector3d::Zero();
  /// Accumulated spin angle of each wheel (fl, fr, rl, rr), radians.
  std::array<double, 4> wheel_angle_rad{};
  /// Single-track steering angle, radians.
  double steer_rad = 0.0;
  /// Velocity of the vehicle frame origin in the track frame, m/s.
  Eigen::Vector2d velocity_mps = Eigen::Vector2d::Zero();
};

/// When a sensor samples and how late its samples arrive.
struct SensorTiming {
  double rate_hz = 100.0;
  double latency_s = 0.0;

  /// Sample period on the sim clock, microseconds.
  core::TimeUs period_us() const;
  /// Delivery delay on the sim clock, microseconds.
  core::TimeUs latency_us() const;
  /// Empty when usable, otherwise "key: what was expected" (prefix: the sensor's key).
  std::string validate(const std::string& prefix) const;
};

/// A MEMS IMU of the class FS teams use (VectorNav VN-100 / Xsens MTi-30 datasheets): white
/// noise from the noise densities at the sample rate, bias random walk, initial bias.
struct ImuConfig {
  SensorTiming timing{250.0, 0.002};
  double gyro_noise_density_rps_rthz = 1.2e-4;   // 0.007 deg/s/sqrt(Hz)
  double gyro_bias_walk_rps_rts = 2.0e-5;        // rad/s per sqrt(s)
  double gyro_initial_bias_rps = 1.0e-3;         // sigma of the turn-on bias
  double accel_noise_density_mps2_rthz = 1.4e-3;  // 0.14 mg/sqrt(Hz)
  double accel_bias_walk_mps2_rts = 2.0e-4;
  double accel_initial_bias_mps2 = 0.02;
  std::string validate() const;
};

/// Hall-effect wheel speed sensors on a toothed ring: speed from the tooth count in each
/// period (quantisation) plus electrical noise.
struct WheelEncoderConfig {
  SensorTiming timing{100.0, 0.002};
  int teeth_per_revolution = 48;
  double noise_rps = 0.02;
  std::string validate() const;
};

/// The steering angle sensor on the column, reporting the single-track angle.
struct SteeringSensorConfig {
  SensorTiming timing{100.0, 0.002};
  double noise_rad = 0.002;
  double resolution_rad = 0.0005;
  double offset_rad = 0.0;
  std::string validate() const;
};

/// GNSS: off by default (FS cars run without it at events); RTK-like (2 cm) or plain (1.5 m
/// with a slowly wandering bias, a first-order Gauss-Markov process).
struct GnssConfig {
  bool enabled = false;
  SensorTiming timing{10.0, 0.05};
  double noise_m = 0.02;
  double bias_sigma_m = 0.0;
  double bias_time_constant_s = 60.0;
  double velocity_noise_mps = 0.05;
  /// Presets: "rtk" (2 cm, no bias) and "plain" (1.5 m noise, 1 m bias over 60 s).
  static GnssConfig preset(const std::string& name);
  std::string validate() const;
};

/// The IMU: one sample per period.
class Imu {
 public:
  Imu(const ImuConfig& config, uint64_t seed);
  core::ImuSample sample(const VehicleSensorTruth& truth);
  const ImuConfig& config() const { return config_; }

 private:
  ImuConfig config_;
  core::Rng rng_;
  Eigen::Vector3d gyro_bias_;
  Eigen::Vector3d accel_bias_;
};

/// The four wheel encoders.
class WheelEncoders {
 public:
  WheelEncoders(const WheelEncoderConfig& config, uint64_t seed);
  core::WheelSpeeds sample(const VehicleSensorTruth& truth);
  const WheelEncoderConfig& config() const { return config_; }

 private:
  WheelEncoderConfig config_;
  core::Rng rng_;
  std::array<long long, 4> last_count_{};
  bool has_last_ = false;
};

/// The steering angle sensor.
class SteeringSensor {
 public:
  SteeringSensor(const SteeringSensorConfig& config, uint64_t seed);
  core::SteeringSample sample(const VehicleSensorTruth& truth);
  const SteeringSensorConfig& config() const { return config_; }

 private:
  SteeringSensorConfig config_;
  core::Rng rng_;
};

/// The GNSS receiver.
class Gnss {
 public:
  Gnss(const GnssConfig& config, uint64_t seed);
  core::GnssFix sample(const VehicleSensorTruth& truth);
  const GnssConfig& config() const { return config_; }

 private:
  GnssConfig config_;
  core::Rng rng_;
  Eigen::Vector2d bias_ = Eigen::Vector2d::Zero();
};

}  // namespace conesim::sensors
