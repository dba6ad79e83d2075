#pragma once
// Steering geometry: how one single-track steering angle becomes two front wheel angles.

namespace conesim::vehicle_models {

struct VehicleParams;

/// Front wheel angles for one single-track command, radians, positive to the left.
struct WheelAngles {
  double left_rad = 0.0;
  double right_rad = 0.0;
};

/// Splits a single-track (bicycle) angle delta into wheel angles with the Ackermann factor A:
/// with R = L / tan|delta| the turn radius at the rear axle, the ideal Ackermann angles are
/// atan(L / (R -+ t/2)) for the inner and outer wheel, and each wheel gets
/// |delta| + A (ideal - |delta|). A = 1 is full Ackermann, 0 parallel, negative anti-Ackermann
/// (the outer wheel steers more than the inner one).
WheelAngles split_steering(double delta_rad, double wheelbase_m, double track_m,
                           double ackermann_factor);

/// The same with the car's parameters.
WheelAngles split_steering(double delta_rad, const VehicleParams& params);

/// Turn radius of the rear axle centre for a single-track angle, metres (infinite when straight).
double turn_radius_m(double delta_rad, double wheelbase_m);

}  // namespace conesim::vehicle_models
