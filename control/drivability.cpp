#include "control/drivability.hpp"

#include <cmath>
#include <cstdio>

#include "control/pure_pursuit.hpp"
#include "control/racing_line.hpp"

namespace conesim::control {

namespace {

// spacing of the reference line the check plans on, metres
constexpr double kSpacingM = 1.0;
// clearance the widest line keeps from the cones (just clear: the check asks what is possible,
// not what the driver plans), metres
constexpr double kJustClearM = 0.02;
// a footprint this far into a cone on the widest line is a refusal, metres
constexpr double kMaxOverlapM = 0.05;
// the line's curvature is measured on chords this many points either side (2 m chords on a
// 1 m line would read the corner of a polyline as a tighter turn than the car drives)
constexpr int kCurvatureStride = 3;

}  // namespace

double full_lock_radius_m(const VehicleGeometry& vehicle) {
  return vehicle.wheelbase_m / std::tan(vehicle.max_steer_rad) /
         yaw_gain_at(vehicle.yaw_gain, vehicle.max_steer_rad);
}

Drivability check_drivability(const std::vector<Vec2>& left, const std::vector<Vec2>& right,
                              const std::vector<Vec2>& centre, bool closed,
                              const std::vector<core::MapCone>& cones,
                              const VehicleGeometry& vehicle, const DrivabilityLimits& limits) {
  Drivability d;
  if (centre.size() < 5 || left.empty() || right.empty()) return d;  // nothing to judge

  // the narrowest place against the car's width plus a small cone's base
  const double need_m = vehicle.width_m + core::cone_size(core::ConeClass::kBlue).base_m +
                        2.0 * limits.tracking_tolerance_m;
  const Footprint just_clear{vehicle.rear_axle_to_front_m, vehicle.rear_axle_to_back_m,
                             0.5 * vehicle.width_m, kJustClearM};
  const RacingLine line =
      plan_racing_line(centre, closed, left, right, cones, just_clear, 3, kSpacingM);
  d.min_width_m = line.min_width_m;
  if (line.min_width_m < need_m) {
    char buf[160];
    std::snprintf(buf, sizeof(buf), "lanes %.2f m apart at %s, the car needs %.2f m",
                  line.min_width_m, core::format_place(line.min_width_at).c_str(), need_m);
    d.drivable = false;
    d.reason = buf;
    d.where = line.min_width_at;
    return d;
  }

  // the tightest turn of the widest line against the car's turning circle
  const std::vector<double> k = curvatures(line.path.points, closed, kCurvatureStride);
  double k_max = 0.0;
  Vec2 k_at = Vec2::Zero();
  for (size_t i = 0; i < k.size(); ++i)
    if (std::abs(k[i]) > k_max) k_max = std::abs(k[i]), k_at = line.path.points[i];
  d.min_line_radius_m = k_max > 0.0 ? 1.0 / k_max : 1e9;
  const double r_car =
      limits.min_turn_radius_m > 0.0 ? limits.min_turn_radius_m : full_lock_radius_m(vehicle);
  if (d.min_line_radius_m < limits.radius_share * r_car) {
    char buf[200];
    std::snprintf(buf, sizeof(buf),
                  "a turn of %.1f m radius at %s even on the widest line through the cones, the "
                  "car turns no tighter than %.1f m",
                  d.min_line_radius_m, core::format_place(k_at).c_str(), r_car);
    d.drivable = false;
    d.reason = buf;
    d.where = k_at;
    return d;
  }

  // the footprint must clear the cones somewhere along the widest line
  if (line.min_clearance_m < -kMaxOverlapM) {
    d.drivable = false;
    d.reason = "the car cannot pass the cone at " + core::format_place(line.min_clearance_at) +
               " without touching it on any line";
    d.where = line.min_clearance_at;
  }
  return d;
}

}  // namespace conesim::control
