// conesim's reference driver (control::Driver) built as a plug-in: the same driver the run loop
// makes built in, loaded through the SDK's entry point and interfaces. A run with
// `autonomy.driver: {plugin: .../libconesim_reference_driver.so, config: <the driver: keys>}`
// gives the metrics of the built-in run to the bit (tests/app/sdk_test.sh).
//
// config: the keys of the scenario's driver: block (docs/architecture.md); trackdrive_laps
// comes from the run.

#include <conesim/sdk.hpp>
#include <memory>
#include <string>
#include <vector>

#include "control/driver.hpp"
#include "sdk/builtin/bridge.hpp"

namespace {

using namespace conesim;

using sdk_bridge::from_sdk;

control::DriverParams read_params(const sdk::RunInfo& run, const sdk::Config& config) {
  static const char* const kKnown[] = {
      "explore_speed_mps",   "fast_speed_mps",   "acceleration_speed_mps",
      "skidpad_speed_mps",   "grip_fraction",    "max_lateral_accel_mps2",
      "max_accel_mps2",      "max_decel_mps2",   "footprint_margin_m",
      "tight_turn_margin_m", "check_drivable",   "lookahead_min_m",
      "lookahead_gain_s",    "trackdrive_laps",  "assumed_half_width_m",
      "launch_accel_mps2",   "speed_gain_per_s", nullptr};
  config.require_known(kKnown);
  control::DriverParams p;
  p.explore_speed_mps = config.number("explore_speed_mps", p.explore_speed_mps);
  p.fast_speed_mps = config.number("fast_speed_mps", p.fast_speed_mps);
  p.acceleration_speed_mps = config.number("acceleration_speed_mps", p.acceleration_speed_mps);
  p.skidpad_speed_mps = config.number("skidpad_speed_mps", p.skidpad_speed_mps);
  p.grip_fraction = config.number("grip_fraction", p.grip_fraction);
  p.max_lateral_accel_mps2 = config.number("max_lateral_accel_mps2", p.max_lateral_accel_mps2);
  p.max_accel_mps2 = config.number("max_accel_mps2", p.max_accel_mps2);
  p.max_decel_mps2 = config.number("max_decel_mps2", p.max_decel_mps2);
  p.footprint_margin_m = config.number("footprint_margin_m", p.footprint_margin_m);
  p.tight_turn_margin_m = config.number("tight_turn_margin_m", p.tight_turn_margin_m);
  p.check_drivable = config.boolean("check_drivable", p.check_drivable);
  p.lookahead_min_m = config.number("lookahead_min_m", p.lookahead_min_m);
  p.lookahead_gain_s = config.number("lookahead_gain_s", p.lookahead_gain_s);
  p.assumed_half_width_m = config.number("assumed_half_width_m", p.assumed_half_width_m);
  p.launch_accel_mps2 = config.number("launch_accel_mps2", p.launch_accel_mps2);
  p.speed_gain_per_s = config.number("speed_gain_per_s", p.speed_gain_per_s);
  p.trackdrive_laps = run.trackdrive_laps;
  if (const std::string e = p.validate(); !e.empty()) throw std::invalid_argument(e);
  return p;
}

control::VehicleGeometry geometry(const sdk::Vehicle& v) {
  control::VehicleGeometry g;
  g.wheelbase_m = v.wheelbase_m;
  g.max_steer_rad = v.max_steer_rad;
  g.max_steer_rate_rps = v.max_steer_rate_rps;
  g.rear_axle_to_front_m = v.rear_axle_to_front_m;
  g.rear_axle_to_back_m = v.rear_axle_to_back_m;
  g.width_m = v.width_m;
  g.yaw_gain.clear();
  for (const sdk::YawGain& y : v.yaw_gain) g.yaw_gain.push_back({y.steer_rad, y.gain});
  const sdk::PerformanceEnvelope& e = v.envelope;
  g.envelope = {e.mass_kg,   e.friction,          e.downforce_n_per_v2, e.drag_n_per_v2,
                e.rolling_n, e.max_drive_force_n, e.max_power_w,        e.max_brake_force_n};
  return g;
}

std::vector<core::MapCone> prior_map(const sdk::RunInfo& run) {
  std::vector<core::MapCone> map;
  for (const sdk::MapCone& c : run.prior_map) map.push_back(from_sdk(c));
  return map;
}

class ReferenceDriverPlugin final : public sdk::Driver {
 public:
  ReferenceDriverPlugin(const sdk::RunInfo& run, const sdk::Config& config)
      : driver_(static_cast<core::EventType>(run.event), read_params(run, config),
                geometry(run.vehicle), prior_map(run)) {}

  sdk::Command update(const sdk::DriverInput& in) override {
    const core::VehicleCommand c =
        driver_.update({from_sdk(in.estimate), from_sdk(in.observations)});
    return {c.steer_rad, c.accel_mps2, c.hold_stopped ? 1 : 0};
  }

  sdk::DriverStatus status() const override {
    const control::DriverStatus& s = driver_.status();
    return {s.laps_counted, s.finished ? 1 : 0, s.state.c_str(), s.problem.c_str()};
  }

 private:
  control::Driver driver_;
};

}  // namespace

CONESIM_PLUGIN_DRIVER("reference", ReferenceDriverPlugin)
