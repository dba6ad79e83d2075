#pragma once
// Raw sensor data handed to an observer as the run delivers it, in the SDK's types: the LiDAR
// sweeps and stereo pairs a perception plug-in gets (the same conversions, from the same place
// in the sensor rig) and the IMU, wheel-speed and steering samples SLAM's odometry integrates
// (the same sensors and noise streams). The Python module's `observe=` is such an observer.

#include <vector>

#include "conesim/sdk/types.hpp"
#include "core/time.hpp"

namespace conesim::sim {

/// Which raw data an observer wants; asking for the LiDAR or the camera switches it on, as
/// dumping it does.
struct SensorTapKinds {
  bool lidar = false;
  /// The true cone id of each LiDAR point (-1 ground): ground truth, only when asked for.
  bool lidar_labels = false;
  /// Deliver only every Nth LiDAR sweep (the first, the N+1st, ...): a recorder that keeps a
  /// few sweeps a second skips converting the others.
  int lidar_every = 1;
  bool camera = false;
  bool imu = false;
  bool wheels = false;
  bool steering = false;

  /// True when any of the car's own sensors (IMU, wheels, steering) is wanted.
  bool vehicle_sensors() const { return imu || wheels || steering; }
};

/// Receives the raw data on the run's thread, each with the sim time it is delivered at (its
/// stamp plus the sensor's latency). Views are valid only during the call: copy what you keep.
class SensorTap {
 public:
  explicit SensorTap(const SensorTapKinds& kinds) : kinds_(kinds) {}
  virtual ~SensorTap() = default;

  const SensorTapKinds& kinds() const { return kinds_; }

  /// One LiDAR sweep (points in the sensor frame, as fired). labels: the true cone id of each
  /// point, -1 for the ground; null unless kinds().lidar_labels.
  virtual void on_lidar(core::TimeUs delivered_us, const sdk::LidarSweep& sweep,
                        const std::vector<int>* labels) {
    (void)delivered_us, (void)sweep, (void)labels;
  }
  /// One rectified stereo pair.
  virtual void on_stereo(core::TimeUs delivered_us, const sdk::StereoFrame& frame) {
    (void)delivered_us, (void)frame;
  }
  virtual void on_imu(core::TimeUs delivered_us, const sdk::ImuSample& sample) {
    (void)delivered_us, (void)sample;
  }
  virtual void on_wheels(core::TimeUs delivered_us, const sdk::WheelSpeeds& sample) {
    (void)delivered_us, (void)sample;
  }
  virtual void on_steering(core::TimeUs delivered_us, const sdk::SteeringSample& sample) {
    (void)delivered_us, (void)sample;
  }

 private:
  SensorTapKinds kinds_;
};

}  // namespace conesim::sim
