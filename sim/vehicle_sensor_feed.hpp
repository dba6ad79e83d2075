#pragma once
// The vehicle sensors that feed SLAM's odometry (IMU, wheel encoders, steering angle), sampled
// on their own schedules from the simulated car and delivered after their latencies in stamp
// order. The SLAM lanes read the odometry from here; nothing here knows of a back-end.

#include <deque>
#include <utility>

#include "core/time.hpp"
#include "sensors/vehicle_sensors.hpp"
#include "sim/faults.hpp"
#include "sim/sensor_tap.hpp"
#include "sim/vehicle_sim.hpp"
#include "slam/odometry.hpp"

namespace conesim::sim {

class VehicleSensorFeed {
 public:
  /// The sensors with noise streams derived from the scenario seed, the IMU and the wheel
  /// encoders with the given noise, and the scenario's faults (IMU bias steps, wheel slip act
  /// here).
  explicit VehicleSensorFeed(uint64_t seed, const sensors::ImuConfig& imu = {},
                             const sensors::WheelEncoderConfig& wheels = {},
                             const std::vector<Fault>& faults = {});

  /// What each fault did here (samples changed), index by index with the scenario's faults.
  const FaultCounts& fault_counts() const { return fault_counts_; }

  /// Samples the sensors due at t and delivers what has arrived by t.
  void step(core::TimeUs t, const VehicleSim& car);

  /// Whether the IMU samples at t: the physics step that ends at t must compute the sensors.
  bool imu_due(core::TimeUs t) const;

  /// The longest latency of the sensors: a sample stamped t has arrived by t + this.
  core::TimeUs max_latency_us() const;

  /// Feeds the delivered samples stamped up to `stamp` into the odometry and drops them.
  void feed(slam::Odometry& odometry, core::TimeUs stamp);

  /// Feeds the delivered samples stamped up to `stamp` into the odometry without dropping them
  /// (for an estimate carried forward to the present).
  void feed_copy(slam::Odometry& odometry, core::TimeUs stamp) const;

  /// Hands every delivered sample to the tap (the kinds it wants), as delivered at `now`, and
  /// drops them: for a feed of the tap's own, with the seed of SLAM's, so the same samples.
  void drain_to(SensorTap& tap, core::TimeUs now);

 private:
  struct Sample {
    core::TimeUs stamp;
    int kind;  // 0 imu, 1 wheels, 2 steering
    core::ImuSample imu;
    core::WheelSpeeds wheels;
    core::SteeringSample steering;
  };
  static void add(slam::Odometry& odometry, const Sample& sample);

  sensors::Imu imu_;
  sensors::WheelEncoders wheels_;
  sensors::SteeringSensor steering_;
  FaultInjector faults_;
  FaultCounts fault_counts_;
  // samples taken but not yet arrived: (arrival time, sample)
  std::deque<std::pair<core::TimeUs, Sample>> in_flight_;
  // samples arrived but not yet fed, in stamp order
  std::deque<Sample> delivered_;
};

}  // namespace conesim::sim
