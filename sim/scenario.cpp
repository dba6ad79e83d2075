#include "sim/scenario.hpp"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <sstream>

#include "core/error.hpp"
#include "sensors/lidar_config.hpp"

namespace conesim::sim {

namespace fs = std::filesystem;
using core::InputError;

namespace {

// a key of a section and how to store its value
struct Field {
  std::string key;
  std::function<void(const YAML::Node&)> read;
};

// context for error messages: the file and the dotted path of the section
struct Where {
  std::string file;
  std::string section;

  std::string key(const std::string& k) const { return section.empty() ? k : section + "." + k; }
  int line(const YAML::Node& n) const { return n.Mark().is_null() ? 0 : n.Mark().line + 1; }
};

double read_number(const YAML::Node& n, const Where& w, const std::string& key) {
  double v = 0.0;
  try {
    v = n.as<double>();
  } catch (const YAML::Exception&) {
    throw InputError(w.file, w.line(n), w.key(key) + ": expected a number, got '" +
                                            (n.IsScalar() ? n.Scalar() : "a list or map") + "'");
  }
  if (!std::isfinite(v))
    throw InputError(w.file, w.line(n), w.key(key) + ": expected a finite number");
  return v;
}

int64_t read_integer(const YAML::Node& n, const Where& w, const std::string& key) {
  const double v = read_number(n, w, key);
  if (v != std::floor(v) || std::abs(v) > 9.0e15)
    throw InputError(w.file, w.line(n), w.key(key) + ": expected a whole number");
  return static_cast<int64_t>(v);
}

std::string read_string(const YAML::Node& n, const Where& w, const std::string& key) {
  if (!n.IsScalar())
    throw InputError(w.file, w.line(n), w.key(key) + ": expected a text value");
  return n.Scalar();
}

bool read_bool(const YAML::Node& n, const Where& w, const std::string& key) {
  try {
    return n.as<bool>();
  } catch (const YAML::Exception&) {
    throw InputError(w.file, w.line(n), w.key(key) + ": expected true or false");
  }
}

Field number(const std::string& key, double& target, const Where& w) {
  return {key, [&target, w, key](const YAML::Node& n) { target = read_number(n, w, key); }};
}

Field integer(const std::string& key, int& target, const Where& w) {
  return {key, [&target, w, key](const YAML::Node& n) {
            target = static_cast<int>(read_integer(n, w, key));
          }};
}

// optional keys: unset unless the file gives them
Field optional_number(const std::string& key, std::optional<double>& target, const Where& w) {
  return {key, [&target, w, key](const YAML::Node& n) { target = read_number(n, w, key); }};
}

Field optional_integer(const std::string& key, std::optional<int>& target, const Where& w) {
  return {key, [&target, w, key](const YAML::Node& n) {
            target = static_cast<int>(read_integer(n, w, key));
          }};
}

// reads a map section field by field; an unknown key is an error that lists the known ones
void read_section(const YAML::Node& node, const Where& w, const std::vector<Field>& fields) {
  if (!node.IsMap())
    throw InputError(w.file, w.line(node),
                     (w.section.empty() ? std::string("top level") : w.section) +
                         ": expected a map of key: value");
  for (const auto& item : node) {
    const std::string key = item.first.as<std::string>();
    const Field* field = nullptr;
    for (const Field& f : fields)
      if (f.key == key) field = &f;
    if (!field) {
      std::string known;
      for (const Field& f : fields) known += (known.empty() ? "" : ", ") + f.key;
      throw InputError(w.file, w.line(item.first),
                       w.key(key) + ": unknown key; expected one of: " + known);
    }
    field->read(item.second);
  }
}

std::vector<Field> vehicle_fields(vehicle_models::VehicleParams& p, const Where& w) {
  return {
      {"name", [&p, w](const YAML::Node& n) { p.name = read_string(n, w, "name"); }},
      number("mass_kg", p.mass_kg, w),
      number("wheelbase_m", p.wheelbase_m, w),
      number("front_mass_fraction", p.front_mass_fraction, w),
      number("track_m", p.track_m, w),
      number("cog_height_m", p.cog_height_m, w),
      number("yaw_inertia_kgm2", p.yaw_inertia_kgm2, w),
      number("wheel_radius_m", p.wheel_radius_m, w),
      number("wheel_width_m", p.wheel_width_m, w),
      number("wheel_mass_kg", p.wheel_mass_kg, w),
      number("length_m", p.length_m, w),
      number("width_m", p.width_m, w),
      number("front_overhang_from_rear_axle_m", p.front_overhang_from_rear_axle_m, w),
      number("max_steer_rad", p.max_steer_rad, w),
      number("max_steer_rate_rps", p.max_steer_rate_rps, w),
      number("ackermann_factor", p.ackermann_factor, w),
      number("max_torque_front_nm", p.max_torque_front_nm, w),
      number("max_torque_rear_nm", p.max_torque_rear_nm, w),
      number("max_power_w", p.max_power_w, w),
      number("max_brake_torque_nm", p.max_brake_torque_nm, w),
      number("motor_rotor_inertia_kgm2", p.motor_rotor_inertia_kgm2, w),
      number("slip_target", p.slip_target, w),
      number("tyre_friction", p.tyre_friction, w),
      number("rolling_resistance", p.rolling_resistance, w),
      number("drag_area_m2", p.drag_area_m2, w),
      number("lift_area_m2", p.lift_area_m2, w),
      number("air_density_kgm3", p.air_density_kgm3, w),
      number("spring_n_per_m", p.spring_n_per_m, w),
      number("damper_ns_per_m", p.damper_ns_per_m, w),
      number("suspension_travel_m", p.suspension_travel_m, w),
  };
}

std::vector<Field> driver_fields(control::DriverParams& p, const Where& w) {
  return {
      number("explore_speed_mps", p.explore_speed_mps, w),
      number("fast_speed_mps", p.fast_speed_mps, w),
      number("acceleration_speed_mps", p.acceleration_speed_mps, w),
      number("skidpad_speed_mps", p.skidpad_speed_mps, w),
      number("max_lateral_accel_mps2", p.max_lateral_accel_mps2, w),
      number("max_accel_mps2", p.max_accel_mps2, w),
      number("max_decel_mps2", p.max_decel_mps2, w),
      number("lookahead_min_m", p.lookahead_min_m, w),
      number("lookahead_gain_s", p.lookahead_gain_s, w),
      integer("trackdrive_laps", p.trackdrive_laps, w),
      number("assumed_half_width_m", p.assumed_half_width_m, w),
      number("launch_accel_mps2", p.launch_accel_mps2, w),
      number("speed_gain_per_s", p.speed_gain_per_s, w),
      number("grip_fraction", p.grip_fraction, w),
      number("footprint_margin_m", p.footprint_margin_m, w),
      {"check_drivable",
       [&p, w](const YAML::Node& n) { p.check_drivable = read_bool(n, w, "check_drivable"); }},
  };
}

std::vector<Field> referee_fields(RefereeParams& p, const Where& w) {
  return {
      number("cone_penalty_s", p.cone_penalty_s, w),
      number("off_course_penalty_s", p.off_course_penalty_s, w),
      number("timeout_acceleration_s", p.timeout_acceleration_s, w),
      number("timeout_skidpad_s", p.timeout_skidpad_s, w),
      number("timeout_autocross_s", p.timeout_autocross_s, w),
      number("timeout_trackdrive_first_lap_s", p.timeout_trackdrive_first_lap_s, w),
      number("timeout_trackdrive_total_s", p.timeout_trackdrive_total_s, w),
      number("stuck_speed_mps", p.stuck_speed_mps, w),
      number("stuck_time_s", p.stuck_time_s, w),
      number("left_track_distance_m", p.left_track_distance_m, w),
      number("stopped_speed_mps", p.stopped_speed_mps, w),
      number("stopped_time_s", p.stopped_time_s, w),
  };
}

// applies "a.b.c=value" to the YAML tree, creating maps on the way
void apply_override(YAML::Node& root, const std::string& assignment, const std::string& file) {
  const size_t eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw InputError(file, "--set " + assignment, "expected key.path=value");
  const std::string path = assignment.substr(0, eq);
  YAML::Node value;
  try {
    value = YAML::Load(assignment.substr(eq + 1));
  } catch (const YAML::Exception& e) {
    throw InputError(file, "--set " + path, std::string("value is not valid YAML: ") + e.what());
  }
  std::vector<std::string> keys;
  std::stringstream ss(path);
  for (std::string k; std::getline(ss, k, '.');) {
    if (k.empty()) throw InputError(file, "--set " + path, "empty key in the path");
    keys.push_back(k);
  }
  std::vector<YAML::Node> chain{root};
  for (size_t i = 0; i + 1 < keys.size(); ++i) {
    YAML::Node next = chain.back()[keys[i]];
    if (next.IsDefined() && !next.IsMap() && !next.IsNull())
      throw InputError(file, "--set " + path, keys[i] + " is not a section");
    chain.push_back(next);
  }
  chain.back()[keys.back()] = value;
}

uint64_t read_seed(const YAML::Node& n, const Where& w, const std::string& key) {
  const int64_t v = read_integer(n, w, key);
  if (v < 0) throw InputError(w.file, w.line(n), w.key(key) + ": expected a seed >= 0");
  return static_cast<uint64_t>(v);
}

// resolves a file named in a scenario: relative to the scenario's folder, then as given
fs::path resolve(const fs::path& scenario_file, const std::string& name) {
  const fs::path p(name);
  if (p.is_absolute()) return p;
  const fs::path beside = scenario_file.parent_path() / p;
  if (fs::exists(beside)) return beside;
  return p;
}

}  // namespace

fs::path shipped_scenarios_dir() {
  if (const char* env = std::getenv("CONESIM_SCENARIOS")) return env;
  return fs::path(CONESIM_SOURCE_DIR) / "scenarios";
}

fs::path find_scenario(const std::string& name_or_path) {
  const fs::path as_given(name_or_path);
  if (fs::is_regular_file(as_given)) return as_given;
  const fs::path shipped = shipped_scenarios_dir() / (name_or_path + ".yaml");
  if (fs::is_regular_file(shipped)) return shipped;
  std::string known;
  if (fs::is_directory(shipped_scenarios_dir())) {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(shipped_scenarios_dir()))
      if (e.path().extension() == ".yaml") names.push_back(e.path().stem().string());
    std::sort(names.begin(), names.end());
    for (const auto& n : names) known += (known.empty() ? "" : ", ") + n;
  }
  throw InputError(name_or_path, 0,
                   "no such scenario file, and no shipped scenario of that name (shipped: " +
                       known + ")");
}

vehicle_models::VehicleParams load_vehicle(const fs::path& file) {
  YAML::Node root;
  try {
    if (!fs::is_regular_file(file)) throw InputError(file.string(), 0, "no such vehicle file");
    root = YAML::LoadFile(file.string());
  } catch (const YAML::Exception& e) {
    throw InputError(file.string(), e.mark.is_null() ? 0 : e.mark.line + 1,
                     "malformed YAML: " + e.msg);
  }
  vehicle_models::VehicleParams p;
  const Where w{file.string(), ""};
  if (root.IsNull()) throw InputError(file.string(), 0, "empty vehicle file");
  read_section(root, w, vehicle_fields(p, w));
  if (const std::string error = p.validate(); !error.empty())
    throw InputError(file.string(), 0, error);
  return p;
}

Scenario load_scenario(const fs::path& file, const std::vector<std::string>& overrides) {
  const std::string fname = file.string();

  // parse, then apply the command line's --set values
  YAML::Node root;
  try {
    std::ifstream in(file);
    if (!in) throw InputError(fname, 0, "cannot read the scenario file");
    root = YAML::Load(in);
  } catch (const YAML::Exception& e) {
    throw InputError(fname, e.mark.is_null() ? 0 : e.mark.line + 1, "malformed YAML: " + e.msg);
  }
  if (root.IsNull()) throw InputError(fname, 0, "empty scenario file");
  if (!root.IsMap()) throw InputError(fname, 1, "expected a map of scenario keys");
  for (const std::string& o : overrides) apply_override(root, o, fname);

  Scenario s;
  s.name = file.stem().string();
  s.source_file = file;
  const Where top{fname, ""};
  std::optional<uint64_t> generate_seed;
  bool has_event = false;

  // top-level keys
  std::vector<Field> fields = {
      {"name", [&](const YAML::Node& n) { s.name = read_string(n, top, "name"); }},
      {"event",
       [&](const YAML::Node& n) {
         const auto ev = core::event_from_string(read_string(n, top, "event"));
         if (!ev)
           throw InputError(fname, top.line(n),
                            "event: expected skidpad, acceleration, autocross or trackdrive");
         s.event = *ev;
         has_event = true;
       }},
      {"seed", [&](const YAML::Node& n) { s.seed = read_seed(n, top, "seed"); }},
      number("start_delay_s", s.start_delay_s, top),
      number("slam_latency_s", s.slam_latency_s, top),
      {"track",
       [&](const YAML::Node& n) {
         const Where w{fname, "track"};
         if (n.IsScalar()) {
           s.track.file = resolve(file, n.Scalar());
           return;
         }
         read_section(n, w,
                      {{"file", [&](const YAML::Node& v) {
                          s.track.file = resolve(file, read_string(v, w, "file"));
                        }},
                       {"generate", [&](const YAML::Node& v) {
                          const Where g{fname, "track.generate"};
                          if (v.IsNull()) return;
                          read_section(v, g, {{"seed", [&](const YAML::Node& x) {
                                                 generate_seed = read_seed(x, g, "seed");
                                               }}});
                          if (!generate_seed) generate_seed = std::numeric_limits<uint64_t>::max();
                        }}});
       }},
      {"vehicle",
       [&](const YAML::Node& n) {
         if (n.IsScalar()) {
           s.vehicle_source = n.Scalar();
           if (s.vehicle_source != "default") s.vehicle = load_vehicle(resolve(file, n.Scalar()));
           return;
         }
         const Where w{fname, "vehicle"};
         s.vehicle_source = "inline";
         read_section(n, w, vehicle_fields(s.vehicle, w));
       }},
      {"perception",
       [&](const YAML::Node& n) {
         s.perception = read_string(n, top, "perception");
         if (s.perception != "ground_truth" && s.perception != "cone_sensor" &&
             s.perception != "lidar" && s.perception != "stereo" && s.perception != "fused")
           throw InputError(fname, top.line(n),
                            "perception: expected ground_truth, cone_sensor, lidar, stereo or "
                            "fused, got '" + s.perception + "'");
       }},
      {"slam",
       [&](const YAML::Node& n) {
         s.slam = read_string(n, top, "slam");
         if (s.slam != "none" && s.slam != "graph")
           throw InputError(fname, top.line(n),
                            "slam: expected none or graph (ekf, fastslam1 and fastslam2 are not "
                            "built yet), got '" + s.slam + "'");
       }},
      {"driver",
       [&](const YAML::Node& n) {
         const Where w{fname, "driver"};
         read_section(n, w, driver_fields(s.driver, w));
       }},
      {"referee",
       [&](const YAML::Node& n) {
         const Where w{fname, "referee"};
         read_section(n, w, referee_fields(s.referee, w));
       }},
      {"sensors",
       [&](const YAML::Node& n) {
         const Where w{fname, "sensors"};
         auto& ss = s.sensors;
         read_section(
             n, w,
             {number("driver_rate_hz", ss.driver_rate_hz, w),
              number("cone_range_m", ss.cone_range_m, w),
              number("cone_fov_deg", ss.cone_fov_deg, w),
              {"cone_sensor",
               [&](const YAML::Node& v) {
                 const Where c{fname, "sensors.cone_sensor"};
                 auto& cs = ss.cone_sensor;
                 read_section(v, c,
                              {number("rate_hz", cs.timing.rate_hz, c),
                               number("latency_s", cs.timing.latency_s, c),
                               number("mount_x_m", cs.mount_x_m, c),
                               number("min_range_m", cs.min_range_m, c),
                               number("max_range_m", cs.max_range_m, c),
                               number("fov_deg", cs.fov_deg, c),
                               number("range_sigma_m", cs.range_sigma_m, c),
                               number("bearing_sigma_rad", cs.bearing_sigma_rad, c),
                               number("colour_range_m", cs.colour_range_m, c),
                               number("colour_probability", cs.colour_probability, c),
                               number("colour_confusion_probability",
                                      cs.colour_confusion_probability, c),
                               number("detection_probability_near", cs.detection_probability_near, c),
                               number("detection_probability_far", cs.detection_probability_far, c),
                               number("detection_falloff_start_m", cs.detection_falloff_start_m, c),
                               number("false_positives_per_frame", cs.false_positives_per_frame, c)});
               }},
              {"lidar",
               [&](const YAML::Node& v) {
                 const Where c{fname, "sensors.lidar"};
                 read_section(v, c,
                              {{"enabled",
                                [&](const YAML::Node& x) {
                                  ss.lidar_enabled = read_bool(x, c, "enabled");
                                }},
                               {"model",
                                [&](const YAML::Node& x) {
                                  ss.lidar_model = read_string(x, c, "model");
                                  if (!sensors::lidar_preset(ss.lidar_model))
                                    throw InputError(fname, c.line(x),
                                                     "sensors.lidar.model: expected vlp16, "
                                                     "vlp32c or os1-64");
                                }},
                               number("latency_s", ss.lidar_latency_s, c),
                               {"mount", [&](const YAML::Node& x) {
                                  ss.lidar_mount = read_string(x, c, "mount");
                                  if (!sensors::lidar_mount_preset(ss.lidar_mount))
                                    throw InputError(fname, c.line(x),
                                                     "sensors.lidar.mount: expected front_wing "
                                                     "or main_hoop");
                                }}});
               }},
              {"camera", [&](const YAML::Node& v) {
                 const Where c{fname, "sensors.camera"};
                 auto& cam = ss.camera;
                 read_section(
                     v, c,
                     {{"enabled",
                       [&](const YAML::Node& x) { ss.camera_enabled = read_bool(x, c, "enabled"); }},
                      {"depth",
                       [&](const YAML::Node& x) { ss.camera_depth = read_bool(x, c, "depth"); }},
                      number("rate_hz", ss.camera_rate_hz, c),
                      number("latency_s", ss.camera_latency_s, c),
                      integer("width_px", cam.width_px, c), integer("height_px", cam.height_px, c),
                      number("horizontal_fov_deg", cam.horizontal_fov_deg, c),
                      number("baseline_m", cam.baseline_m, c),
                      number("mount_x_m", cam.mount_x_m, c), number("mount_z_m", cam.mount_z_m, c),
                      number("pitch_down_deg", cam.pitch_down_deg, c)});
               }}});
       }},
      {"pass",
       [&](const YAML::Node& n) {
         const Where w{fname, "pass"};
         read_section(n, w,
                      {{"completed",
                        [&](const YAML::Node& v) {
                          s.pass.completed = read_bool(v, w, "completed");
                        }},
                       integer("max_cones_hit", s.pass.max_cones_hit, w),
                       integer("max_off_course", s.pass.max_off_course, w),
                       number("max_final_time_s", s.pass.max_final_time_s, w),
                       optional_number("max_map_rmse_m", s.pass.max_map_rmse_m, w),
                       optional_number("max_ate_rmse_m", s.pass.max_ate_rmse_m, w),
                       optional_number("min_da_correct_fraction", s.pass.min_da_correct_fraction,
                                       w),
                       optional_integer("max_false_loop_closures",
                                        s.pass.max_false_loop_closures, w)});
       }},
  };
  read_section(root, top, fields);
  if (!has_event) throw InputError(fname, "event", "missing; expected skidpad, acceleration, autocross or trackdrive");

  // a generated circuit without its own seed follows the scenario seed
  if (generate_seed) {
    if (*generate_seed != std::numeric_limits<uint64_t>::max()) s.track.generate_seed = generate_seed;
    else s.track.generate_seed = s.seed;
  }

  // check the values as a whole
  if (const std::string e = s.vehicle.validate(); !e.empty())
    throw InputError(fname, "vehicle", e);
  if (const std::string e = s.driver.validate(); !e.empty()) throw InputError(fname, "driver", e);
  if (!(s.sensors.driver_rate_hz >= 1.0 && s.sensors.driver_rate_hz <= 500.0) ||
      !core::whole_physics_steps(s.sensors.driver_rate_hz))
    throw InputError(fname, "sensors.driver_rate_hz",
                     "expected a rate from 1 to 500 Hz whose period is a whole number of "
                     "physics steps of 2 ms (e.g. 10, 20, 25, 50, 100)");
  if (!(s.sensors.cone_range_m > 0.0 && s.sensors.cone_range_m <= 200.0))
    throw InputError(fname, "sensors.cone_range_m", "expected a range in (0, 200] m");
  if (!(s.sensors.cone_fov_deg > 0.0 && s.sensors.cone_fov_deg <= 360.0))
    throw InputError(fname, "sensors.cone_fov_deg", "expected a field of view in (0, 360] degrees");
  if (const std::string e = s.sensors.cone_sensor.validate(); !e.empty())
    throw InputError(fname, "sensors", e);
  if (const std::string e = s.sensors.camera.validate(); !e.empty())
    throw InputError(fname, "sensors.camera", e);
  {
    if (!core::whole_physics_steps(s.sensors.camera_rate_hz))
      throw InputError(fname, "sensors.camera.rate_hz",
                       "expected a rate whose period is a whole number of physics steps of 2 ms "
                       "(e.g. 10, 20, 25, 50)");
  }
  if (s.pass.max_cones_hit < 0 || s.pass.max_off_course < 0 || s.pass.max_final_time_s < 0.0)
    throw InputError(fname, "pass", "expected limits >= 0");
  if (s.pass.max_map_rmse_m && !(*s.pass.max_map_rmse_m > 0.0))
    throw InputError(fname, "pass.max_map_rmse_m", "expected a distance > 0 m");
  if (s.pass.max_ate_rmse_m && !(*s.pass.max_ate_rmse_m > 0.0))
    throw InputError(fname, "pass.max_ate_rmse_m", "expected a distance > 0 m");
  if (s.pass.min_da_correct_fraction &&
      !(*s.pass.min_da_correct_fraction >= 0.0 && *s.pass.min_da_correct_fraction <= 1.0))
    throw InputError(fname, "pass.min_da_correct_fraction", "expected a fraction from 0 to 1");
  if (s.pass.max_false_loop_closures && *s.pass.max_false_loop_closures < 0)
    throw InputError(fname, "pass.max_false_loop_closures", "expected a count >= 0");
  {
    const PassCriteria& p = s.pass;
    const bool slam_criteria = p.max_map_rmse_m || p.max_ate_rmse_m ||
                               p.min_da_correct_fraction || p.max_false_loop_closures;
    if (slam_criteria && s.slam == "none")
      throw InputError(fname, "pass",
                       "SLAM criteria (max_map_rmse_m, max_ate_rmse_m, min_da_correct_fraction, "
                       "max_false_loop_closures) need slam: graph");
  }
  if (!(s.start_delay_s >= 0.0 && s.start_delay_s <= 60.0))
    throw InputError(fname, "start_delay_s", "expected a delay from 0 to 60 s");
  {
    const double sweep_s = 1.0 / sensors::lidar_preset(s.sensors.lidar_model)->rate_hz;
    if (!(s.sensors.lidar_latency_s >= 0.0 && s.sensors.lidar_latency_s < sweep_s))
      throw InputError(fname, "sensors.lidar.latency_s",
                       "expected a latency from 0 s to less than one sweep (" +
                           std::to_string(sweep_s) + " s)");
    if (!(s.sensors.camera_latency_s >= 0.0 && s.sensors.camera_latency_s <= 1.0))
      throw InputError(fname, "sensors.camera.latency_s", "expected a latency from 0 to 1 s");
  }
  if (!(s.slam_latency_s >= 0.0 && s.slam_latency_s <= 1.0))
    throw InputError(fname, "slam_latency_s", "expected a latency from 0 to 1 s");
  if (s.slam != "none" && s.perception == "ground_truth")
    throw InputError(fname, "slam", "SLAM needs observations with noise: set perception to "
                                    "cone_sensor, lidar, stereo or fused");
  if (s.track.file && s.track.generate_seed)
    throw InputError(fname, "track", "give either file or generate, not both");
  return s;
}

}  // namespace conesim::sim
