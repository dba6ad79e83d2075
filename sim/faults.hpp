#pragma once
// Sensor and vehicle faults (the scenario's `faults:` block): LiDAR point dropout, sector
// blackouts and lost sweeps, camera blackouts and frozen frames, GNSS outages, IMU bias steps,
// wheel slip, and delay jitter with out-of-order delivery of the perception's frames. Each fault
// has a time window on the sim clock. Every random draw comes from a generator seeded from the
// run's seed, the fault's place in the list and the sample's stamp, never from the sensors'
// noise streams: a run without faults is the run it always was, and a faulted run repeats to
// the bit whatever the threads do.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/measurements.hpp"
#include "core/time.hpp"

namespace conesim::sim {

/// What a fault does.
enum class FaultKind {
  kLidarDropout,         // each LiDAR point lost with probability `fraction`
  kLidarSectorBlackout,  // no points between azimuths `from_deg` and `to_deg` (sensor frame)
  kLidarLostSweeps,      // whole sweeps never reach perception: one in `every`, or `probability`
  kCameraBlackout,       // black frames
  kCameraFrozen,         // the last frame before the window delivered again and again
  kGnssOutage,           // no GNSS fixes
  kImuBiasStep,          // `gyro_bias_rps` (yaw) and `accel_bias_mps2` (forward) added from start
  kWheelSlip,            // the driven (rear) wheels read `factor` times their speed
  kDelayJitter,          // each perception frame delivered up to `max_delay_s` late
};

/// Every kind's name in the scenario (`lidar_dropout`, ...), in enum order.
const std::vector<std::string>& fault_kind_names();
std::string to_string(FaultKind kind);
std::optional<FaultKind> fault_kind_from_string(const std::string& name);

/// One fault of a scenario: its kind, window and parameters (those of other kinds unused).
struct Fault {
  FaultKind kind = FaultKind::kLidarDropout;
  /// The window on the sim clock (the standstill before the go signal included), seconds; no
  /// end: to the end of the run.
  double start_s = 0.0;
  std::optional<double> end_s;
  double fraction = 0.0;
  double from_deg = 0.0;
  double to_deg = 0.0;
  int every = 0;
  double probability = 0.0;
  double gyro_bias_rps = 0.0;
  double accel_bias_mps2 = 0.0;
  double factor = 1.0;
  double max_delay_s = 0.0;
  bool out_of_order = false;

  /// Whether the fault acts at time t.
  bool active(core::TimeUs t) const;
  /// In words, with its window: "30 % of the LiDAR points dropped from 0.0 s to the end".
  std::string describe() const;
  /// Empty when usable, otherwise "key: what was expected".
  std::string validate() const;
};

/// How much each fault did, index by index with the scenario's faults.
struct FaultCounts {
  /// LiDAR points removed, sweeps lost, camera frames blacked out or frozen, IMU and wheel
  /// samples changed, perception frames delayed: whatever the fault's kind acts on.
  std::vector<int64_t> affected;
  void add(const FaultCounts& other);
};

/// Applies a scenario's faults to the sensors' data. Holds no state that changes: every draw is
/// seeded from (run seed, fault index, stamp), so the calls may come from any thread in any
/// order.
class FaultInjector {
 public:
  FaultInjector() = default;
  FaultInjector(std::vector<Fault> faults, uint64_t seed);

  bool empty() const { return faults_.empty(); }
  const std::vector<Fault>& faults() const { return faults_; }
  /// Zero counts, one per fault.
  FaultCounts zero_counts() const { return {std::vector<int64_t>(faults_.size(), 0)}; }

  /// Whether the LiDAR sweep that ends at `end_us` (the `index`th from the start, counting
  /// from 0) is lost before perception.
  bool lidar_sweep_lost(int64_t index, core::TimeUs end_us, FaultCounts& counts) const;
  /// Removes the points of a sweep that dropout and sector blackouts take, labels with them.
  void apply_lidar(core::PointCloud& cloud, core::PointCloudLabels& labels,
                   FaultCounts& counts) const;
  /// Camera: whether the frame at t is black, or frozen (the previous good frame again).
  bool camera_black(core::TimeUs t, FaultCounts& counts) const;
  bool camera_frozen(core::TimeUs t, FaultCounts& counts) const;
  /// Vehicle sensors: the IMU's bias steps and the wheels' slip at the sample's stamp.
  void apply_imu(core::ImuSample& sample, FaultCounts& counts) const;
  void apply_wheels(core::WheelSpeeds& sample, FaultCounts& counts) const;
  /// When a perception frame stamped `stamp`, due at `due_us`, is delivered with the jitter;
  /// `previous_us` the delivery time of the frame queued before it (without out-of-order
  /// delivery no frame overtakes another). `source` tells the sensors' streams apart.
  core::TimeUs delivery_us(core::TimeUs stamp, core::TimeUs due_us, core::TimeUs previous_us,
                           int source, FaultCounts& counts) const;
  /// The longest extra delay the jitter adds, microseconds (0 without).
  core::TimeUs max_delay_us() const;

 private:
  // a draw in [0, 1) for fault `index` at `stamp` on `stream`
  double draw(size_t index, core::TimeUs stamp, uint64_t stream) const;

  std::vector<Fault> faults_;
  uint64_t seed_ = 0;
};

}  // namespace conesim::sim
