#include "sensors/vehicle_sensors.hpp"

#include <cmath>
#include <numbers>
#include <sstream>

#include "core/time.hpp"
#include "core/validate.hpp"

namespace conesim::sensors {

namespace {

std::string check(const std::string& key, double v, double lo, double hi) {
  return core::check_range(key, v, lo, hi);
}

std::string first_error(std::initializer_list<std::string> errors) {
  for (const std::string& e : errors)
    if (!e.empty()) return e;
  return {};
}

// two independent draws as a vector, y drawn before x (a statement each: the order of a call's
// arguments is the compiler's choice, and gcc, whose order this keeps, and clang differ)
Eigen::Vector2d gaussian2(core::Rng& rng, double sigma) {
  const double y = core::gaussian(rng, 0.0, sigma);
  const double x = core::gaussian(rng, 0.0, sigma);
  return {x, y};
}

Eigen::Vector3d gaussian3(core::Rng& rng, double sigma) {
  return {core::gaussian(rng, 0.0, sigma), core::gaussian(rng, 0.0, sigma),
          core::gaussian(rng, 0.0, sigma)};
}

}  // namespace

core::TimeUs SensorTiming::period_us() const {
  return core::from_seconds(1.0 / rate_hz);
}
core::TimeUs SensorTiming::latency_us() const {
  return core::from_seconds(latency_s);
}

std::string SensorTiming::validate(const std::string& prefix) const {
  if (auto e = check(prefix + ".rate_hz", rate_hz, 0.1, 1000.0); !e.empty()) return e;
  // the period must be a whole number of physics steps so the schedule never drifts
  if (!core::whole_physics_steps(rate_hz))
    return prefix + ".rate_hz: expected a rate whose period is a whole number of physics steps (" +
           std::to_string(core::kPhysicsStepUs / 1000) + " ms)";
  return check(prefix + ".latency_s", latency_s, 0.0, 1.0);
}

std::string ImuConfig::validate() const {
  return first_error(
      {timing.validate("imu"),
       check("imu.gyro_noise_density_rps_rthz", gyro_noise_density_rps_rthz, 0, 1),
       check("imu.gyro_bias_walk_rps_rts", gyro_bias_walk_rps_rts, 0, 1),
       check("imu.gyro_initial_bias_rps", gyro_initial_bias_rps, 0, 1),
       check("imu.accel_noise_density_mps2_rthz", accel_noise_density_mps2_rthz, 0, 10),
       check("imu.accel_bias_walk_mps2_rts", accel_bias_walk_mps2_rts, 0, 10),
       check("imu.accel_initial_bias_mps2", accel_initial_bias_mps2, 0, 10)});
}

std::string WheelEncoderConfig::validate() const {
  return first_error({timing.validate("wheel_encoders"),
                      check("wheel_encoders.teeth_per_revolution", teeth_per_revolution, 1, 1e6),
                      check("wheel_encoders.noise_rps", noise_rps, 0, 100)});
}

std::string SteeringSensorConfig::validate() const {
  return first_error({timing.validate("steering"), check("steering.noise_rad", noise_rad, 0, 0.5),
                      check("steering.resolution_rad", resolution_rad, 0, 0.1),
                      check("steering.offset_rad", offset_rad, -0.5, 0.5)});
}

GnssConfig GnssConfig::preset(const std::string& name) {
  GnssConfig c;
  c.enabled = true;
  if (name == "plain") {
    c.noise_m = 1.5;
    c.bias_sigma_m = 1.0;
    c.velocity_noise_mps = 0.1;
  }
  return c;
}

std::string GnssConfig::validate() const {
  return first_error({timing.validate("gnss"), check("gnss.noise_m", noise_m, 0, 100),
                      check("gnss.bias_sigma_m", bias_sigma_m, 0, 100),
                      check("gnss.bias_time_constant_s", bias_time_constant_s, 0.1, 1e5),
                      check("gnss.velocity_noise_mps", velocity_noise_mps, 0, 10)});
}

Imu::Imu(const ImuConfig& config, uint64_t seed) : config_(config), rng_(seed) {
  gyro_bias_ = gaussian3(rng_, config_.gyro_initial_bias_rps);
  accel_bias_ = gaussian3(rng_, config_.accel_initial_bias_mps2);
}

core::ImuSample Imu::sample(const VehicleSensorTruth& truth) {
  const double rate = config_.timing.rate_hz;
  const double dt = 1.0 / rate;
  // biases wander; white noise scales with the square root of the sample rate
  gyro_bias_ += gaussian3(rng_, config_.gyro_bias_walk_rps_rts * std::sqrt(dt));
  accel_bias_ += gaussian3(rng_, config_.accel_bias_walk_mps2_rts * std::sqrt(dt));
  core::ImuSample s;
  s.stamp = truth.stamp;
  s.gyro_rps = truth.angular_rate_rps + gyro_bias_ +
               gaussian3(rng_, config_.gyro_noise_density_rps_rthz * std::sqrt(rate));
  s.accel_mps2 = truth.specific_force_mps2 + accel_bias_ +
                 gaussian3(rng_, config_.accel_noise_density_mps2_rthz * std::sqrt(rate));
  return s;
}

WheelEncoders::WheelEncoders(const WheelEncoderConfig& config, uint64_t seed)
    : config_(config), rng_(seed) {}

core::WheelSpeeds WheelEncoders::sample(const VehicleSensorTruth& truth) {
  const double rad_per_tooth = 2.0 * std::numbers::pi / config_.teeth_per_revolution;
  const double dt = 1.0 / config_.timing.rate_hz;
  core::WheelSpeeds s;
  s.stamp = truth.stamp;
  for (int w = 0; w < 4; ++w) {
    // teeth passed since the last sample give the speed, quantised to one tooth per period
    const long long count =
        static_cast<long long>(std::floor(truth.wheel_angle_rad[w] / rad_per_tooth));
    const double omega = has_last_ ? (count - last_count_[w]) * rad_per_tooth / dt : 0.0;
    s.omega_rps[w] = omega + core::gaussian(rng_, 0.0, config_.noise_rps);
    last_count_[w] = count;
  }
  has_last_ = true;
  return s;
}

SteeringSensor::SteeringSensor(const SteeringSensorConfig& config, uint64_t seed)
    : config_(config), rng_(seed) {}

core::SteeringSample SteeringSensor::sample(const VehicleSensorTruth& truth) {
  double angle =
      truth.steer_rad + config_.offset_rad + core::gaussian(rng_, 0.0, config_.noise_rad);
  if (config_.resolution_rad > 0.0)
    angle = std::round(angle / config_.resolution_rad) * config_.resolution_rad;
  return {truth.stamp, angle};
}

Gnss::Gnss(const GnssConfig& config, uint64_t seed) : config_(config), rng_(seed) {
  bias_ = {core::gaussian(rng_, 0.0, config_.bias_sigma_m),
           core::gaussian(rng_, 0.0, config_.bias_sigma_m)};
}

core::GnssFix Gnss::sample(const VehicleSensorTruth& truth) {
  // first-order Gauss-Markov bias: keeps its stationary sigma while it wanders
  const double dt = 1.0 / config_.timing.rate_hz;
  const double phi = std::exp(-dt / config_.bias_time_constant_s);
  const double drive = config_.bias_sigma_m * std::sqrt(1.0 - phi * phi);
  bias_ = phi * bias_ + gaussian2(rng_, drive);
  core::GnssFix fix;
  fix.stamp = truth.stamp;
  fix.position = truth.vehicle_pose.position.head<2>() + bias_ + gaussian2(rng_, config_.noise_m);
  fix.velocity_mps = truth.velocity_mps + gaussian2(rng_, config_.velocity_noise_mps);
  fix.sigma_m = std::hypot(config_.noise_m, config_.bias_sigma_m);
  return fix;
}

}  // namespace conesim::sensors
