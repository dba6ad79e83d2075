#include "vehicle_models/steering.hpp"

#include <cmath>
#include <limits>
#include <numbers>

#include "vehicle_models/vehicle_params.hpp"

namespace conesim::vehicle_models {

WheelAngles split_steering(double delta_rad, double wheelbase_m, double track_m,
                           double ackermann_factor) {
  const double mag = std::abs(delta_rad);
  if (mag < 1e-9) return {0.0, 0.0};

  // ideal Ackermann angles of the inner and outer wheel around the rear-axle turn centre
  const double radius = wheelbase_m / std::tan(mag);
  const double inner_ideal = std::atan(wheelbase_m / (radius - 0.5 * track_m));
  const double outer_ideal = std::atan(wheelbase_m / (radius + 0.5 * track_m));
  // a radius inside the half track makes the inner ideal angle wrap past 90 degrees
  const double inner_ackermann = radius > 0.5 * track_m ? inner_ideal : 0.5 * std::numbers::pi;

  // blend between parallel steer and the ideal by the Ackermann factor
  const double inner = mag + ackermann_factor * (inner_ackermann - mag);
  const double outer = mag + ackermann_factor * (outer_ideal - mag);
  const double sign = delta_rad > 0.0 ? 1.0 : -1.0;
  // turning left (delta > 0): the left wheel is the inner one
  if (sign > 0.0) return {inner, outer};
  return {-outer, -inner};
}

WheelAngles split_steering(double delta_rad, const VehicleParams& params) {
  return split_steering(delta_rad, params.wheelbase_m, params.track_m, params.ackermann_factor);
}

double turn_radius_m(double delta_rad, double wheelbase_m) {
  const double t = std::tan(std::abs(delta_rad));
  if (t < 1e-12) return std::numeric_limits<double>::infinity();
  return wheelbase_m / t;
}

}  // namespace conesim::vehicle_models
