#pragma once
// Conversions between conesim's core types and the SDK's plain structs, exact in every number:
// the built-in stack run through the SDK's interfaces gives the same metrics to the bit. Used by
// the run loop (sim/autonomy.cpp) and by the reference driver plug-in (reference_driver_plugin).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <iterator>
#include <utility>
#include <vector>

#include "conesim/sdk/types.hpp"
#include "core/autonomy_types.hpp"
#include "core/measurements.hpp"

namespace conesim::sdk_bridge {

/// A covariance into the SDK's row-major form (both off-diagonal entries kept).
inline sdk::Covariance2 to_sdk(const Eigen::Matrix2d& m) {
  return {m(0, 0), m(0, 1), m(1, 0), m(1, 1)};
}

/// A covariance from the SDK's form.
inline Eigen::Matrix2d from_sdk(const sdk::Covariance2& c) {
  Eigen::Matrix2d m;
  m << c.xx, c.xy, c.yx, c.yy;
  return m;
}

/// A planar pose into the SDK's type.
inline sdk::Pose2 to_sdk(const core::Pose2& p) {
  return {p.x, p.y, p.yaw};
}

/// A planar pose from the SDK's type.
inline core::Pose2 from_sdk(const sdk::Pose2& p) {
  return {p.x_m, p.y_m, p.yaw_rad};
}

/// A cone class into the SDK's enumeration.
inline sdk::ConeClass to_sdk(core::ConeClass c) {
  switch (c) {
    case core::ConeClass::kBlue:
      return sdk::ConeClass::kBlue;
    case core::ConeClass::kYellow:
      return sdk::ConeClass::kYellow;
    case core::ConeClass::kOrangeSmall:
      return sdk::ConeClass::kOrangeSmall;
    case core::ConeClass::kOrangeBig:
      return sdk::ConeClass::kOrangeBig;
    case core::ConeClass::kUnknown:
      break;
  }
  return sdk::ConeClass::kUnknown;
}

/// A cone class from the SDK's enumeration (a value outside it reads as unknown).
inline core::ConeClass from_sdk(sdk::ConeClass c) {
  switch (c) {
    case sdk::ConeClass::kBlue:
      return core::ConeClass::kBlue;
    case sdk::ConeClass::kYellow:
      return core::ConeClass::kYellow;
    case sdk::ConeClass::kOrangeSmall:
      return core::ConeClass::kOrangeSmall;
    case sdk::ConeClass::kOrangeBig:
      return core::ConeClass::kOrangeBig;
    case sdk::ConeClass::kUnknown:
      break;
  }
  // a value outside the enumeration reads as unknown
  return core::ConeClass::kUnknown;
}

/// A frame of cones into `buffer`; the returned view points into it.
inline sdk::ConeFrame to_sdk(const core::ConeObservations& frame,
                             std::vector<sdk::ConeObservation>& buffer) {
  buffer.clear();
  for (const core::ConeObservation& o : frame.cones)
    buffer.push_back(
        {o.position.x(), o.position.y(), to_sdk(o.cls), o.track_id, to_sdk(o.covariance)});
  return {frame.stamp, {buffer.data(), buffer.size()}};
}

/// A frame of cones from the SDK's view (copied).
inline core::ConeObservations from_sdk(const sdk::ConeFrame& frame) {
  core::ConeObservations out;
  out.stamp = frame.stamp_us;
  out.cones.reserve(frame.cones.size);
  for (const sdk::ConeObservation& o : frame.cones) {
    core::ConeObservation c;
    c.position = {o.x_m, o.y_m};
    c.cls = from_sdk(o.cls);
    c.covariance = from_sdk(o.covariance);
    c.track_id = o.track_id;
    out.cones.push_back(c);
  }
  return out;
}

/// A map cone into the SDK's type.
inline sdk::MapCone to_sdk(const core::MapCone& c) {
  return {c.id, to_sdk(c.cls), c.position.x(), c.position.y(), to_sdk(c.covariance)};
}

/// A map cone from the SDK's type.
inline core::MapCone from_sdk(const sdk::MapCone& c) {
  return {c.id, from_sdk(c.cls), {c.x_m, c.y_m}, from_sdk(c.covariance)};
}

/// An estimate whose map view points into `buffer`.
inline sdk::Estimate to_sdk(const core::Estimate& e, std::vector<sdk::MapCone>& buffer) {
  buffer.clear();
  for (const core::MapCone& c : e.map) buffer.push_back(to_sdk(c));
  sdk::Estimate out;
  out.stamp_us = e.stamp;
  out.pose = to_sdk(e.pose);
  out.speed_mps = e.speed_mps;
  out.yaw_rate_rps = e.yaw_rate_rps;
  out.map = {buffer.data(), buffer.size()};
  out.phase = e.phase == core::SlamPhase::kLocalisation ? sdk::SlamPhase::kLocalisation
                                                        : sdk::SlamPhase::kMapping;
  out.map_complete = e.map_complete ? 1 : 0;
  return out;
}

/// An estimate from the SDK's view (the map copied).
inline core::Estimate from_sdk(const sdk::Estimate& e) {
  core::Estimate out;
  out.stamp = e.stamp_us;
  out.pose = from_sdk(e.pose);
  out.speed_mps = e.speed_mps;
  out.yaw_rate_rps = e.yaw_rate_rps;
  out.map.reserve(e.map.size);
  for (const sdk::MapCone& c : e.map) out.map.push_back(from_sdk(c));
  out.phase = e.phase == sdk::SlamPhase::kLocalisation ? core::SlamPhase::kLocalisation
                                                       : core::SlamPhase::kMapping;
  out.map_complete = e.map_complete != 0;
  return out;
}

/// A 3D pose (position, unit quaternion) into the SDK's type.
inline sdk::Pose3 to_sdk(const core::Pose3& p) {
  const Eigen::Quaterniond& q = p.orientation;
  return {{p.position.x(), p.position.y(), p.position.z()}, {q.w(), q.x(), q.y(), q.z()}};
}

/// A 3D pose from the SDK's type.
inline core::Pose3 from_sdk(const sdk::Pose3& p) {
  core::Pose3 out;
  out.position = {p.position_m.x, p.position_m.y, p.position_m.z};
  out.orientation =
      Eigen::Quaterniond(p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z);
  return out;
}

/// A LiDAR sweep's points into `buffer` (the same numbers: floats stay floats).
inline sdk::Span<sdk::LidarPoint> to_sdk(const core::PointCloud& cloud,
                                         std::vector<sdk::LidarPoint>& buffer) {
  buffer.clear();
  buffer.reserve(cloud.points.size());
  for (const core::LidarPoint& p : cloud.points)
    buffer.push_back({p.x, p.y, p.z, p.intensity, p.ring, 0, p.time_offset_s});
  return {buffer.data(), buffer.size()};
}

/// A LiDAR sweep's points back into the simulator's type (copied; floats stay floats).
inline core::PointCloud from_sdk(const sdk::LidarSweep& sweep) {
  core::PointCloud out;
  out.stamp = sweep.stamp_us;
  out.points.reserve(sweep.points.size);
  for (const sdk::LidarPoint& p : sweep.points)
    out.points.push_back({p.x_m, p.y_m, p.z_m, p.intensity, p.ring, p.time_offset_s});
  return out;
}

/// A stereo pair as the SDK's view: the images point into `frame`.
inline sdk::StereoFrame to_sdk(const core::StereoFrame& f) {
  sdk::StereoFrame out;
  out.stamp_us = f.stamp;
  out.left = {f.left.width_px, f.left.height_px, f.left.rgb.data()};
  out.right = {f.right.width_px, f.right.height_px, f.right.rgb.data()};
  const core::CameraIntrinsics& k = f.intrinsics;
  out.intrinsics = {k.width_px, k.height_px, k.fx, k.fy, k.cx, k.cy, {}};
  std::copy(k.distortion.begin(), k.distortion.end(), out.intrinsics.distortion);
  out.left_in_vehicle = to_sdk(f.left_in_vehicle);
  out.right_in_vehicle = to_sdk(f.right_in_vehicle);
  out.baseline_m = f.baseline_m;
  return out;
}

/// A stereo pair from the SDK's view (the images copied).
inline core::StereoFrame from_sdk(const sdk::StereoFrame& f) {
  core::StereoFrame out;
  out.stamp = f.stamp_us;
  for (auto [from, to] : {std::pair{&f.left, &out.left}, {&f.right, &out.right}}) {
    to->width_px = from->width_px;
    to->height_px = from->height_px;
    to->rgb.assign(from->rgb, from->rgb + 3 * static_cast<size_t>(from->width_px) *
                                              static_cast<size_t>(from->height_px));
  }
  const sdk::CameraIntrinsics& k = f.intrinsics;
  out.intrinsics = {k.width_px, k.height_px, k.fx, k.fy, k.cx, k.cy, {}};
  std::copy(std::begin(k.distortion), std::end(k.distortion), out.intrinsics.distortion.begin());
  out.left_in_vehicle = from_sdk(f.left_in_vehicle);
  out.right_in_vehicle = from_sdk(f.right_in_vehicle);
  out.baseline_m = f.baseline_m;
  return out;
}

/// An IMU sample into the SDK's type.
inline sdk::ImuSample to_sdk(const core::ImuSample& s) {
  return {s.stamp,
          {s.gyro_rps.x(), s.gyro_rps.y(), s.gyro_rps.z()},
          {s.accel_mps2.x(), s.accel_mps2.y(), s.accel_mps2.z()}};
}

/// Wheel speeds into the SDK's type.
inline sdk::WheelSpeeds to_sdk(const core::WheelSpeeds& w) {
  return {w.stamp, {w.omega_rps[0], w.omega_rps[1], w.omega_rps[2], w.omega_rps[3]}};
}

/// A steering sample into the SDK's type.
inline sdk::SteeringSample to_sdk(const core::SteeringSample& s) {
  return {s.stamp, s.steer_rad};
}

/// A command from the SDK's type.
inline core::VehicleCommand from_sdk(const sdk::Command& c) {
  return {c.steer_rad, c.accel_mps2, c.hold_stopped != 0};
}

}  // namespace conesim::sdk_bridge
