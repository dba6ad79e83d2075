#include "slam/frontend/fusion.hpp"

#include <cmath>
#include <limits>

namespace conesim::slam::frontend {
namespace {

// the covariance of a planar point seen from a frame rotated by yaw
Eigen::Matrix2d rotate_covariance(const Eigen::Matrix2d& covariance, double yaw) {
  const Eigen::Matrix2d r = Eigen::Rotation2Dd(yaw).toRotationMatrix();
  return r * covariance * r.transpose();
}

// pixel of a point of the vehicle frame in the left image and its depth along the optical
// axis; false behind the camera
bool project(const Eigen::Vector3d& in_vehicle, const core::CameraIntrinsics& k,
             const core::Pose3& left_camera_in_vehicle, Eigen::Vector2d& pixel, double& depth_m) {
  const Eigen::Vector3d q = left_camera_in_vehicle.inverse().transform(in_vehicle);
  if (q.z() <= 1e-6) return false;
  pixel = {k.fx * q.x() / q.z() + k.cx, k.fy * q.y() / q.z() + k.cy};
  depth_m = q.z();
  return true;
}

// a camera cone's position sigma along the line of sight from the camera, metres
double ray_sigma(const core::ConeObservation& seen, const core::Pose3& camera_in_vehicle) {
  const core::Vec2 ray = seen.position - camera_in_vehicle.position.head<2>();
  if (ray.norm() < 1e-9) return 0.0;
  const core::Vec2 unit = ray.normalized();
  return std::sqrt(unit.dot(seen.covariance * unit));
}

bool inside(const PixelBox& box, const Eigen::Vector2d& pixel, double margin_px) {
  return pixel.x() >= box.x - margin_px && pixel.x() <= box.x + box.width - 1 + margin_px &&
         pixel.y() >= box.y - margin_px && pixel.y() <= box.y + box.height - 1 + margin_px;
}

}  // namespace

std::string FusionConfig::validate() const {
  if (!(box_margin_px >= 0.0)) return "box_margin_px: expected >= 0";
  if (!(camera_only_gate_m >= 0.0)) return "camera_only_gate_m: expected >= 0";
  if (!(projection_height_m >= 0.0)) return "projection_height_m: expected >= 0";
  if (!(depth_gate_sigmas >= 0.0)) return "depth_gate_sigmas: expected >= 0";
  if (!(depth_gate_m >= 0.0)) return "depth_gate_m: expected >= 0";
  return "";
}

core::ConeObservations fuse(const FusionConfig& config, const std::optional<LidarDetections>& lidar,
                            const std::optional<StereoDetections>& camera,
                            const core::CameraIntrinsics& intrinsics,
                            const core::Pose3& left_camera_in_vehicle,
                            const core::Pose2& camera_in_lidar_frame) {
  core::ConeObservations out;

  // one sensor alone: its cones as they are
  if (!lidar && !camera) return out;
  if (!lidar) return camera->observations();
  out.stamp = lidar->stamp;
  for (const LidarCone& cone : lidar->cones) out.cones.push_back(cone.observation);
  if (!camera) return out;

  // each LiDAR cone, moved into the camera result's vehicle frame and projected into the left
  // image, takes the class of the box it falls in (depths agreeing); when boxes overlap, of
  // the one whose centre column is nearest in units of its half width (a cone partly hidden
  // behind another leaves a narrow box at the edge of the nearer one's)
  const core::Pose2 lidar_in_camera_frame = camera_in_lidar_frame.inverse();
  std::vector<bool> box_used(camera->cones.size(), false);
  for (core::ConeObservation& fused : out.cones) {
    const core::Vec2 p = lidar_in_camera_frame.transform(fused.position);
    Eigen::Vector2d pixel;
    double depth_m = 0.0;
    if (!project({p.x(), p.y(), config.projection_height_m}, intrinsics, left_camera_in_vehicle,
                 pixel, depth_m))
      continue;
    int best = -1;
    double best_offset = std::numeric_limits<double>::infinity();
    for (size_t i = 0; i < camera->cones.size(); ++i) {
      const CameraCone& seen = camera->cones[i];
      if (!inside(seen.box, pixel, config.box_margin_px)) continue;
      const double depth_error = std::abs(seen.depth_m - depth_m);
      const double sigma = ray_sigma(seen.observation, left_camera_in_vehicle);
      if (depth_error > config.depth_gate_sigmas * sigma + config.depth_gate_m) continue;
      const double centre = seen.box.x + 0.5 * (seen.box.width - 1);
      const double offset = std::abs(pixel.x() - centre) / (0.5 * seen.box.width + 1.0);
      if (offset < best_offset) {
        best_offset = offset;
        best = static_cast<int>(i);
      }
    }
    if (best < 0) continue;
    box_used[best] = true;
    if (camera->cones[best].observation.cls != core::ConeClass::kUnknown)
      fused.cls = camera->cones[best].observation.cls;
  }

  // camera cones that no LiDAR cone explains, in the LiDAR result's frame
  if (!config.add_camera_only) return out;
  const size_t lidar_count = lidar->cones.size();
  for (size_t i = 0; i < camera->cones.size(); ++i) {
    if (box_used[i]) continue;
    core::ConeObservation moved = camera->cones[i].observation;
    moved.position = camera_in_lidar_frame.transform(moved.position);
    moved.covariance = rotate_covariance(moved.covariance, camera_in_lidar_frame.yaw);
    bool explained = false;
    for (size_t j = 0; j < lidar_count && !explained; ++j)
      explained = (out.cones[j].position - moved.position).norm() <= config.camera_only_gate_m;
    if (!explained) out.cones.push_back(moved);
  }
  return out;
}

}  // namespace conesim::slam::frontend
