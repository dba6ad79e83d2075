#include <cmath>
#include <sstream>

#include "control/driver.hpp"

namespace conesim::control {

std::string DriverParams::validate() const {
  const std::pair<const char*, double> positive[] = {
      {"explore_speed_mps", explore_speed_mps},
      {"fast_speed_mps", fast_speed_mps},
      {"acceleration_speed_mps", acceleration_speed_mps},
      {"skidpad_speed_mps", skidpad_speed_mps},
      {"max_lateral_accel_mps2", max_lateral_accel_mps2},
      {"max_accel_mps2", max_accel_mps2},
      {"max_decel_mps2", max_decel_mps2},
      {"lookahead_min_m", lookahead_min_m},
      {"lookahead_gain_s", lookahead_gain_s},
      {"assumed_half_width_m", assumed_half_width_m},
      {"launch_accel_mps2", launch_accel_mps2},
      {"speed_gain_per_s", speed_gain_per_s},
      {"grip_fraction", grip_fraction},
      {"explore_grip_fraction", explore_grip_fraction},
  };
  for (const auto& [key, value] : positive) {
    if (!std::isfinite(value) || value <= 0.0 || value > 1000.0) {
      std::ostringstream s;
      s << key << ": expected a positive number below 1000, got " << value;
      return s.str();
    }
  }
  if (grip_fraction > 1.0)
    return "grip_fraction: expected a share of the measured grip in (0, 1], got " +
           std::to_string(grip_fraction);
  if (explore_grip_fraction > 1.0)
    return "explore_grip_fraction: expected a share of the measured grip in (0, 1], got " +
           std::to_string(explore_grip_fraction);
  if (!std::isfinite(footprint_margin_m) || footprint_margin_m < 0.0 || footprint_margin_m > 2.0)
    return "footprint_margin_m: expected metres from 0 to 2, got " +
           std::to_string(footprint_margin_m);
  if (!std::isfinite(tight_turn_margin_m) || tight_turn_margin_m < 0.0 || tight_turn_margin_m > 2.0)
    return "tight_turn_margin_m: expected metres from 0 to 2, got " +
           std::to_string(tight_turn_margin_m);
  if (trackdrive_laps < 1 || trackdrive_laps > 100)
    return "trackdrive_laps: expected a lap count from 1 to 100, got " +
           std::to_string(trackdrive_laps);
  return {};
}

}  // namespace conesim::control
