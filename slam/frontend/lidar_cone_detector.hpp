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
  /// Points nearer than this to the sensor (horizontally) are ignored (the car's own body), m.
  double min_range_m = 0.5;

  // ground: a plane fitted by least squares to the points near the vehicle's ground plane,
  // refitted twice on the inliers, so that pitch and roll of the car are followed
  /// Points within this height of the vehicle frame's z = 0 are candidates for the fit, metres.
  double ground_candidate_band_m = 0.15;
  /// Residual of an inlier in the refits, metres.
  double ground_inlier_m = 0.03;
  /// Points lower than this above the fitted plane are ground, metres (range noise of 1.5 cm
  /// moves a ground return by well under 1 cm vertically; the cones' base plates, 2-2.5 cm, go
  /// with the ground).
  double min_point_height_m = 0.03;
  /// Points higher than this above the plane are not cones, metres.
  double max_point_height_m = 0.8;

  // clustering: points whose ground-projected distance is below this belong together
  /// Linking distance, metres (cones stand at least ~2.5 m apart; one cone spans < 0.4 m).
  double cluster_distance_m = 0.3;

  // validation of a cluster as a cone
  /// Fewest points of a cone.
  int min_cluster_points = 3;
  /// Widest ground-projected extent of a cone's points, metres (big cone plate 0.285 m).
  double max_cluster_extent_m = 0.45;
  /// Cones whose bases touch (a start gate's big orange cones stand 0.26-0.30 m apart) link
  /// into one cluster: a cluster wider than one cone (or deeper along the line of sight than a
  /// cone's visible half), by less than this many cones less one, is cut into the number of
  /// cones, up to this many, whose surfaces explain its points best; each piece is then
  /// validated as a cone. 1 turns the cut off.
  int max_row_cones = 3;
  /// Lowest and highest top of a cone's points above the ground, metres.
  double min_cone_height_m = 0.05;
  double max_cone_height_m = 0.6;
  /// A cluster whose top is above this is a big cone (small cones are 0.325 m tall), metres.
  double big_cone_min_height_m = 0.37;
  /// Elevation step between neighbouring rings, degrees (2 for a VLP-16): used to tell whether
  /// a big cone would have been hit by the ring above the cluster's top one.
  double ring_spacing_deg = 2.0;
  /// Elevation of each ring, degrees, ring 0 lowest (the LiDAR model's beam table). When set,
  /// the ring above the top one is looked up here instead of using ring_spacing_deg (a
  /// VLP-32C's rings are 0.33 degrees apart near the horizon, 7 degrees apart far above it).
  std::vector<double> ring_elevations_deg;
  /// A cluster is no cone when the ring above its top one, at its range, would have met a small
  /// cone at least this far below the cone's top and left no point: a low step met by one ring
  /// (the grass edge's 6 cm, a kerb) whose ring above passes over it. Covers the error of the
  /// heights (the ground fit, the car's pitch between rings) and the cone's narrow tip, metres.
  double ring_above_margin_m = 0.05;
  /// Azimuth step between columns, degrees (0.2 for a VLP-16 at 10 Hz): when the height leaves
  /// the size open, the width of each ring's points across the line of sight, 2 r(h) less
  /// about one step, tells a small cone from a big one.
  double azimuth_step_deg = 0.2;
  /// Smallest log-likelihood lead of one size over the other from the ring widths.
  double size_min_log_likelihood_ratio = 4.0;

  // colour: which paint pattern explains the intensities along the height best
  /// Reflectivity of the paints as the sensor is calibrated (sensors::Reflectivity defaults).
  double reflectivity_blue = 0.15;
  double reflectivity_yellow = 0.65;
  double reflectivity_orange = 0.45;
  double reflectivity_white = 0.85;
  double reflectivity_black = 0.05;
  /// Residual range fall-off of the intensity: gain 1 / (1 + (range / falloff)^2), metres.
  double intensity_falloff_m = 40.0;
  /// One-sigma noise of an intensity reading, 0-255 units.
  double intensity_sigma = 3.0;
  /// Relative error of the intensity model (incidence, facets), added to intensity_sigma.
  double intensity_model_error = 0.08;
  /// The gain fitted per hypothesis (what the model misses of incidence and calibration) is
  /// kept within 1 +- this: wide enough for the model's errors, narrow enough that a bright
  /// orange cannot pass for yellow (reflectivity 0.45 against 0.65).
  double intensity_gain_tolerance = 0.15;
  /// One-sigma error of a point's height above the fitted ground, metres: near a band edge the
  /// point may be on either band, and both paints are weighed.
  double height_sigma_m = 0.005;
  /// Full width of the beam across the scan, mrad (VLP-16: 3.0): a point whose spot may reach
  /// past the cone's silhouette brought back only part of its energy, and is not used for colour.
  double beam_divergence_mrad = 3.0;
  /// Fewest points usable for colour (away from the silhouette and the band edges).
  int colour_min_points = 3;
  /// Smallest log-likelihood lead of the best paint pattern over the next one; below it the
  /// class is kUnknown.
  double colour_min_log_likelihood_ratio = 4.0;

  // noise of the fitted centre (see covariance_of in the .cpp for the derivation)
  /// One-sigma range noise of a return, metres (VLP-16: 0.015).
  double range_noise_sigma_m = 0.015;
  /// One-sigma error of the cone model (radius at a height, facets, ground fit), metres.
  double model_sigma_m = 0.005;
  /// One-sigma bearing error (mount calibration, timing), radians: grows the covariance with
  /// range across the line of sight.
  double bearing_sigma_rad = 0.002;
  /// One-sigma relative error of the odometry speed used for de-skew: a cluster fired dt
  /// before the sweep end is off by this x speed x dt (with de-skew off, by the whole motion).
  double speed_relative_sigma = 0.02;

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

  /// Finds the cones of one sweep (points in the sensor frame, as sensors::Lidar gives them),
  /// in the vehicle frame at frame_stamp (at or after the sweep's start): the run and the SDK
  /// refer a sweep's cones to its last column, `LidarSweep::end_us`.
  LidarDetections detect(const core::PointCloud& cloud, const SweepMotion& motion,
                         core::TimeUs frame_stamp) const;
  /// The same in the vehicle frame one sweep period after the sweep's start.
  LidarDetections detect(const core::PointCloud& cloud, const SweepMotion& motion) const;

  const LidarDetectorConfig& config() const { return config_; }

 private:
  LidarDetectorConfig config_;
  core::Pose3 sensor_in_vehicle_;
};

}  // namespace conesim::slam::frontend
