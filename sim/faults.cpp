#include "sim/faults.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "core/rng.hpp"

namespace conesim::sim {

using core::TimeUs;

namespace {

// the faults' streams, apart from every sensor's (sensor_rig.cpp 101-102, vehicle feed 201-203)
constexpr uint64_t kFaultStream = 301;
// draws of one fault: lost sweeps, dropout, delay
constexpr uint64_t kLostSweepDraw = 1;
constexpr uint64_t kDropoutDraw = 2;
constexpr uint64_t kDelayDraw = 3;

std::string seconds(double s) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.1f s", s);
  return buf;
}

std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%g", v);
  return buf;
}

// the angle of a point counter-clockwise from a sector's start, in [0, 360)
double degrees_from(double from_deg, double azimuth_deg) {
  double d = std::fmod(azimuth_deg - from_deg, 360.0);
  return d < 0.0 ? d + 360.0 : d;
}

}  // namespace

const std::vector<std::string>& fault_kind_names() {
  static const std::vector<std::string> names = {
      "lidar_dropout", "lidar_sector_blackout", "lidar_lost_sweeps", "camera_blackout",
      "camera_frozen", "gnss_outage",           "imu_bias_step",     "wheel_slip",
      "delay_jitter"};
  return names;
}

std::string to_string(FaultKind kind) {
  return fault_kind_names()[static_cast<size_t>(kind)];
}

std::optional<FaultKind> fault_kind_from_string(const std::string& name) {
  const auto& names = fault_kind_names();
  const auto it = std::find(names.begin(), names.end(), name);
  if (it == names.end()) return std::nullopt;
  return static_cast<FaultKind>(it - names.begin());
}

bool Fault::active(TimeUs t) const {
  return t >= core::from_seconds(start_s) && (!end_s || t < core::from_seconds(*end_s));
}

std::string Fault::describe() const {
  const std::string window =
      "from " + seconds(start_s) + (end_s ? " to " + seconds(*end_s) : " to the end");
  switch (kind) {
    case FaultKind::kLidarDropout:
      return number(100.0 * fraction) + " % of the LiDAR points dropped " + window;
    case FaultKind::kLidarSectorBlackout:
      return "LiDAR blind from " + number(from_deg) + " to " + number(to_deg) + " deg " + window;
    case FaultKind::kLidarLostSweeps:
      return (every > 0 ? "one LiDAR sweep in " + std::to_string(every)
                        : number(100.0 * probability) + " % of the LiDAR sweeps") +
             " lost " + window;
    case FaultKind::kCameraBlackout:
      return "camera frames black " + window;
    case FaultKind::kCameraFrozen:
      return "camera frozen on its last frame " + window;
    case FaultKind::kGnssOutage:
      return "no GNSS fix " + window;
    case FaultKind::kImuBiasStep:
      return "IMU bias step of " + number(gyro_bias_rps) + " rad/s (yaw rate) and " +
             number(accel_bias_mps2) + " m/s^2 (forward) " + window;
    case FaultKind::kWheelSlip:
      return "rear wheels read " + number(factor) + " x their speed " + window;
    case FaultKind::kDelayJitter:
      return "perception frames up to " + number(1000.0 * max_delay_s) + " ms late" +
             (out_of_order ? ", out of order," : "") + " " + window;
  }
  return window;
}

std::string Fault::validate() const {
  if (!(start_s >= 0.0 && start_s <= 1e5)) return "start_s: expected a time from 0 to 100000 s";
  if (end_s && !(*end_s > start_s && *end_s <= 1e5))
    return "end_s: expected a time after start_s (" + number(start_s) + " s), at most 100000 s";
  switch (kind) {
    case FaultKind::kLidarDropout:
      if (!(fraction > 0.0 && fraction <= 1.0))
        return "fraction: expected the share of points lost, in (0, 1]";
      break;
    case FaultKind::kLidarSectorBlackout:
      if (!(from_deg >= -360.0 && from_deg <= 360.0 && to_deg >= -360.0 && to_deg <= 360.0) ||
          from_deg == to_deg)
        return "from_deg: expected two different azimuths from -360 to 360 degrees (from_deg, "
               "to_deg: the blind sector counter-clockwise from one to the other, 0 ahead)";
      break;
    case FaultKind::kLidarLostSweeps:
      if ((every > 0) == (probability > 0.0))
        return "every: expected either every (one sweep in N lost, N >= 2) or probability (of "
               "each sweep, in (0, 1])";
      if (every != 0 && every < 2) return "every: expected N >= 2 (one sweep in N lost)";
      if (!(probability >= 0.0 && probability <= 1.0))
        return "probability: expected a probability in (0, 1]";
      break;
    case FaultKind::kImuBiasStep:
      if (!(std::abs(gyro_bias_rps) <= 1.0 && std::abs(accel_bias_mps2) <= 20.0) ||
          (gyro_bias_rps == 0.0 && accel_bias_mps2 == 0.0))
        return "gyro_bias_rps: expected a bias step: gyro_bias_rps up to 1 rad/s, "
               "accel_bias_mps2 up to 20 m/s^2, not both 0";
      break;
    case FaultKind::kWheelSlip:
      if (!(factor >= 0.0 && factor <= 10.0) || factor == 1.0)
        return "factor: expected the wheel speed's factor from 0 to 10, not 1";
      break;
    case FaultKind::kDelayJitter:
      if (!(max_delay_s > 0.0 && max_delay_s <= 1.0))
        return "max_delay_s: expected the longest extra delay in (0, 1] s";
      break;
    case FaultKind::kCameraBlackout:
    case FaultKind::kCameraFrozen:
    case FaultKind::kGnssOutage:
      break;
  }
  return {};
}

void FaultCounts::add(const FaultCounts& other) {
  if (affected.size() < other.affected.size()) affected.resize(other.affected.size(), 0);
  for (size_t i = 0; i < other.affected.size(); ++i) affected[i] += other.affected[i];
}

FaultInjector::FaultInjector(std::vector<Fault> faults, uint64_t seed)
    : faults_(std::move(faults)), seed_(core::derive_seed(seed, kFaultStream)) {}

double FaultInjector::draw(size_t index, TimeUs stamp, uint64_t stream) const {
  core::Rng rng(
      core::derive_seed(core::derive_seed(seed_ + index, stream), static_cast<uint64_t>(stamp)));
  return core::uniform(rng, 0.0, 1.0);
}

bool FaultInjector::lidar_sweep_lost(int64_t index, TimeUs end_us, FaultCounts& counts) const {
  bool lost = false;
  for (size_t i = 0; i < faults_.size(); ++i) {
    const Fault& f = faults_[i];
    if (f.kind != FaultKind::kLidarLostSweeps || !f.active(end_us)) continue;
    // one in N: the Nth, 2Nth, ... sweep of the run; or a draw per sweep
    const bool this_one =
        f.every > 0 ? (index + 1) % f.every == 0 : draw(i, end_us, kLostSweepDraw) < f.probability;
    if (this_one && !lost) ++counts.affected[i];
    lost = lost || this_one;
  }
  return lost;
}

void FaultInjector::apply_lidar(core::PointCloud& cloud, core::PointCloudLabels& labels,
                                FaultCounts& counts) const {
  for (size_t i = 0; i < faults_.size(); ++i) {
    const Fault& f = faults_[i];
    if (f.kind != FaultKind::kLidarDropout && f.kind != FaultKind::kLidarSectorBlackout) continue;
    // one generator per sweep and fault, drawn point by point in the sweep's order
    core::Rng rng(core::derive_seed(core::derive_seed(seed_ + i, kDropoutDraw),
                                    static_cast<uint64_t>(cloud.stamp)));
    const double sector_deg = degrees_from(f.from_deg, f.to_deg);
    size_t kept = 0;
    for (size_t k = 0; k < cloud.points.size(); ++k) {
      const core::LidarPoint& p = cloud.points[k];
      const TimeUs t = cloud.stamp + core::from_seconds(p.time_offset_s);
      bool lose = false;
      if (f.kind == FaultKind::kLidarDropout) {
        // a draw for every point, in or out of the window, so that the window does not shift
        // the draws of the points after it
        lose = core::uniform(rng, 0.0, 1.0) < f.fraction && f.active(t);
      } else if (f.active(t)) {
        const double azimuth = std::atan2(p.y, p.x) * 180.0 / std::numbers::pi;
        lose = degrees_from(f.from_deg, azimuth) <= sector_deg;
      }
      if (lose) {
        ++counts.affected[i];
        continue;
      }
      cloud.points[kept] = p;
      if (k < labels.cone_id.size()) labels.cone_id[kept] = labels.cone_id[k];
      ++kept;
    }
    cloud.points.resize(kept);
    if (labels.cone_id.size() > kept) labels.cone_id.resize(kept);
  }
}

bool FaultInjector::camera_black(TimeUs t, FaultCounts& counts) const {
  for (size_t i = 0; i < faults_.size(); ++i)
    if (faults_[i].kind == FaultKind::kCameraBlackout && faults_[i].active(t)) {
      ++counts.affected[i];
      return true;
    }
  return false;
}

bool FaultInjector::camera_frozen(TimeUs t, FaultCounts& counts) const {
  for (size_t i = 0; i < faults_.size(); ++i)
    if (faults_[i].kind == FaultKind::kCameraFrozen && faults_[i].active(t)) {
      ++counts.affected[i];
      return true;
    }
  return false;
}

void FaultInjector::apply_imu(core::ImuSample& sample, FaultCounts& counts) const {
  for (size_t i = 0; i < faults_.size(); ++i) {
    const Fault& f = faults_[i];
    if (f.kind != FaultKind::kImuBiasStep || !f.active(sample.stamp)) continue;
    sample.gyro_rps.z() += f.gyro_bias_rps;
    sample.accel_mps2.x() += f.accel_bias_mps2;
    ++counts.affected[i];
  }
}

void FaultInjector::apply_wheels(core::WheelSpeeds& sample, FaultCounts& counts) const {
  for (size_t i = 0; i < faults_.size(); ++i) {
    const Fault& f = faults_[i];
    if (f.kind != FaultKind::kWheelSlip || !f.active(sample.stamp)) continue;
    sample.omega_rps[2] *= f.factor;
    sample.omega_rps[3] *= f.factor;
    ++counts.affected[i];
  }
}

TimeUs FaultInjector::delivery_us(TimeUs stamp, TimeUs due_us, TimeUs previous_us, int source,
                                  FaultCounts& counts) const {
  TimeUs at = due_us;
  bool in_order = true;
  for (size_t i = 0; i < faults_.size(); ++i) {
    const Fault& f = faults_[i];
    if (f.kind != FaultKind::kDelayJitter || !f.active(stamp)) continue;
    const double u = draw(i, stamp, kDelayDraw + 16 * static_cast<uint64_t>(source));
    at += core::from_seconds(u * f.max_delay_s);
    in_order = in_order && !f.out_of_order;
    ++counts.affected[i];
  }
  return in_order ? std::max(at, previous_us) : at;
}

TimeUs FaultInjector::max_delay_us() const {
  TimeUs most = 0;
  for (const Fault& f : faults_)
    if (f.kind == FaultKind::kDelayJitter) most += core::from_seconds(f.max_delay_s);
  return most;
}

}  // namespace conesim::sim
