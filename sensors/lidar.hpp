#pragma once
// The ray-cast LiDAR: an Embree scene of the ground and every cone, swept column by column
// from the vehicle pose at each column's firing time (ARCHITECTURE decision 4).
//
// Per sweep the harness calls, after the sweep has ended:
//   PoseHistory poses;                           // push(t, vehicle pose) every physics step
//   Lidar lidar(config, track);                   // once per run
//   lidar.set_cone_present(id, false);            // when the referee knocks a cone over
//   LidarScan scan = lidar.sweep(start, poses, rng);  // needs poses over [start, sweep_end]

#include <cstdint>
#include <memory>
#include <vector>

#include "core/measurements.hpp"
#include "core/rng.hpp"
#include "core/time.hpp"
#include "sensors/lidar_config.hpp"
#include "sensors/pose_history.hpp"
#include "tracks/track.hpp"

namespace conesim::sensors {

/// What happened to the rays of one sweep.
struct LidarSweepStats {
  /// Rays cast (columns x channels).
  int64_t rays = 0;
  /// Rays that hit the ground or a cone within max_range_m.
  int64_t hits = 0;
  /// Hits lost to the configured dropout.
  int64_t dropped = 0;
  /// Hits whose noisy range fell outside [min_range_m, max_range_m].
  int64_t out_of_range = 0;
  /// Rays cast through the Embree scene because they pass near a standing cone; the others
  /// can only meet the ground, which is intersected directly.
  int64_t traced = 0;
};

/// One sweep: the data the system under test receives and the ground truth beside it.
struct LidarScan {
  core::PointCloud cloud;
  core::PointCloudLabels labels;
  LidarSweepStats stats;
};

/// A spinning LiDAR over a track. Holds the Embree scene (the state: which cones stand): the
/// ground and one instance per cone of its class's mesh, so that knocking a cone over rebuilds
/// only the top level. A ray whose track on the ground passes clear of every standing cone's
/// footprint meets the ground plane analytically; only the others are cast through Embree. The
/// configuration never changes. sweep() may run on several threads at once, but not at
/// the same time as set_cone_present().
class Lidar {
 public:
  /// Builds the scene: a ground quad covering the track and every cone at its true size.
  /// Throws std::invalid_argument for a configuration that fails validate() and
  /// std::runtime_error when Embree cannot start.
  Lidar(const LidarConfig& config, const tracks::Track& track);
  ~Lidar();
  Lidar(Lidar&&) noexcept;
  Lidar& operator=(Lidar&&) noexcept;
  Lidar(const Lidar&) = delete;
  Lidar& operator=(const Lidar&) = delete;

  /// The configuration the LiDAR was built with.
  const LidarConfig& config() const;

  /// Puts a cone back in the scene or takes it out (a knocked cone leaves the scene). Throws
  /// std::out_of_range for an id the track does not have.
  void set_cone_present(int cone_id, bool present);
  /// True when the cone is in the scene.
  bool cone_present(int cone_id) const;

  /// Firing time of a column of the sweep that starts at sweep_start.
  core::TimeUs column_time(core::TimeUs sweep_start, int column) const;
  /// Firing time of the sweep's last column: the pose history must reach it.
  core::TimeUs sweep_end(core::TimeUs sweep_start) const;
  /// The sensor frame in the track frame for a vehicle pose.
  core::Pose3 sensor_pose(const core::Pose3& vehicle_pose) const;

  /// Casts one sweep starting at sweep_start, each column from the vehicle pose at its firing
  /// time. Points are in the sensor frame of their own column (motion distortion included),
  /// in firing order. Throws std::invalid_argument when the poses do not cover the sweep.
  LidarScan sweep(core::TimeUs sweep_start, const PoseHistory& vehicle_poses, core::Rng& rng) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace conesim::sensors
