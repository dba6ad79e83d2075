#include "sim/vehicle_sensor_feed.hpp"

#include <algorithm>
#include <iterator>

#include "sdk/builtin/bridge.hpp"

namespace conesim::sim {

namespace {
constexpr uint64_t kImuStream = 201;
constexpr uint64_t kWheelStream = 202;
constexpr uint64_t kSteeringStream = 203;
}  // namespace

VehicleSensorFeed::VehicleSensorFeed(uint64_t seed, const sensors::ImuConfig& imu,
                                     const sensors::WheelEncoderConfig& wheels,
                                     const std::vector<Fault>& faults)
    : imu_(imu, core::derive_seed(seed, kImuStream)),
      wheels_(wheels, core::derive_seed(seed, kWheelStream)),
      steering_(sensors::SteeringSensorConfig{}, core::derive_seed(seed, kSteeringStream)),
      faults_(faults, seed),
      fault_counts_(faults_.zero_counts()) {}

bool VehicleSensorFeed::imu_due(core::TimeUs t) const {
  return t % imu_.config().timing.period_us() == 0;
}

core::TimeUs VehicleSensorFeed::max_latency_us() const {
  return std::max({imu_.config().timing.latency_us(), wheels_.config().timing.latency_us(),
                   steering_.config().timing.latency_us()});
}

void VehicleSensorFeed::step(core::TimeUs t, const VehicleSim& car) {
  // sample what is due; samples arrive after their latency
  const bool imu_due = this->imu_due(t);
  const bool wheels_due = t % wheels_.config().timing.period_us() == 0;
  const bool steer_due = t % steering_.config().timing.period_us() == 0;
  if (imu_due || wheels_due || steer_due) {
    const VehicleTruth truth = car.truth();
    sensors::VehicleSensorTruth st;
    st.stamp = t;
    if (imu_due) {
      st.angular_rate_rps = car.imu_angular_rate();
      st.specific_force_mps2 = car.imu_specific_force();
    }
    st.wheel_angle_rad = truth.wheel_spin_rad;
    st.steer_rad = truth.steer_rad;
    if (imu_due) {
      Sample v{t, 0, imu_.sample(st), {}, {}};
      if (!faults_.empty()) faults_.apply_imu(v.imu, fault_counts_);
      in_flight_.push_back({t + imu_.config().timing.latency_us(), v});
    }
    if (wheels_due) {
      Sample v{t, 1, {}, wheels_.sample(st), {}};
      if (!faults_.empty()) faults_.apply_wheels(v.wheels, fault_counts_);
      in_flight_.push_back({t + wheels_.config().timing.latency_us(), v});
    }
    if (steer_due) {
      Sample v{t, 2, {}, {}, steering_.sample(st)};
      in_flight_.push_back({t + steering_.config().timing.latency_us(), v});
    }
  }
  // deliver what has arrived; sensors with different latencies arrive out of stamp order, so
  // each sample goes in after the queued ones stamped no later (the queue stays in stamp order,
  // equal stamps in arrival order)
  while (!in_flight_.empty()) {
    auto it = std::min_element(in_flight_.begin(), in_flight_.end(),
                               [](const auto& a, const auto& b) { return a.first < b.first; });
    if (it->first > t) break;
    auto at = delivered_.end();
    while (at != delivered_.begin() && std::prev(at)->stamp > it->second.stamp) --at;
    delivered_.insert(at, it->second);
    in_flight_.erase(it);
  }
}

void VehicleSensorFeed::add(slam::Odometry& odometry, const Sample& v) {
  if (v.kind == 0) odometry.add_imu(v.imu);
  if (v.kind == 1) odometry.add_wheel_speeds(v.wheels);
  if (v.kind == 2) odometry.add_steering(v.steering);
}

void VehicleSensorFeed::feed(slam::Odometry& odometry, core::TimeUs stamp) {
  while (!delivered_.empty() && delivered_.front().stamp <= stamp) {
    add(odometry, delivered_.front());
    delivered_.pop_front();
  }
}

void VehicleSensorFeed::feed_copy(slam::Odometry& odometry, core::TimeUs stamp) const {
  for (const Sample& v : delivered_) {
    if (v.stamp > stamp) break;
    add(odometry, v);
  }
}

void VehicleSensorFeed::drain_to(SensorTap& tap, core::TimeUs now) {
  using sdk_bridge::to_sdk;
  const SensorTapKinds& kinds = tap.kinds();
  for (const Sample& v : delivered_) {
    if (v.kind == 0 && kinds.imu) tap.on_imu(now, to_sdk(v.imu));
    if (v.kind == 1 && kinds.wheels) tap.on_wheels(now, to_sdk(v.wheels));
    if (v.kind == 2 && kinds.steering) tap.on_steering(now, to_sdk(v.steering));
  }
  delivered_.clear();
}

}  // namespace conesim::sim
