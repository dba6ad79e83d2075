#include "sensors/vehicle_sensors.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

namespace conesim::sensors {
namespace {

// mean and standard deviation of a sample
std::pair<double, double> mean_std(const std::vector<double>& v) {
  double m = 0.0;
  for (double x : v) m += x;
  m /= v.size();
  double var = 0.0;
  for (double x : v) var += (x - m) * (x - m);
  return {m, std::sqrt(var / (v.size() - 1))};
}

TEST(Imu, WhiteNoiseMatchesTheNoiseDensityAtTheSampleRate) {
  ImuConfig config;
  config.gyro_bias_walk_rps_rts = 0.0;
  config.gyro_initial_bias_rps = 0.0;
  config.accel_bias_walk_mps2_rts = 0.0;
  config.accel_initial_bias_mps2 = 0.0;
  Imu imu(config, 7);
  VehicleSensorTruth truth;
  truth.angular_rate_rps = {0.0, 0.0, 0.5};
  truth.specific_force_mps2 = {0.0, 0.0, 9.81};
  std::vector<double> gz, az;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    const auto s = imu.sample(truth);
    gz.push_back(s.gyro_rps.z());
    az.push_back(s.accel_mps2.z());
  }
  const double gyro_sigma = config.gyro_noise_density_rps_rthz * std::sqrt(config.timing.rate_hz);
  const auto [gm, gs] = mean_std(gz);
  EXPECT_NEAR(gm, 0.5, 4.0 * gyro_sigma / std::sqrt(n));
  // the sample sigma of 20,000 draws is within 3 % of the true one with overwhelming odds
  EXPECT_NEAR(gs, gyro_sigma, 0.03 * gyro_sigma);
  const double accel_sigma =
      config.accel_noise_density_mps2_rthz * std::sqrt(config.timing.rate_hz);
  const auto [am, as] = mean_std(az);
  EXPECT_NEAR(am, 9.81, 4.0 * accel_sigma / std::sqrt(n));
  EXPECT_NEAR(as, accel_sigma, 0.03 * accel_sigma);
}

TEST(Imu, BiasWandersAsARandomWalk) {
  // with no white noise, the gyro error after T seconds has sigma walk * sqrt(T)
  ImuConfig config;
  config.gyro_noise_density_rps_rthz = 0.0;
  config.gyro_initial_bias_rps = 0.0;
  const double seconds = 25.0;
  std::vector<double> end_bias;
  for (uint64_t seed = 0; seed < 200; ++seed) {
    Imu imu(config, seed);
    core::ImuSample s;
    for (int i = 0; i < static_cast<int>(seconds * config.timing.rate_hz); ++i) s = imu.sample({});
    end_bias.push_back(s.gyro_rps.x());
  }
  const auto [m, sd] = mean_std(end_bias);
  const double expected = config.gyro_bias_walk_rps_rts * std::sqrt(seconds);
  // 200 runs: the sample sigma is within about 15 % at 3 sigma
  EXPECT_NEAR(sd, expected, 0.15 * expected);
  EXPECT_NEAR(m, 0.0, 4.0 * expected / std::sqrt(200.0));
}

TEST(WheelEncoders, SpeedIsQuantisedToOneToothPerPeriod) {
  WheelEncoderConfig config;
  config.noise_rps = 0.0;
  WheelEncoders enc(config, 1);
  const double omega = 43.3;  // about 10 m/s on a 0.23 m wheel
  const double dt = 1.0 / config.timing.rate_hz;
  const double step = 2.0 * std::numbers::pi / config.teeth_per_revolution / dt;
  VehicleSensorTruth truth;
  double sum = 0.0;
  const int n = 1000;
  for (int i = 0; i <= n; ++i) {
    truth.wheel_angle_rad.fill(omega * i * dt);
    const auto s = enc.sample(truth);
    if (i == 0) continue;
    // every reading is a whole number of teeth per period, within one tooth of the truth
    EXPECT_NEAR(std::remainder(s.omega_rps[0], step), 0.0, 1e-9);
    EXPECT_LE(std::abs(s.omega_rps[2] - omega), step);
    sum += s.omega_rps[0];
  }
  // averaged over many periods the quantisation error vanishes
  EXPECT_NEAR(sum / n, omega, step / n + 1e-9);
}

TEST(SteeringSensor, ReadsTheAngleAtItsResolution) {
  SteeringSensorConfig config;
  config.noise_rad = 0.0;
  SteeringSensor sensor(config, 3);
  VehicleSensorTruth truth;
  truth.steer_rad = 0.12345;
  const auto s = sensor.sample(truth);
  EXPECT_NEAR(s.steer_rad, 0.12345, 0.5 * config.resolution_rad + 1e-12);
  EXPECT_NEAR(std::remainder(s.steer_rad, config.resolution_rad), 0.0, 1e-12);
}

TEST(Gnss, RtkAndPlainPresetsHaveTheirAccuracy) {
  for (const char* preset : {"rtk", "plain"}) {
    const GnssConfig config = GnssConfig::preset(preset);
    std::vector<double> ex;
    // many receivers, one fix each after a while: the spread includes the bias
    for (uint64_t seed = 0; seed < 400; ++seed) {
      Gnss gnss(config, seed);
      core::GnssFix fix;
      for (int i = 0; i < 20; ++i) fix = gnss.sample({});
      ex.push_back(fix.position.x());
    }
    const auto [m, sd] = mean_std(ex);
    const double expected = std::hypot(config.noise_m, config.bias_sigma_m);
    EXPECT_NEAR(sd, expected, 0.12 * expected) << preset;
    EXPECT_NEAR(m, 0.0, 4.0 * expected / std::sqrt(400.0)) << preset;
  }
}

TEST(SensorTiming, RejectsRatesOffTheMillisecondGrid) {
  EXPECT_EQ((SensorTiming{100.0, 0.0}.validate("imu")), "");
  EXPECT_NE((SensorTiming{300.0, 0.0}.validate("imu").find("imu.rate_hz")), std::string::npos);
  EXPECT_NE((SensorTiming{100.0, -1.0}.validate("imu").find("imu.latency_s")), std::string::npos);
  EXPECT_EQ((SensorTiming{200.0, 0.002}).period_us(), 5000);
}

TEST(VehicleSensors, SameSeedSameNoise) {
  Imu a(ImuConfig{}, 11), b(ImuConfig{}, 11), c(ImuConfig{}, 12);
  const auto sa = a.sample({}), sb = b.sample({}), sc = c.sample({});
  EXPECT_EQ(sa.gyro_rps, sb.gyro_rps);
  EXPECT_NE(sa.gyro_rps, sc.gyro_rps);
}

}  // namespace
}  // namespace conesim::sensors
