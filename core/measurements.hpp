#pragma once
// Raw sensor data as the system under test receives it, and the ground-truth labels that
// travel beside it (docs/architecture.md: only the scorers read labels).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <vector>

#include "core/geometry.hpp"
#include "core/time.hpp"

namespace conesim::core {

/// A rigid transform in 3D (position in metres, orientation as a unit quaternion).
struct Pose3 {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();

  /// Maps a point from this frame into the parent frame.
  Eigen::Vector3d transform(const Eigen::Vector3d& p) const { return position + orientation * p; }
  /// Composition this * other.
  Pose3 compose(const Pose3& other) const {
    return {transform(other.position), (orientation * other.orientation).normalized()};
  }
  /// The inverse transform.
  Pose3 inverse() const {
    const Eigen::Quaterniond q = orientation.conjugate();
    return {-(q * position), q};
  }
  /// The planar part: x, y and the heading of the x axis.
  Pose2 planar() const {
    const Eigen::Vector3d x_axis = orientation * Eigen::Vector3d::UnitX();
    return {position.x(), position.y(), std::atan2(x_axis.y(), x_axis.x())};
  }
  /// Interpolates between a (s = 0) and b (s = 1): linear in position, slerp in orientation.
  static Pose3 interpolate(const Pose3& a, const Pose3& b, double s) {
    return {a.position + s * (b.position - a.position), a.orientation.slerp(s, b.orientation)};
  }
};

/// One LiDAR return in the sensor frame.
struct LidarPoint {
  float x = 0.f;
  float y = 0.f;
  float z = 0.f;
  /// Calibrated reflectivity-like intensity, 0-255.
  float intensity = 0.f;
  /// Laser channel, 0 = lowest elevation.
  uint16_t ring = 0;
  /// Time of the return after the sweep's start, seconds.
  float time_offset_s = 0.f;
};

/// One sweep of a spinning LiDAR.
struct PointCloud {
  /// Time of the sweep's first column.
  TimeUs stamp = 0;
  std::vector<LidarPoint> points;
};

/// Ground truth of a sweep, index by index with PointCloud::points: the cone id each point hit
/// (kGroundLabel for the ground, core::clutter_label() of its class for a scenery object:
/// -2 and below, never a cone id).
struct PointCloudLabels {
  static constexpr int kGroundLabel = -1;
  std::vector<int> cone_id;
  /// Pose of the sensor in the track frame at each column's firing time is not stored; the
  /// sensor pose at the sweep's start and end are.
  Pose3 sensor_pose_start;
  Pose3 sensor_pose_end;
};

/// Pinhole intrinsics of a rectified camera, pixels.
struct CameraIntrinsics {
  int width_px = 0;
  int height_px = 0;
  double fx = 0.0;
  double fy = 0.0;
  double cx = 0.0;
  double cy = 0.0;
  /// Lens distortion in OpenCV's model and order (k1, k2, p1, p2, k3): a point (x, y) = (X/Z,
  /// Y/Z) in the camera frame is drawn at (fx xd + cx, fy yd + cy) with r2 = x^2 + y^2,
  /// radial = 1 + k1 r2 + k2 r2^2 + k3 r2^3, xd = x radial + 2 p1 x y + p2 (r2 + 2 x^2),
  /// yd = y radial + p1 (r2 + 2 y^2) + 2 p2 x y. All zero: a pinhole camera.
  std::array<double, 5> distortion{};

  bool operator==(const CameraIntrinsics&) const = default;
  bool distorted() const {
    for (const double d : distortion)
      if (d != 0.0) return true;
    return false;
  }
  /// The pixel where the ray through the normalised point (x, y) = (X/Z, Y/Z) is drawn.
  Eigen::Vector2d pixel_of(const Eigen::Vector2d& normalised) const {
    const double x = normalised.x(), y = normalised.y();
    const double r2 = x * x + y * y;
    const auto& [k1, k2, p1, p2, k3] = distortion;
    const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
    const double xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
    const double yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
    return {fx * xd + cx, fy * yd + cy};
  }
};

/// An 8-bit RGB image, rows top to bottom.
struct RgbImage {
  int width_px = 0;
  int height_px = 0;
  std::vector<uint8_t> rgb;
};

/// A stereo pair from rectified cameras with exact calibration. The camera frame is the usual
/// optical one: x right, y down, z forward.
struct StereoFrame {
  TimeUs stamp = 0;
  RgbImage left;
  RgbImage right;
  /// Metric depth along the optical axis of the left image, row-major, empty unless requested.
  std::vector<float> left_depth_m;
  CameraIntrinsics intrinsics;
  /// Left camera pose in the vehicle frame (rear axle centre on the ground plane).
  Pose3 left_in_vehicle;
  /// Right camera pose in the vehicle frame.
  Pose3 right_in_vehicle;
  /// Distance between the optical centres, metres.
  double baseline_m = 0.0;
};

/// Ground truth of a stereo frame: the camera poses in the track frame.
struct StereoLabels {
  Pose3 left_in_track;
  Pose3 right_in_track;
};

/// An IMU sample in the IMU frame (aligned with the vehicle frame).
struct ImuSample {
  TimeUs stamp = 0;
  /// Angular rate, rad/s.
  Eigen::Vector3d gyro_rps = Eigen::Vector3d::Zero();
  /// Specific force (acceleration minus gravity), m/s^2: +9.81 on z at rest.
  Eigen::Vector3d accel_mps2 = Eigen::Vector3d::Zero();
};

/// Wheel speeds from the encoders, rad/s, order fl, fr, rl, rr.
struct WheelSpeeds {
  TimeUs stamp = 0;
  std::array<double, 4> omega_rps{};
};

/// The steering angle sensor: the single-track equivalent angle, radians, positive left.
struct SteeringSample {
  TimeUs stamp = 0;
  double steer_rad = 0.0;
};

/// A GNSS fix in the track frame (a local tangent plane), metres and m/s.
struct GnssFix {
  TimeUs stamp = 0;
  Eigen::Vector2d position = Eigen::Vector2d::Zero();
  Eigen::Vector2d velocity_mps = Eigen::Vector2d::Zero();
  /// One-sigma horizontal accuracy the receiver reports, metres.
  double sigma_m = 0.0;
};

/// Ground truth of a cone observation batch: the true cone id of each observation, index by
/// index, or kFalsePositive.
struct ObservationLabels {
  static constexpr int kFalsePositive = -1;
  /// A cone standing off the track (world.clutter's spare cones): the k-th is labelled
  /// kOffTrackCone - k. It is a real cone, so finding it is no false detection, and observing it
  /// again and again as one landmark is a right association; it is not a cone of the track.
  static constexpr int kOffTrackCone = -1000;
  static constexpr int off_track_cone(int k) { return kOffTrackCone - k; }
  static constexpr bool is_off_track_cone(int label) { return label <= kOffTrackCone; }
  std::vector<int> cone_id;
};

}  // namespace conesim::core
