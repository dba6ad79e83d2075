#pragma once
// LiDAR-camera fusion (the FST pipeline): LiDAR cones, projected into the latest left image,
// take their colour from the camera box they fall in. LiDAR positions are kept (they are the
// more precise); camera cones that no LiDAR cone explains are added with their own covariance
// when configured, so either sensor alone keeps working when the other fails.

#include <optional>
#include <string>

#include "core/autonomy_types.hpp"
#include "core/measurements.hpp"
#include "slam/frontend/lidar_cone_detector.hpp"
#include "slam/frontend/stereo_cone_detector.hpp"

namespace conesim::slam::frontend {

/// Parameters of the fusion.
struct FusionConfig {
  /// A projected LiDAR cone takes a box's colour when it falls inside the box grown by this
  /// margin, pixels.
  double box_margin_px = 4.0;
  /// Camera cones with no LiDAR cone within this distance are added on their own, metres.
  double camera_only_gate_m = 1.0;
  /// Add camera-only cones (off: the camera only colours).
  bool add_camera_only = true;
  /// Height above the ground of the point of a LiDAR cone projected into the image, metres
  /// (about mid-height of a small cone, so that it falls inside the cone's box).
  double projection_height_m = 0.15;
  /// A LiDAR cone takes a box's colour only when their depths along the optical axis agree
  /// within this many of the camera cone's sigmas along its viewing ray (from its covariance)
  /// plus depth_gate_m: a cone seen past the edge of a nearer one is not coloured by it.
  double depth_gate_sigmas = 3.0;
  double depth_gate_m = 0.3;

  /// Empty when valid, else a message naming the key and what was expected.
  std::string validate() const;
};

/// Fuses one LiDAR result with the latest stereo result. camera_in_lidar_frame is the pose of
/// the camera frame's vehicle frame in the LiDAR result's vehicle frame (from the odometry;
/// identity when both share a stamp). Either input may be missing. The output is in the
/// vehicle frame of the LiDAR result (or of the camera result when there is no LiDAR one).
core::ConeObservations fuse(const FusionConfig& config,
                            const std::optional<LidarDetections>& lidar,
                            const std::optional<StereoDetections>& camera,
                            const core::CameraIntrinsics& intrinsics,
                            const core::Pose3& left_camera_in_vehicle,
                            const core::Pose2& camera_in_lidar_frame);

}  // namespace conesim::slam::frontend
