#pragma once
// The ray-cast LiDAR: the ground plane and every cone's Embree mesh, swept column by column
// from the vehicle pose at each column's firing time (docs/architecture.md).
//
// Per sweep the harness calls, after the sweep has ended:
//   PoseHistory poses;                           // push(t, vehicle pose) every physics step
//   Lidar lidar(config, track);                   // once per run
//   lidar.set_cone_present(id, false);            // when the referee knocks a cone over
//   LidarScan scan = lidar.sweep(start, poses, rng);  // needs poses over [start, sweep_end]
// or, a part at a time as the poses arrive (the same points):
//   LidarNoise noise(rng);
//   lidar.sweep_columns(start, 0, 256, poses, noise, scan);  // poses up to column 255's time
//   lidar.sweep_columns(start, 256, lidar.config().columns, poses, noise, scan);

#include <cstdint>
#include <memory>
#include <vector>

#include "core/measurements.hpp"
#include "core/rng.hpp"
#include "core/time.hpp"
#include "sensors/lidar_config.hpp"
#include "sensors/pose_history.hpp"
#include "tracks/ground.hpp"
#include "tracks/scenery.hpp"
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
  /// Hits too weak to be detected (dark or grazing surfaces far away; detection_range_10pct_m).
  int64_t faded = 0;
  /// Hits whose noisy range fell outside [min_range_m, max_range_m].
  int64_t out_of_range = 0;
  /// Rays cast through Embree (the meshes of the standing cones they pass near); the others
  /// can only meet the ground, which is intersected directly.
  int64_t traced = 0;

  /// Adds the counts of another part of the sweep.
  LidarSweepStats& operator+=(const LidarSweepStats& o) {
    rays += o.rays, hits += o.hits, dropped += o.dropped, faded += o.faded;
    out_of_range += o.out_of_range, traced += o.traced;
    return *this;
  }
};

/// One sweep: the data the system under test receives and the ground truth beside it.
struct LidarScan {
  core::PointCloud cloud;
  core::PointCloudLabels labels;
  LidarSweepStats stats;
};

/// The noise of a sweep cast in parts (Lidar::sweep_columns): the normal sampler with the
/// samples it holds and the generator of the uniform draws (dropout, fading), both seeded from
/// the sweep's generator when the sweep starts and carried from one part to the next, so that the
/// parts draw the same numbers as one sweep() does. (A caller that casts parts on several threads
/// gives each part its own noise instead, seeded from the sweep's seed and the part's index, as
/// sim/sensor_rig.cpp does.)
struct LidarNoise {
  explicit LidarNoise(core::Rng& generator) : normal(generator), uniform_bits(generator) {}
  core::ZigguratNormals normal;
  core::Xoshiro256 uniform_bits;
  /// A uniform float in [0, 1).
  float uniform() { return static_cast<float>(uniform_bits() >> 40) * 0x1.0p-24f; }
};

/// A spinning LiDAR over a track. Holds one Embree mesh per cone class and every cone's class
/// and place (the state: which cones stand). Every ray meets the ground plane analytically; a
/// ray whose track on the ground enters a standing cone's footprint below its top is also cast
/// through that cone's mesh, shifted to the cone's place. The configuration never changes.
/// sweep() may run on several threads at once, but not at the same time as set_cone_present().
class Lidar {
 public:
  /// Builds the scene: a ground rectangle covering the track and every cone at its true size,
  /// and the scenery objects (tracks/scenery.hpp), whose points carry their class's clutter
  /// label (core/clutter.hpp), never a cone id. A ground that is not flat (tracks/ground.hpp)
  /// replaces the plane: its grid becomes a triangle mesh every ray is cast through (labelled
  /// ground; no ground beyond the grid), and the cones and objects stand on it. Throws
  /// std::invalid_argument for a configuration that fails validate() and std::runtime_error when
  /// Embree cannot start.
  Lidar(const LidarConfig& config, const tracks::Track& track,
        const std::vector<tracks::SceneryObject>& scenery = {},
        const tracks::GroundModel& ground = {});
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

  /// Columns cast together: a sweep cast in parts that start on multiples of it, in order,
  /// gives exactly the points of sweep().
  int column_block() const;
  /// Casts the columns [column_begin, column_end) of the sweep starting at sweep_start and
  /// appends their points to scan, so that the harness can cast a sweep while its poses arrive.
  /// Column 0 sets the scan's stamp and start pose, the last column its end pose. The poses
  /// must cover the columns' firing times (else std::invalid_argument); noise starts with the
  /// sweep and goes on through its parts.
  void sweep_columns(core::TimeUs sweep_start, int column_begin, int column_end,
                     const PoseHistory& vehicle_poses, LidarNoise& noise, LidarScan& scan) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace conesim::sensors
