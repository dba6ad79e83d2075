#pragma once
// Kinematic motion models shared with SLAM: unicycle and kinematic bicycle.

#include "core/geometry.hpp"

namespace conesim::vehicle_models {

/// Unicycle: moves the pose by speed v and yaw rate w for dt seconds (exact arc integration).
core::Pose2 unicycle_step(const core::Pose2& pose, double speed_mps, double yaw_rate_rps,
                          double dt_s);

/// Kinematic bicycle about the rear axle: yaw rate v tan(delta) / L, delta being the
/// single-track equivalent angle (for an anti-Ackermann car: the commanded single-track angle).
core::Pose2 bicycle_step(const core::Pose2& pose, double speed_mps, double steer_rad,
                         double wheelbase_m, double dt_s);

/// The yaw rate of the kinematic bicycle.
double bicycle_yaw_rate(double speed_mps, double steer_rad, double wheelbase_m);

}  // namespace conesim::vehicle_models
