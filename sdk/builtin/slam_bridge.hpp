#pragma once
// Conversions between the SLAM back-ends' odometry and the SDK's, exact in every number: a
// built-in back-end run as a plug-in (graph_slam_plugin.cpp) gets what it gets built in.

#include "sdk/builtin/bridge.hpp"
#include "slam/backend.hpp"

namespace conesim::sdk_bridge {

/// The odometry between two frames into the SDK's type (the covariance row-major).
inline sdk::OdometryDelta to_sdk(const slam::OdometryDelta& o) {
  sdk::OdometryDelta out;
  out.from_us = o.from;
  out.to_us = o.to;
  out.delta = to_sdk(o.delta);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) out.covariance[3 * r + c] = o.covariance(r, c);
  out.distance_m = o.distance_m;
  out.speed_mps = o.speed_mps;
  out.yaw_rate_rps = o.yaw_rate_rps;
  return out;
}

/// The odometry between two frames from the SDK's type.
inline slam::OdometryDelta from_sdk(const sdk::OdometryDelta& o) {
  slam::OdometryDelta out;
  out.from = o.from_us;
  out.to = o.to_us;
  out.delta = from_sdk(o.delta);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) out.covariance(r, c) = o.covariance[3 * r + c];
  out.distance_m = o.distance_m;
  out.speed_mps = o.speed_mps;
  out.yaw_rate_rps = o.yaw_rate_rps;
  return out;
}

}  // namespace conesim::sdk_bridge
