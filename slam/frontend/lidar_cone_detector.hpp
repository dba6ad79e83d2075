#pragma once
// Cones from a LiDAR sweep: de-skew, ground removal, Euclidean clustering, validation by size,
// height and point count, the cone centre fitted to the visible surface, colour from the
// intensity pattern along the height, and a covariance that grows with range.
//
//   LidarConeDetector detector(config, lidar_mount_in_vehicle);
//   LidarDetections d = detector.detect(cloud, motion);   // vehicle frame at the sweep end

#include <string>
#include <vector>

#include "core/autonomy_types.hpp"
#include "core/measurements.hpp"

namespace conesim::slam::frontend {

/// Planar motion of the vehicle during a sweep, from the odometry (constant over the sweep).
struct SweepMotion {
  /// Forward speed, m/s.
  double speed_mps = 0.0;
  /// Yaw rate, rad/s.
  double yaw_rate_rps = 0.0;
};

/// Parameters of the LiDAR cone detector (defaults tuned for a VLP-16 on the front wing).
struct LidarDetectorConfig {
  /// Length of one sweep, seconds (the LiDAR's 1 / rate_hz); observations are referred to the
  /// vehicle frame at the sweep's end.
  double sweep_period_s = 0.1;
  /// Undo the motion distortion with SweepMotion (off: points taken as if fired at the end).
  bool deskew = true;
  /// Points farther than this from the sensor (horizontally) are ignored, metres.
  double max_range_m = 20.0;
  // (the implementation adds its own tuning keys: ground, clustering, validation, colour, noise)

  /// Empty when valid, else a message naming the key and what was expected.
  std::string validate() const;
};

/// One cone found in a sweep.
struct LidarCone {
  /// Position (vehicle frame at the sweep end), class or kUnknown, covariance; track_id -1.
  core::ConeObservation observation;
  /// The fitted centre in the sensor frame at the sweep end (x, y on the cone's axis, z of the
  /// ground under it), metres.
  Eigen::Vector3d centre_sensor = Eigen::Vector3d::Zero();
  /// Visible height above the ground, metres.
  double height_m = 0.0;
  /// Number of points in the cluster.
  int points = 0;
  /// Indices into PointCloud::points of the cluster's points (lets the harness score with the
  /// labels; the detector itself never sees labels).
  std::vector<int> point_indices;
};

/// The result of one sweep.
struct LidarDetections {
  /// Stamp of the vehicle frame the cones are expressed in: the sweep's end.
  core::TimeUs stamp = 0;
  std::vector<LidarCone> cones;
  /// Points left after ground removal (for reports).
  int non_ground_points = 0;
  /// Clusters rejected by validation (for reports).
  int rejected_clusters = 0;

  /// The observations alone, as SLAM takes them.
  core::ConeObservations observations() const;
};

/// Detects cones in LiDAR sweeps. Holds only its configuration: detect() is const and may run
/// on any thread.
class LidarConeDetector {
 public:
  /// Throws std::invalid_argument when config.validate() fails.
  LidarConeDetector(const LidarDetectorConfig& config, const core::Pose3& sensor_in_vehicle);

  /// Finds the cones of one sweep (points in the sensor frame, as sensors::Lidar gives them).
  LidarDetections detect(const core::PointCloud& cloud, const SweepMotion& motion) const;

  const LidarDetectorConfig& config() const { return config_; }

 private:
  LidarDetectorConfig config_;
  core::Pose3 sensor_in_vehicle_;
};

}  // namespace conesim::slam::frontend
