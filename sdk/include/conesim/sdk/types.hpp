#pragma once
// The plain data a plug-in exchanges with conesim: poses, stamps, cone observations, the map,
// sensor frames and commands. Every type here is a standard-layout struct of fixed-width
// numbers and views (Span): no Eigen, no std::vector or std::string crosses the plug-in
// boundary, so a plug-in built with other compiler flags or another Eigen still reads them.
// Frames and units: SI, radians, x forward, y left, z up; the vehicle frame's origin is the
// rear axle centre on the ground.

#include <cstddef>
#include <cstdint>

namespace conesim::sdk {

/// Sim time or a duration, integer microseconds (the one clock of a run).
using TimeUs = int64_t;

/// A read-only view of `size` consecutive values owned by the caller (or, for a value a
/// plug-in returns, by the plug-in until its next call).
template <typename T>
struct Span {
  const T* data = nullptr;
  uint64_t size = 0;

  /// The first value.
  const T* begin() const { return data; }
  /// One past the last value.
  const T* end() const { return data + size; }
  /// The i-th value (no bounds check).
  const T& operator[](uint64_t i) const { return data[i]; }
  /// True when the view holds no value.
  bool empty() const { return size == 0; }
};

/// A planar pose: position in metres, heading in radians (x forward, y left).
struct Pose2 {
  double x_m = 0.0;
  double y_m = 0.0;
  double yaw_rad = 0.0;
};

/// A point or vector in 3D, metres.
struct Vec3 {
  double x = 0.0;
  double y = 0.0;
  double z = 0.0;
};

/// A unit quaternion (w, x, y, z).
struct Quaternion {
  double w = 1.0;
  double x = 0.0;
  double y = 0.0;
  double z = 0.0;
};

/// A rigid transform in 3D: a child frame's origin and orientation in its parent frame.
struct Pose3 {
  Vec3 position_m;
  Quaternion orientation;
};

/// A 2x2 covariance, row-major (xy and yx both given, as conesim's own estimates hold them), m^2.
struct Covariance2 {
  double xx = 0.01;
  double xy = 0.0;
  double yx = 0.0;
  double yy = 0.01;
};

/// The class of a track cone (FSG): blue marks the left boundary, yellow the right one.
enum class ConeClass : int32_t {
  kBlue = 0,
  kYellow = 1,
  kOrangeSmall = 2,
  kOrangeBig = 3,
  kUnknown = 4
};

/// One cone seen by perception, in the vehicle frame at its frame's stamp.
struct ConeObservation {
  /// Position, metres (x forward, y left).
  double x_m = 0.0;
  double y_m = 0.0;
  /// Class as perceived (kUnknown when not known).
  ConeClass cls = ConeClass::kUnknown;
  /// Perception's frame-to-frame track id, -1 when not tracked.
  int32_t track_id = -1;
  /// Position covariance in the vehicle frame, m^2.
  Covariance2 covariance;
};

/// The cones perceived in one sensor frame, in the vehicle frame at `stamp_us`.
struct ConeFrame {
  /// Stamp of the vehicle frame the cones are expressed in; -1 means "no frame" (a perception
  /// that has nothing to deliver for this input).
  TimeUs stamp_us = -1;
  Span<ConeObservation> cones;
};

/// A cone of an estimated (or given) map, in the map frame.
struct MapCone {
  /// Landmark id, unique within one map.
  int32_t id = 0;
  ConeClass cls = ConeClass::kUnknown;
  /// Position in the map frame, metres.
  double x_m = 0.0;
  double y_m = 0.0;
  /// Position covariance in the map frame, m^2.
  Covariance2 covariance;
};

/// Whether SLAM is still building the map or localising on a fixed one.
enum class SlamPhase : int32_t { kMapping = 0, kLocalisation = 1 };

/// A state estimate: what a Slam returns and what a Driver plans from.
struct Estimate {
  /// Stamp of the estimate.
  TimeUs stamp_us = 0;
  /// Pose of the rear axle centre in the map frame (the map frame is the start pose's parent).
  Pose2 pose;
  /// Forward speed, m/s.
  double speed_mps = 0.0;
  /// Yaw rate, rad/s.
  double yaw_rate_rps = 0.0;
  /// The map so far (or the whole known map in localisation).
  Span<MapCone> map;
  SlamPhase phase = SlamPhase::kMapping;
  /// 1 once the map is known to be complete (a loop has closed), else 0.
  int32_t map_complete = 0;
};

/// What a Driver asks of the car: the single-track steering angle and a longitudinal
/// acceleration; the car turns them into wheel angles and torques within its limits.
struct Command {
  /// Equivalent single-track (bicycle) steering angle, radians, positive left.
  double steer_rad = 0.0;
  /// Requested longitudinal acceleration, m/s^2 (negative brakes).
  double accel_mps2 = 0.0;
  /// 1 once the driver has finished and wants the car held still, else 0.
  int32_t hold_stopped = 0;
};

/// The vehicle's motion by the autonomy's own estimate, for de-skewing a sweep or predicting
/// tracks: constant forward speed and yaw rate.
struct Motion {
  double speed_mps = 0.0;
  double yaw_rate_rps = 0.0;
};

/// One LiDAR return in the sensor frame.
struct LidarPoint {
  float x_m = 0.f;
  float y_m = 0.f;
  float z_m = 0.f;
  /// Calibrated reflectivity-like intensity, 0-255.
  float intensity = 0.f;
  /// Laser channel, 0 = lowest elevation.
  uint16_t ring = 0;
  uint16_t reserved = 0;
  /// Time of the return after the sweep's start, seconds.
  float time_offset_s = 0.f;
};

/// One sweep of a spinning LiDAR (points in the sensor frame, as fired: with motion distortion).
struct LidarSweep {
  /// Time of the sweep's first column.
  TimeUs stamp_us = 0;
  /// Time of its last column: cones a perception returns are expected in the vehicle frame here.
  TimeUs end_us = 0;
  Span<LidarPoint> points;
  /// The sensor's pose in the vehicle frame.
  Pose3 sensor_in_vehicle;
};

/// Intrinsics of a rectified camera, pixels, with its lens distortion.
struct CameraIntrinsics {
  int32_t width_px = 0;
  int32_t height_px = 0;
  double fx = 0.0;
  double fy = 0.0;
  double cx = 0.0;
  double cy = 0.0;
  /// OpenCV's lens model (k1, k2, p1, p2, k3), as cv::undistortPoints and
  /// cv::initUndistortRectifyMap take it: the images are drawn through it. All zero for a
  /// pinhole camera (`sensors.realism: off`). Added in ABI 3.
  double distortion[5] = {0.0, 0.0, 0.0, 0.0, 0.0};
};

/// An 8-bit RGB image, rows top to bottom, 3 bytes per pixel, no padding.
struct RgbImage {
  int32_t width_px = 0;
  int32_t height_px = 0;
  const uint8_t* rgb = nullptr;
};

/// A rectified stereo pair with its exact calibration. Camera frames are optical: x right,
/// y down, z forward.
struct StereoFrame {
  TimeUs stamp_us = 0;
  RgbImage left;
  RgbImage right;
  CameraIntrinsics intrinsics;
  /// Left and right camera poses in the vehicle frame.
  Pose3 left_in_vehicle;
  Pose3 right_in_vehicle;
  /// Distance between the optical centres, metres.
  double baseline_m = 0.0;
};

/// An IMU sample in the IMU frame (aligned with the vehicle frame).
struct ImuSample {
  TimeUs stamp_us = 0;
  /// Angular rate, rad/s (x, y, z).
  double gyro_rps[3] = {0.0, 0.0, 0.0};
  /// Specific force, m/s^2 (x, y, z): +9.81 on z at rest.
  double accel_mps2[3] = {0.0, 0.0, 0.0};
};

/// Wheel speeds from the encoders, rad/s, order front left, front right, rear left, rear right.
struct WheelSpeeds {
  TimeUs stamp_us = 0;
  double omega_rps[4] = {0.0, 0.0, 0.0, 0.0};
};

/// The steering angle sensor: the single-track equivalent angle, radians, positive left.
struct SteeringSample {
  TimeUs stamp_us = 0;
  double steer_rad = 0.0;
};

/// A GNSS fix in the track frame (a local tangent plane).
struct GnssFix {
  TimeUs stamp_us = 0;
  double x_m = 0.0;
  double y_m = 0.0;
  double vx_mps = 0.0;
  double vy_mps = 0.0;
  /// One-sigma horizontal accuracy the receiver reports, metres.
  double sigma_m = 0.0;
};

/// The vehicle's motion between two cone frames, as conesim's odometry (wheel speeds, gyro and
/// steering, fused) estimates it.
struct OdometryDelta {
  /// Stamps of the start and the end of the interval.
  TimeUs from_us = 0;
  TimeUs to_us = 0;
  /// Pose at `to_us` in the vehicle frame at `from_us`.
  Pose2 delta;
  /// Covariance of (x, y, yaw) of the delta, row-major 3x3, m^2 and rad^2.
  double covariance[9] = {1e-4, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, 1e-4};
  /// Distance driven over the interval (arc length), metres.
  double distance_m = 0.0;
  /// Forward speed and yaw rate at `to_us`.
  double speed_mps = 0.0;
  double yaw_rate_rps = 0.0;
};

/// One step of a Slam's input: the motion since the previous frame and the cones seen at its
/// end (observations in the vehicle frame at odometry.to_us).
struct SlamInput {
  OdometryDelta odometry;
  ConeFrame observations;
};

/// The FSG events.
enum class Event : int32_t { kSkidpad = 0, kAcceleration = 1, kAutocross = 2, kTrackdrive = 3 };

/// What the car can do over speed at its full measured grip (a point-mass model with
/// downforce, drag and power): a driver plans its speed from it.
struct PerformanceEnvelope {
  double mass_kg = 0.0;
  /// Friction the tyres give on this car.
  double friction = 0.0;
  /// Downforce and drag per speed squared, N s^2/m^2.
  double downforce_n_per_v2 = 0.0;
  double drag_n_per_v2 = 0.0;
  /// Rolling resistance, N.
  double rolling_n = 0.0;
  /// Drive force at low speed, N; power at the wheels, W; braking force, N.
  double max_drive_force_n = 0.0;
  double max_power_w = 0.0;
  double max_brake_force_n = 0.0;
};

/// A yaw gain table entry: at this single-track steering angle the car turns with this share
/// of the kinematic yaw rate v tan(angle) / wheelbase (anti-Ackermann cars turn wider).
struct YawGain {
  double steer_rad = 0.0;
  double gain = 1.0;
};

/// What the car knows of itself.
struct Vehicle {
  double wheelbase_m = 0.0;
  double max_steer_rad = 0.0;
  /// How fast the steering turns, rad/s.
  double max_steer_rate_rps = 0.0;
  /// From the rear axle forward to the front wing, and back to the rear end, metres.
  double rear_axle_to_front_m = 0.0;
  double rear_axle_to_back_m = 0.0;
  double width_m = 0.0;
  double wheel_radius_m = 0.0;
  PerformanceEnvelope envelope;
  /// Yaw gain over steering angle, angles rising.
  Span<YawGain> yaw_gain;
};

/// One key of a plug-in's YAML block, flattened: "gain", "lookahead.min_m", "list.0".
struct ConfigEntry {
  const char* key = nullptr;
  /// The scalar as written in the YAML file.
  const char* value = nullptr;
};

}  // namespace conesim::sdk
