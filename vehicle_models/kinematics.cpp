#include "vehicle_models/kinematics.hpp"

#include <cmath>

namespace conesim::vehicle_models {

core::Pose2 unicycle_step(const core::Pose2& pose, double speed_mps, double yaw_rate_rps,
                          double dt_s) {
  const double dyaw = yaw_rate_rps * dt_s;
  const double ds = speed_mps * dt_s;
  // chord of the arc: straight-line limit when the yaw change is tiny
  double fx, fy;
  if (std::abs(dyaw) < 1e-9) {
    fx = ds;
    fy = 0.0;
  } else {
    const double r = ds / dyaw;
    fx = r * std::sin(dyaw);
    fy = r * (1.0 - std::cos(dyaw));
  }
  core::Pose2 next = pose.compose({fx, fy, dyaw});
  return next;
}

double bicycle_yaw_rate(double speed_mps, double steer_rad, double wheelbase_m) {
  return speed_mps * std::tan(steer_rad) / wheelbase_m;
}

core::Pose2 bicycle_step(const core::Pose2& pose, double speed_mps, double steer_rad,
                         double wheelbase_m, double dt_s) {
  return unicycle_step(pose, speed_mps, bicycle_yaw_rate(speed_mps, steer_rad, wheelbase_m), dt_s);
}

}  // namespace conesim::vehicle_models
