#include "vehicle_models/vehicle_params.hpp"

#include <cmath>
#include <sstream>

#include "core/validate.hpp"

namespace conesim::vehicle_models {

namespace {

std::string check_range(const char* key, double v, double lo, double hi) {
  return core::check_range(std::string(key), v, lo, hi);
}

}  // namespace

std::string VehicleParams::validate() const {
  const std::pair<const char*, std::string> checks[] = {
      {"mass_kg", check_range("mass_kg", mass_kg, 50, 2000)},
      {"wheelbase_m", check_range("wheelbase_m", wheelbase_m, 0.5, 5)},
      {"front_mass_fraction", check_range("front_mass_fraction", front_mass_fraction, 0.2, 0.8)},
      {"track_m", check_range("track_m", track_m, 0.5, 3)},
      {"cog_height_m", check_range("cog_height_m", cog_height_m, 0.1, 1.5)},
      {"yaw_inertia_kgm2", check_range("yaw_inertia_kgm2", yaw_inertia_kgm2, 1, 5000)},
      {"wheel_radius_m", check_range("wheel_radius_m", wheel_radius_m, 0.1, 0.6)},
      {"wheel_width_m", check_range("wheel_width_m", wheel_width_m, 0.05, 0.5)},
      {"wheel_mass_kg", check_range("wheel_mass_kg", wheel_mass_kg, 0.5, 50)},
      {"length_m", check_range("length_m", length_m, wheelbase_m, 10)},
      {"width_m", check_range("width_m", width_m, track_m, 5)},
      {"front_overhang_from_rear_axle_m",
       check_range("front_overhang_from_rear_axle_m", front_overhang_from_rear_axle_m, wheelbase_m,
                   length_m)},
      {"max_steer_rad", check_range("max_steer_rad", max_steer_rad, 0.05, 1.0)},
      {"max_steer_rate_rps", check_range("max_steer_rate_rps", max_steer_rate_rps, 0.1, 50)},
      {"ackermann_factor", check_range("ackermann_factor", ackermann_factor, -2, 2)},
      {"max_torque_front_nm", check_range("max_torque_front_nm", max_torque_front_nm, 0, 5000)},
      {"max_torque_rear_nm", check_range("max_torque_rear_nm", max_torque_rear_nm, 0, 5000)},
      {"max_power_w", check_range("max_power_w", max_power_w, 1000, 1e6)},
      {"max_brake_torque_nm", check_range("max_brake_torque_nm", max_brake_torque_nm, 10, 1e4)},
      {"motor_rotor_inertia_kgm2",
       check_range("motor_rotor_inertia_kgm2", motor_rotor_inertia_kgm2, 0, 10)},
      {"slip_target", check_range("slip_target", slip_target, 0.01, 0.5)},
      {"tyre_friction", check_range("tyre_friction", tyre_friction, 0.1, 3)},
      {"rolling_resistance", check_range("rolling_resistance", rolling_resistance, 0, 0.2)},
      {"drag_area_m2", check_range("drag_area_m2", drag_area_m2, 0, 5)},
      {"lift_area_m2", check_range("lift_area_m2", lift_area_m2, 0, 10)},
      {"air_density_kgm3", check_range("air_density_kgm3", air_density_kgm3, 0.5, 2)},
      {"spring_n_per_m", check_range("spring_n_per_m", spring_n_per_m, 1000, 1e6)},
      {"damper_ns_per_m", check_range("damper_ns_per_m", damper_ns_per_m, 10, 1e5)},
      {"suspension_travel_m", check_range("suspension_travel_m", suspension_travel_m, 0.005, 0.3)},
  };
  for (const auto& [key, error] : checks)
    if (!error.empty()) return error;
  if (max_torque_front_nm + max_torque_rear_nm <= 0.0)
    return "max_torque_front_nm: expected some drive torque on at least one axle";
  return {};
}

}  // namespace conesim::vehicle_models
