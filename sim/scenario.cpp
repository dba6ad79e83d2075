#include "sim/scenario.hpp"

#include <yaml-cpp/depthguard.h>
#include <yaml-cpp/yaml.h>

#include <charconv>
#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <sstream>
#include <string_view>
#include <type_traits>

#include "core/error.hpp"
#include "core/files.hpp"
#include "core/rng.hpp"
#include "sensors/lidar_config.hpp"
#include "slam/factory.hpp"
#include "vehicle_models/mjcf_builder.hpp"

namespace conesim::sim {

namespace fs = std::filesystem;
using core::InputError;

namespace {

// the longest time or penalty the referee takes, seconds (about 28 hours of sim time)
constexpr double kMaxRefereeSeconds = 100000.0;

// a key of a section and how to store its value
struct Field {
  std::string key;
  std::function<void(const YAML::Node&)> read;
};

// what one load shares: the file, the keys the command line gave (dotted key -> option), the
// line of every key read from the file, and the warnings
struct Context {
  std::string file;
  std::map<std::string, std::string> origins;
  std::map<std::string, int> lines;
  std::vector<std::string> warnings;

  // the option that gave a key (or a section holding it), nullptr when the file gave it
  const std::string* origin(const std::string& key) const {
    for (const auto& [k, option] : origins)
      if (key == k || key.starts_with(k + ".")) return &option;
    return nullptr;
  }

  // an error at a key: "--set: key: message" for a value from the command line, otherwise
  // "file:line: key: message" (the line where the key was read, when known)
  [[noreturn]] void fail(const std::string& key, const std::string& message, int line = 0) const {
    if (const std::string* option = origin(key)) throw InputError(*option, 0, key + ": " + message);
    if (line == 0)
      if (const auto it = lines.find(key); it != lines.end()) line = it->second;
    if (line > 0) throw InputError(file, line, key + ": " + message);
    throw InputError(file, key, message);
  }

  // a validate() message "key: what was expected" of a section, at that key
  [[noreturn]] void fail_check(const std::string& section, const std::string& error) const {
    const size_t colon = error.find(": ");
    const std::string key = colon == std::string::npos ? "" : error.substr(0, colon);
    if (key.empty() || key.find(' ') != std::string::npos) fail(section, error);
    fail(section.empty() ? key : section + "." + key, error.substr(colon + 2));
  }
};

// context for error messages: the load and the dotted path of the section
struct Where {
  Context* context;
  std::string section;

  std::string key(const std::string& k) const { return section.empty() ? k : section + "." + k; }
  static int line(const YAML::Node& n) { return n.Mark().is_null() ? 0 : n.Mark().line + 1; }
  [[noreturn]] void fail(const YAML::Node& n, const std::string& k,
                         const std::string& message) const {
    context->fail(key(k), message, line(n));
  }
};

// a value as error messages show it
std::string describe(const YAML::Node& n) {
  if (n.IsScalar()) return "'" + n.Scalar() + "'";
  if (n.IsSequence()) return "a list";
  if (n.IsMap()) return "a map";
  return "nothing";
}

double read_number(const YAML::Node& n, const Where& w, const std::string& key) {
  double v = 0.0;
  try {
    if (!n.IsScalar()) throw YAML::Exception(n.Mark(), "not a scalar");
    v = n.as<double>();
  } catch (const YAML::Exception&) {
    w.fail(n, key, "expected a number, got " + describe(n));
  }
  if (!std::isfinite(v)) w.fail(n, key, "expected a finite number, got " + describe(n));
  return v;
}

// a whole number within [lo, hi]: the text read exactly as digits (so every 64-bit seed
// reads), or a number with a fraction or an exponent that is whole and exact in a double (10.0,
// 1e3); never narrowed or wrapped
template <typename T>
T read_integer(const YAML::Node& n, const Where& w, const std::string& key,
               T lo = std::numeric_limits<T>::min(), T hi = std::numeric_limits<T>::max()) {
  const std::string range = "expected a whole number from " + std::to_string(lo) + " to " +
                            std::to_string(hi) + ", got " + describe(n);
  if (!n.IsScalar()) w.fail(n, key, range);

  // the sign and the magnitude: from the digits, or from a whole double
  std::string_view text = n.Scalar();
  bool negative = text.starts_with('-');
  if (negative || text.starts_with('+')) text.remove_prefix(1);
  uint64_t magnitude = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), magnitude);
  if (ec == std::errc::result_out_of_range) w.fail(n, key, range);
  if (text.empty() || ec != std::errc() || end != text.data() + text.size()) {
    double v = 0.0;
    try {
      v = n.as<double>();
    } catch (const YAML::Exception&) {
      w.fail(n, key, range);
    }
    if (v != std::floor(v) || !(std::abs(v) <= 9007199254740992.0)) w.fail(n, key, range);  // 2^53
    negative = v < 0.0;
    magnitude = static_cast<uint64_t>(std::abs(v));
  }

  // within [lo, hi], compared in 64 bits
  if (negative && magnitude != 0) {
    if constexpr (std::is_unsigned_v<T>) {
      w.fail(n, key, range);
    } else {
      if (lo >= 0) w.fail(n, key, range);
      const uint64_t most = static_cast<uint64_t>(-(static_cast<int64_t>(lo) + 1)) + 1;
      if (magnitude > most) w.fail(n, key, range);
      const int64_t v =
          magnitude == most ? static_cast<int64_t>(lo) : -static_cast<int64_t>(magnitude);
      if (v > static_cast<int64_t>(hi)) w.fail(n, key, range);
      return static_cast<T>(v);
    }
  }
  if (magnitude > static_cast<uint64_t>(hi) || (lo > 0 && magnitude < static_cast<uint64_t>(lo)))
    w.fail(n, key, range);
  return static_cast<T>(magnitude);
}

std::string read_string(const YAML::Node& n, const Where& w, const std::string& key) {
  if (!n.IsScalar()) w.fail(n, key, "expected a text value, got " + describe(n));
  return n.Scalar();
}

bool read_bool(const YAML::Node& n, const Where& w, const std::string& key) {
  try {
    if (n.IsScalar()) return n.as<bool>();
  } catch (const YAML::Exception&) {
  }
  w.fail(n, key, "expected true or false, got " + describe(n));
}

// a switch: on or off (or true or false)
Field on_off(const std::string& key, bool& target, const Where& w) {
  return {key, [&target, w, key](const YAML::Node& n) {
            const std::string text = n.IsScalar() ? n.Scalar() : std::string();
            if (text == "on" || text == "true")
              target = true;
            else if (text == "off" || text == "false")
              target = false;
            else
              w.fail(n, key, "expected on or off, got " + describe(n));
          }};
}

Field number(const std::string& key, double& target, const Where& w) {
  return {key, [&target, w, key](const YAML::Node& n) { target = read_number(n, w, key); }};
}

Field integer(const std::string& key, int& target, const Where& w) {
  return {key, [&target, w, key](const YAML::Node& n) { target = read_integer<int>(n, w, key); }};
}

// optional keys: unset unless the file gives them
Field optional_number(const std::string& key, std::optional<double>& target, const Where& w) {
  return {key, [&target, w, key](const YAML::Node& n) { target = read_number(n, w, key); }};
}

Field optional_integer(const std::string& key, std::optional<int>& target, const Where& w) {
  return {key, [&target, w, key](const YAML::Node& n) { target = read_integer<int>(n, w, key); }};
}

// refuses keys that are not plain words (a YAML complex key); a key given twice in one map
// gives a warning with both lines and the last one counts (as in most YAML readers), the
// earlier ones are dropped here so that --set and the reader see the same value
void drop_duplicate_keys(YAML::Node node, Context& context, const std::string& section) {
  if (!node.IsMap()) return;
  std::map<std::string, std::vector<int>> lines;
  for (const auto& item : node) {
    const std::string where = section.empty() ? "top level" : section;
    if (!item.first.IsScalar())
      throw InputError(context.file, Where::line(item.first),
                       where + ": expected key: value with a plain word as key, got " +
                           describe(item.first) + " as a key");
    lines[item.first.Scalar()].push_back(Where::line(item.first));
  }
  for (const auto& [key, at] : lines) {
    const std::string dotted = section.empty() ? key : section + "." + key;
    if (at.size() > 1) {
      std::string earlier;
      for (size_t i = 0; i + 1 < at.size(); ++i)
        earlier += (earlier.empty() ? "" : ", ") + std::to_string(at[i]);
      context.warnings.push_back(context.file + ":" + std::to_string(at.back()) + ": " + dotted +
                                 ": given again (also on line " + earlier +
                                 "); the last one counts");
      for (size_t i = 0; i + 1 < at.size(); ++i) node.remove(key);
    }
    drop_duplicate_keys(node[key], context, dotted);
  }
}

// reads a map section field by field; an unknown key is an error that lists the known ones
void read_section(const YAML::Node& node, const Where& w, const std::vector<Field>& fields) {
  if (!node.IsMap())
    w.context->fail(w.section.empty() ? std::string("top level") : w.section,
                    "expected a map of key: value, got " + describe(node), Where::line(node));
  for (const auto& item : node) {
    if (!item.first.IsScalar())
      w.context->fail(w.section.empty() ? std::string("top level") : w.section,
                      "expected a plain word as key, got " + describe(item.first),
                      Where::line(item.first));
    const std::string key = item.first.Scalar();
    const Field* field = nullptr;
    for (const Field& f : fields)
      if (f.key == key) field = &f;
    if (!field) {
      std::string known;
      for (const Field& f : fields) known += (known.empty() ? "" : ", ") + f.key;
      w.fail(item.first, key, "unknown key; expected one of: " + known);
    }
    w.context->lines[w.key(key)] = Where::line(item.first);
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
      number("explore_grip_fraction", p.explore_grip_fraction, w),
      number("footprint_margin_m", p.footprint_margin_m, w),
      number("tight_turn_margin_m", p.tight_turn_margin_m, w),
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

// applies "a.b.c=value" to the YAML tree, creating maps on the way, and notes that `option`
// (--set, --seed) gave the key, so that an error about it names the option and not the file
void apply_override(YAML::Node& root, const std::string& assignment, const std::string& option,
                    Context& context) {
  const size_t eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw InputError(option, 0, "'" + assignment + "': expected key.path=value");
  const std::string path = assignment.substr(0, eq);
  const std::string text = assignment.substr(eq + 1);
  if (text.find_first_not_of(" \t") == std::string::npos)
    throw InputError(option, 0, path + ": expected a value after '=', got nothing");
  YAML::Node value;
  try {
    value = YAML::Load(text);
  } catch (const YAML::DeepRecursion& e) {
    throw InputError(option, 0,
                     path + ": value nested " + std::to_string(e.depth()) + " levels deep");
  } catch (const YAML::Exception& e) {
    throw InputError(option, 0, path + ": value is not valid YAML: " + e.msg);
  }
  drop_duplicate_keys(value, context, path);
  std::vector<std::string> keys;
  std::stringstream ss(path);
  for (std::string k; std::getline(ss, k, '.');) {
    if (k.empty()) throw InputError(option, 0, path + ": empty key in the path");
    keys.push_back(k);
  }
  if (path.back() == '.') throw InputError(option, 0, path + ": empty key in the path");
  // `slam: graph` is short for `slam: {drive: graph}`: a key set under it extends that form
  if (keys.size() > 1 && keys[0] == "slam" && root["slam"].IsScalar()) {
    YAML::Node section(YAML::NodeType::Map);
    section["drive"] = YAML::Clone(root["slam"]);
    root["slam"] = section;
  }
  std::vector<YAML::Node> chain{root};
  for (size_t i = 0; i + 1 < keys.size(); ++i) {
    YAML::Node next = chain.back()[keys[i]];
    if (next.IsDefined() && !next.IsMap() && !next.IsNull())
      throw InputError(option, 0, path + ": " + keys[i] + " is not a section");
    chain.push_back(next);
  }
  chain.back()[keys.back()] = value;
  context.origins[path] = option;
}

// a generator profile by name (tracks::profile_from_string)
tracks::GeneratorProfile read_profile(const YAML::Node& n, const Where& w, const std::string& key) {
  const std::string name = read_string(n, w, key);
  if (const auto p = tracks::profile_from_string(name)) return *p;
  std::string names;
  for (tracks::GeneratorProfile p : tracks::all_profiles())
    names += (names.empty() ? "" : ", ") + std::string(tracks::to_string(p));
  w.fail(n, key, "expected one of " + names + ", got '" + name + "'");
}

// resolves a file named in a scenario: relative to the scenario's folder, then as given
fs::path resolve(const fs::path& scenario_file, const std::string& name) {
  const fs::path p(name);
  if (p.is_absolute()) return p;
  const fs::path beside = scenario_file.parent_path() / p;
  if (core::path_exists(beside)) return beside;
  return p;
}

// a back-end name of the slam: block
std::string read_backend(const YAML::Node& n, const Where& w, const std::string& key,
                         bool none_allowed) {
  const std::string name = read_string(n, w, key);
  if ((none_allowed && name == "none") || slam::is_backend(name)) return name;
  w.fail(n, key,
         std::string("expected ") + (none_allowed ? "none or " : "") + "a SLAM back-end (" +
             slam::backend_list() + "), got '" + name + "'");
}

slam::AssociationMethod read_association(const YAML::Node& n, const Where& w,
                                         const std::string& key) {
  const std::string name = read_string(n, w, key);
  if (const auto m = slam::association_from_string(name)) return *m;
  w.fail(n, key,
         "expected an association method (" + slam::association_names() + "), got '" + name + "'");
}

// slam: NAME, or slam: {drive: NAME, shadow: [NAME, NAME:METHOD, ...], association: METHOD or
// {NAME: METHOD, ...}, graph: {...}, ekf: {...}, fastslam: {...}}
void read_slam(const YAML::Node& n, const Where& top, Context& context, Scenario& s) {
  if (n.IsScalar()) {
    s.slam = read_backend(n, top, "slam", true);
    return;
  }
  const Where w{&context, "slam"};
  auto& ekf = s.slam_settings.ekf;
  auto& graph = s.slam_settings.graph;
  read_section(
      n, w,
      {{"drive", [&](const YAML::Node& v) { s.slam = read_backend(v, w, "drive", true); }},
       {"shadow",
        [&](const YAML::Node& v) {
          s.slam_shadows.clear();
          // one name or a list of them (a YAML node assigned to is changed in place, so the
          // items are gathered rather than the node rebuilt)
          std::vector<YAML::Node> items;
          if (v.IsScalar()) items.push_back(v);
          if (v.IsSequence())
            for (const YAML::Node& item : v) items.push_back(item);
          if (!v.IsScalar() && !v.IsSequence())
            w.fail(v, "shadow", "expected a list of back-ends, e.g. [ekf], got " + describe(v));
          for (const YAML::Node& item : items) {
            const std::string given = read_string(item, w, "shadow");
            // NAME, NAME:METHOD (the back-end with that association), then +ABLATION each
            SlamShadow shadow;
            std::string entry = given;
            for (size_t plus = entry.rfind('+'); plus != std::string::npos;
                 plus = entry.rfind('+')) {
              shadow.ablations.insert(shadow.ablations.begin(), entry.substr(plus + 1));
              entry.resize(plus);
            }
            const size_t colon = entry.find(':');
            shadow.backend = entry.substr(0, colon);
            if (!slam::is_backend(shadow.backend))
              w.fail(item, "shadow",
                     "expected back-ends (" + slam::backend_list() +
                         ", each optionally :METHOD and +ABLATION), got '" + given + "'");
            for (const std::string& a : shadow.ablations) {
              const auto& known = slam_ablations(shadow.backend);
              if (std::find(known.begin(), known.end(), a) != known.end()) continue;
              std::string list;
              for (const std::string& k : known) list += (list.empty() ? "" : ", ") + k;
              w.fail(item, "shadow",
                     "unknown ablation '" + a + "' in '" + given + "': " + shadow.backend +
                         (known.empty() ? " has none" : " has " + list) +
                         " (graph: global_only, no_landmark_edges, no_icr; ekf: no_preliminary)");
            }
            if (colon != std::string::npos) {
              const auto m = slam::association_from_string(entry.substr(colon + 1));
              if (!m)
                w.fail(item, "shadow",
                       "expected NAME:METHOD with a method of " + slam::association_names() +
                           ", got '" + given + "'");
              shadow.association = *m;
            }
            s.slam_shadows.push_back(shadow);
          }
        }},
       {"association",
        [&](const YAML::Node& v) {
          if (v.IsScalar()) {
            const slam::AssociationMethod m = read_association(v, w, "association");
            for (const std::string& name : slam::backend_names()) s.slam_association[name] = m;
            return;
          }
          const Where a{&context, "slam.association"};
          std::vector<Field> per_backend;
          for (const std::string& name : slam::backend_names())
            per_backend.push_back({name, [&, name](const YAML::Node& x) {
                                     s.slam_association[name] = read_association(x, a, name);
                                   }});
          read_section(v, a, per_backend);
        }},
       {"ekf",
        [&](const YAML::Node& v) {
          const Where e{&context, "slam.ekf"};
          read_section(v, e,
                       {integer("confirm_sightings", ekf.confirm_sightings, e),
                        number("preliminary_max_travel_m", ekf.preliminary_max_travel_m, e),
                        number("preliminary_radius_m", ekf.preliminary_radius_m, e),
                        {"preliminary_list",
                         [&](const YAML::Node& x) {
                           ekf.preliminary_list = read_bool(x, e, "preliminary_list");
                         }},
                        number("new_landmark_min_distance_m", ekf.new_landmark_min_distance_m, e),
                        number("new_landmark_chi2", ekf.new_landmark_chi2, e),
                        number("unseen_exclusion_m", ekf.unseen_exclusion_m, e),
                        number("loop_min_travel_m", ekf.loop_min_travel_m, e),
                        number("start_radius_m", ekf.start_radius_m, e),
                        number("closure_delay_m", ekf.closure_delay_m, e),
                        integer("closure_min_pairs", ekf.closure_min_pairs, e),
                        number("closure_max_heading_rad", ekf.closure_max_heading_rad, e),
                        {"localise_after_loop_closure",
                         [&](const YAML::Node& x) {
                           ekf.localise_after_loop_closure =
                               read_bool(x, e, "localise_after_loop_closure");
                         }},
                        number("odometry_noise_scale", ekf.odometry_noise_scale, e),
                        number("yaw_noise_per_m", ekf.yaw_noise_per_m, e),
                        number("gate_chi2", ekf.association.gate_chi2, e),
                        number("joint_probability", ekf.association.joint_probability, e),
                        number("nn_radius_m", ekf.association.nn_radius_m, e),
                        number("track_memory_frames", ekf.association.track_memory_frames, e),
                        number("ambiguity_margin", ekf.association.ambiguity_margin, e)});
        }},
       {"fastslam",
        [&](const YAML::Node& v) {
          auto& f = s.slam_settings.fastslam;
          const Where e{&context, "slam.fastslam"};
          read_section(v, e,
                       {integer("particles", f.particles, e),
                        number("resample_fraction", f.resample_fraction, e),
                        number("new_landmark_likelihood", f.new_landmark_likelihood, e),
                        number("unseen_penalty", f.unseen_penalty, e),
                        number("colour_mismatch_penalty", f.colour_mismatch_penalty, e),
                        number("new_landmark_min_distance_m", f.new_landmark_min_distance_m, e),
                        number("new_landmark_chi2", f.new_landmark_chi2, e),
                        integer("confirm_sightings", f.confirm_sightings, e),
                        number("tentative_max_travel_m", f.tentative_max_travel_m, e),
                        integer("class_vote_margin", f.class_vote_margin, e),
                        number("odometry_noise_scale", f.odometry_noise_scale, e),
                        number("yaw_noise_per_m", f.yaw_noise_per_m, e),
                        number("drift_variance_m2_per_m", f.drift_variance_m2_per_m, e),
                        number("max_drift_variance_m2", f.max_drift_variance_m2, e),
                        number("return_gap_m", f.return_gap_m, e),
                        number("hold_drift_m", f.hold_drift_m, e),
                        number("fov_margin_m", f.fov_margin_m, e),
                        number("loop_closure_factor", f.loop_closure.returned_fraction, e),
                        number("loop_min_travel_m", f.loop_closure.min_travel_m, e),
                        number("closure_delay_m", f.loop_closure.closure_delay_m, e),
                        number("closure_max_spread_m", f.closure_max_spread_m, e),
                        {"localise_after_loop_closure",
                         [&](const YAML::Node& x) {
                           f.localise_after_loop_closure =
                               read_bool(x, e, "localise_after_loop_closure");
                         }},
                        number("gate_chi2", f.association.gate_chi2, e),
                        number("joint_probability", f.association.joint_probability, e),
                        number("nn_radius_m", f.association.nn_radius_m, e),
                        number("track_memory_frames", f.association.track_memory_frames, e),
                        number("ambiguity_margin", f.association.ambiguity_margin, e)});
        }},
       {"odometry",
        [&](const YAML::Node& v) {
          auto& o = s.slam_settings.odometry;
          const Where d{&context, "slam.odometry"};
          read_section(
              v, d,
              {integer("confirm_sightings", o.confirm_sightings, d),
               number("tentative_max_travel_m", o.tentative_max_travel_m, d),
               number("reach_m", o.reach_m, d), number("nn_radius_m", o.association.nn_radius_m, d),
               number("gate_chi2", o.association.gate_chi2, d),
               number("joint_probability", o.association.joint_probability, d)});
        }},
       {"graph", [&](const YAML::Node& v) {
          const Where g{&context, "slam.graph"};
          read_section(
              v, g,
              {integer("confirm_sightings", graph.confirm_sightings, g),
               integer("window_poses", graph.window_poses, g),
               number("icr_sigma_m", graph.icr_sigma_m, g),
               {"icr",
                [&](const YAML::Node& x) {
                  // off: no ICR edge; on: the edge with icr_sigma_m (given or default)
                  if (!read_bool(x, g, "icr")) graph.icr_sigma_m = 0.0;
                }},
               {"global_only",
                [&](const YAML::Node& x) { graph.global_only = read_bool(x, g, "global_only"); }},
               {"landmark_edges",
                [&](const YAML::Node& x) {
                  graph.landmark_edges = read_bool(x, g, "landmark_edges");
                }},
               number("gate_chi2", graph.association.gate_chi2, g),
               number("track_memory_frames", graph.association.track_memory_frames, g),
               number("ambiguity_margin", graph.association.ambiguity_margin, g),
               {"localise_after_loop_closure", [&](const YAML::Node& x) {
                  graph.localise_after_loop_closure =
                      read_bool(x, g, "localise_after_loop_closure");
                }}});
        }}});
}
}  // namespace

const std::vector<std::string>& slam_ablations(const std::string& backend) {
  static const std::vector<std::string> graph = {"global_only", "no_landmark_edges", "no_icr"};
  static const std::vector<std::string> ekf = {"no_preliminary"};
  static const std::vector<std::string> none;
  return backend == "graph" ? graph : backend == "ekf" ? ekf : none;
}

fs::path shipped_scenarios_dir() {
  if (const char* env = std::getenv("CONESIM_SCENARIOS")) return env;
  return fs::path(CONESIM_SOURCE_DIR) / "scenarios";
}

fs::path find_scenario(const std::string& name_or_path) {
  const fs::path as_given(name_or_path);
  if (core::is_file(as_given)) return as_given;
  const fs::path shipped = shipped_scenarios_dir() / (name_or_path + ".yaml");
  if (core::is_file(shipped)) return shipped;
  std::string known;
  if (core::is_folder(shipped_scenarios_dir())) {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(shipped_scenarios_dir()))
      if (e.path().extension() == ".yaml") names.push_back(e.path().stem().string());
    std::sort(names.begin(), names.end());
    for (const auto& n : names) known += (known.empty() ? "" : ", ") + n;
  }
  throw InputError(
      name_or_path, 0,
      "no such scenario file, and no shipped scenario of that name (shipped: " + known + ")");
}

namespace {

// parses a YAML file; a failure names the file and the line
YAML::Node parse_yaml_file(const fs::path& file, const std::string& what) {
  const std::string name = file.string();
  if (!core::is_file(file)) throw InputError(name, 0, "no such " + what + " file");
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(name, 0, "cannot read the " + what + " file");
  try {
    return YAML::Load(in);
  } catch (const YAML::DeepRecursion& e) {
    // yaml-cpp's message for it is "bad file"
    throw InputError(name, e.mark.is_null() ? 0 : e.mark.line + 1,
                     "malformed YAML: nested " + std::to_string(e.depth()) +
                         " levels deep, more than any " + what + " file");
  } catch (const YAML::Exception& e) {
    throw InputError(name, e.mark.is_null() ? 0 : e.mark.line + 1, "malformed YAML: " + e.msg);
  }
}

// a vehicle file's keys, its warnings added to the context's
vehicle_models::VehicleParams read_vehicle_file(const fs::path& file,
                                                std::vector<std::string>& warnings) {
  const YAML::Node root = parse_yaml_file(file, "vehicle");
  if (root.IsNull()) throw InputError(file.string(), 0, "empty vehicle file");
  Context context{file.string(), {}, {}, {}};
  drop_duplicate_keys(root, context, "");
  vehicle_models::VehicleParams p;
  const Where w{&context, ""};
  read_section(root, w, vehicle_fields(p, w));
  if (const std::string error = p.validate(); !error.empty()) context.fail_check("", error);
  warnings.insert(warnings.end(), context.warnings.begin(), context.warnings.end());
  return p;
}

// a run folder is named after the scenario: a plain file name, nothing that leads elsewhere
std::string run_name_error(const std::string& name) {
  if (name.empty()) return "expected a plain name for the run folder, got nothing";
  if (name == "." || name == "..")
    return "expected a plain name for the run folder, got '" + name + "'";
  if (name.size() > 100) return "expected a name of at most 100 characters for the run folder";
  for (const char c : name) {
    if (c == '/' || c == '\\')
      return "expected a plain name for the run folder, without / or \\, got '" + name + "'";
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f)
      return "expected a plain name for the run folder, without control characters";
  }
  return {};
}

// a YAML block flattened to "key.sub" / "list.0" -> scalar text, in the file's order
void flatten_config(const YAML::Node& n, const std::string& prefix,
                    std::vector<std::pair<std::string, std::string>>& out) {
  if (n.IsMap()) {
    for (const auto& item : n)
      flatten_config(item.second,
                     prefix.empty() ? item.first.Scalar() : prefix + "." + item.first.Scalar(),
                     out);
  } else if (n.IsSequence()) {
    for (size_t i = 0; i < n.size(); ++i)
      flatten_config(n[i], prefix + "." + std::to_string(i), out);
  } else if (n.IsScalar()) {
    out.emplace_back(prefix, n.Scalar());
  }
}

// one entry of the autonomy: block: a built-in name, `plugin:PATH`, or {plugin: PATH, config:
// {...}, time_budget_ms: N, sensors: [lidar, camera]} (the last for a perception); returns the
// built-in name, or nullopt with `spec` filled for a plug-in
std::optional<std::string> read_autonomy_entry(const YAML::Node& n, const Where& w,
                                               const std::string& key, PluginKind kind,
                                               const fs::path& file,
                                               std::optional<PluginSpec>& spec) {
  const std::string plugin_prefix = "plugin:";
  PluginSpec p;
  p.kind = kind;
  int line = Where::line(n);
  if (n.IsScalar()) {
    const std::string v = n.Scalar();
    if (!v.starts_with(plugin_prefix)) {
      spec.reset();
      return v;
    }
    p.file = resolve(file, v.substr(plugin_prefix.size()));
  } else {
    const Where e{w.context, w.key(key)};
    bool has_file = false;
    read_section(
        n, e,
        {{"plugin",
          [&](const YAML::Node& v) {
            p.file = resolve(file, read_string(v, e, "plugin"));
            has_file = true;
            line = Where::line(v);
          }},
         {"config",
          [&](const YAML::Node& v) {
            if (!v.IsMap() && !v.IsNull())
              e.fail(v, "config", "expected a map of the plug-in's own keys, got " + describe(v));
            flatten_config(v, "", p.config);
            YAML::Emitter out;
            out << YAML::Flow << v;
            p.config_yaml = v.IsNull() ? "{}" : out.c_str();
          }},
         {"time_budget_ms",
          [&](const YAML::Node& v) {
            p.time_budget_ms = read_number(v, e, "time_budget_ms");
            if (!(p.time_budget_ms > 0.0))
              e.fail(v, "time_budget_ms", "expected a time > 0 ms, got " + describe(v));
          }},
         {"sensors", [&](const YAML::Node& v) {
            if (kind != PluginKind::kPerception)
              e.fail(v, "sensors", "only a perception plug-in is given sensors");
            if (!v.IsSequence() || v.size() == 0)
              e.fail(v, "sensors", "expected a list of lidar and camera, got " + describe(v));
            p.lidar = p.camera = false;
            for (const YAML::Node& item : v) {
              const std::string name = read_string(item, e, "sensors");
              if (name == "lidar")
                p.lidar = true;
              else if (name == "camera")
                p.camera = true;
              else
                e.fail(item, "sensors", "expected lidar or camera, got '" + name + "'");
            }
          }}});
    if (!has_file) w.fail(n, key, "expected plugin: PATH of a shared library");
  }
  // the library is opened and checked now: bad input stops before anything runs
  try {
    p.library = PluginLibrary::open(p.file);
  } catch (const std::exception& ex) {
    w.context->fail(w.key(key), ex.what(), line);
  }
  const sdk::PluginInfo& info = p.library->info();
  const bool offered = kind == PluginKind::kPerception ? info.create_perception != nullptr
                       : kind == PluginKind::kSlam     ? info.create_slam != nullptr
                                                       : info.create_driver != nullptr;
  if (!offered)
    w.context->fail(w.key(key),
                    p.file.string() + ": the plug-in '" + info.name + "' offers no " + key +
                        " (its CONESIM_PLUGIN names none)",
                    line);
  spec = std::move(p);
  return std::nullopt;
}

// the perception and SLAM autonomy: chose (applied over the top-level keys once all are read)
struct AutonomyChoice {
  std::optional<std::string> perception;
  std::optional<std::string> slam;
};

// autonomy: {perception: ..., slam: ..., driver: ...}: the stack, built-in or plug-ins
void read_autonomy(const YAML::Node& n, Context& context, const fs::path& file, Scenario& s,
                   AutonomyChoice& choice) {
  const Where w{&context, "autonomy"};
  read_section(
      n, w,
      {{"perception",
        [&](const YAML::Node& v) {
          const auto name = read_autonomy_entry(v, w, "perception", PluginKind::kPerception, file,
                                                s.perception_plugin);
          choice.perception = name.value_or("plugin");
          if (name && *name != "ground_truth" && *name != "cone_sensor" && *name != "lidar" &&
              *name != "stereo" && *name != "fused")
            w.fail(
                v, "perception",
                "expected ground_truth, cone_sensor, lidar, stereo, fused or plugin:PATH, got '" +
                    *name + "'");
        }},
       {"slam",
        [&](const YAML::Node& v) {
          const auto name =
              read_autonomy_entry(v, w, "slam", PluginKind::kSlam, file, s.slam_plugin);
          if (name && *name != "none" && !slam::is_backend(*name))
            w.fail(v, "slam",
                   "expected none, a SLAM back-end (" + slam::backend_list() +
                       ") or plugin:PATH, got '" + *name + "'");
          choice.slam = name ? *name : "plugin:" + s.slam_plugin->name();
        }},
       {"driver", [&](const YAML::Node& v) {
          const auto name =
              read_autonomy_entry(v, w, "driver", PluginKind::kDriver, file, s.driver_plugin);
          if (name && *name != "reference")
            w.fail(v, "driver", "expected reference or plugin:PATH, got '" + *name + "'");
        }}});
}

// one fault's window and the parameters of its kind (a key of another kind is unknown here)
Fault read_fault(const YAML::Node& n, FaultKind kind, const Where& w) {
  Fault f;
  f.kind = kind;
  std::vector<Field> fields = {
      number("start_s", f.start_s, w),
      {"end_s",
       [&f, w](const YAML::Node& v) {
         if (!v.IsNull()) f.end_s = read_number(v, w, "end_s");
       }},
  };
  switch (kind) {
    case FaultKind::kLidarDropout:
      fields.push_back(number("fraction", f.fraction, w));
      break;
    case FaultKind::kLidarSectorBlackout:
      fields.push_back(number("from_deg", f.from_deg, w));
      fields.push_back(number("to_deg", f.to_deg, w));
      break;
    case FaultKind::kLidarLostSweeps:
      fields.push_back(integer("every", f.every, w));
      fields.push_back(number("probability", f.probability, w));
      break;
    case FaultKind::kImuBiasStep:
      fields.push_back(number("gyro_bias_rps", f.gyro_bias_rps, w));
      fields.push_back(number("accel_bias_mps2", f.accel_bias_mps2, w));
      break;
    case FaultKind::kWheelSlip:
      fields.push_back(number("factor", f.factor, w));
      break;
    case FaultKind::kDelayJitter:
      fields.push_back(number("max_delay_s", f.max_delay_s, w));
      fields.push_back({"out_of_order", [&f, w](const YAML::Node& v) {
                          f.out_of_order = read_bool(v, w, "out_of_order");
                        }});
      break;
    case FaultKind::kCameraBlackout:
    case FaultKind::kCameraFrozen:
    case FaultKind::kGnssOutage:
      break;
  }
  if (!n.IsNull()) read_section(n, w, fields);
  if (const std::string e = f.validate(); !e.empty()) w.context->fail_check(w.section, e);
  return f;
}

// `faults:` a map from kind to one window ({start_s, end_s, ...}) or a list of them; null or {}
// for none
std::vector<Fault> read_faults(const YAML::Node& n, Context& context) {
  std::vector<Fault> faults;
  if (n.IsNull()) return faults;
  const Where w{&context, "faults"};
  std::vector<Field> fields;
  for (const std::string& name : fault_kind_names()) {
    const FaultKind kind = *fault_kind_from_string(name);
    fields.push_back(
        {name, [&faults, &context, kind, name](const YAML::Node& v) {
           if (v.IsSequence()) {
             for (size_t i = 0; i < v.size(); ++i)
               faults.push_back(read_fault(
                   v[i], kind, Where{&context, "faults." + name + "[" + std::to_string(i) + "]"}));
             return;
           }
           faults.push_back(read_fault(v, kind, Where{&context, "faults." + name}));
         }});
  }
  read_section(n, w, fields);
  return faults;
}

// the faults against the sensors and the stack they act on: a fault of a sensor that is not in
// the loop would do nothing, which is refused rather than reported as survived
void check_faults(const Scenario& s, const Context& context) {
  const bool lidar = s.sensors.lidar_enabled || s.perception == "lidar" || s.perception == "fused";
  const bool camera =
      s.sensors.camera_enabled || s.perception == "stereo" || s.perception == "fused";
  for (const Fault& f : s.faults) {
    const std::string key = "faults." + to_string(f.kind);
    switch (f.kind) {
      case FaultKind::kLidarDropout:
      case FaultKind::kLidarSectorBlackout:
      case FaultKind::kLidarLostSweeps:
        if (!lidar)
          context.fail(key, "no LiDAR in the loop (perception: " + s.perception +
                                "); expected perception lidar or fused, or sensors.lidar.enabled");
        break;
      case FaultKind::kCameraBlackout:
      case FaultKind::kCameraFrozen:
        if (!camera)
          context.fail(key, "no camera in the loop (perception: " + s.perception +
                                "); expected perception stereo or fused, or "
                                "sensors.camera.enabled");
        break;
      case FaultKind::kImuBiasStep:
      case FaultKind::kWheelSlip:
        if (s.slam == "none")
          context.fail(key,
                       "the IMU and wheel encoders feed SLAM's odometry, and this scenario runs "
                       "no SLAM (slam: none); expected slam: graph, ekf, fastslam1 or fastslam2");
        break;
      case FaultKind::kDelayJitter:
        if (s.perception == "ground_truth")
          context.fail(key,
                       "ground-truth perception delivers no frames to delay; expected "
                       "perception cone_sensor, lidar, stereo or fused");
        break;
      case FaultKind::kGnssOutage:
        break;
    }
  }
}

}  // namespace

vehicle_models::VehicleParams load_vehicle(const fs::path& file) {
  std::vector<std::string> warnings;
  return read_vehicle_file(file, warnings);
}

Scenario load_scenario(const fs::path& file, const std::vector<std::string>& overrides,
                       std::optional<uint64_t> seed) {
  const std::string fname = file.string();
  Context context{fname, {}, {}, {}};

  // parse, drop keys given twice (with a warning), then apply the command line's values
  YAML::Node root = parse_yaml_file(file, "scenario");
  if (root.IsNull()) throw InputError(fname, 0, "empty scenario file");
  if (!root.IsMap()) throw InputError(fname, Where::line(root), "expected a map of scenario keys");
  drop_duplicate_keys(root, context, "");
  if (seed) apply_override(root, "seed=" + std::to_string(*seed), "--seed", context);
  for (const std::string& o : overrides) apply_override(root, o, "--set", context);

  Scenario s;
  s.name = file.stem().string();
  s.source_file = file;
  const Where top{&context, ""};
  std::optional<uint64_t> generate_seed;
  bool has_event = false;
  // sensors switched off explicitly, which a raw-data perception contradicts
  bool lidar_disabled = false;
  bool camera_noise_given = false;
  bool lens_given = false;
  bool texture_given = false;
  bool exposure_given = false;
  bool sun_given = false;
  bool camera_disabled = false;
  // the stack chosen under autonomy: (over the top-level perception: and slam:)
  AutonomyChoice autonomy;

  // top-level keys
  std::vector<Field> fields = {
      {"name", [&](const YAML::Node& n) { s.name = read_string(n, top, "name"); }},
      {"event",
       [&](const YAML::Node& n) {
         const auto ev = core::event_from_string(read_string(n, top, "event"));
         if (!ev) top.fail(n, "event", "expected skidpad, acceleration, autocross or trackdrive");
         s.event = *ev;
         has_event = true;
       }},
      {"seed", [&](const YAML::Node& n) { s.seed = read_integer<uint64_t>(n, top, "seed"); }},
      number("start_delay_s", s.start_delay_s, top),
      number("slam_latency_s", s.slam_latency_s, top),
      {"track",
       [&](const YAML::Node& n) {
         const Where w{&context, "track"};
         if (n.IsScalar()) {
           s.track.file = resolve(file, n.Scalar());
           return;
         }
         read_section(n, w,
                      {{"file",
                        [&](const YAML::Node& v) {
                          s.track.file = resolve(file, read_string(v, w, "file"));
                        }},
                       {"generate", [&](const YAML::Node& v) {
                          const Where g{&context, "track.generate"};
                          if (v.IsNull()) return;
                          read_section(v, g,
                                       {{"seed",
                                         [&](const YAML::Node& x) {
                                           generate_seed = read_integer<uint64_t>(x, g, "seed");
                                         }},
                                        {"profile", [&](const YAML::Node& x) {
                                           s.track.generate_profile = read_profile(x, g, "profile");
                                         }}});
                          if (!generate_seed) generate_seed = std::numeric_limits<uint64_t>::max();
                        }}});
       }},
      {"vehicle",
       [&](const YAML::Node& n) {
         if (n.IsScalar()) {
           s.vehicle_source = n.Scalar();
           if (s.vehicle_source == "default") return;
           // a file that is not there is this file's mistake, at this line
           const fs::path vehicle_file = resolve(file, n.Scalar());
           if (!core::is_file(vehicle_file))
             top.fail(n, "vehicle",
                      "expected default or a vehicle YAML file, got '" + n.Scalar() +
                          "' (no such file" +
                          (vehicle_file.is_relative() ? " beside the scenario or here)" : ")"));
           s.vehicle = read_vehicle_file(vehicle_file, context.warnings);
           return;
         }
         const Where w{&context, "vehicle"};
         s.vehicle_source = "inline";
         read_section(n, w, vehicle_fields(s.vehicle, w));
       }},
      {"perception",
       [&](const YAML::Node& n) {
         s.perception = read_string(n, top, "perception");
         if (s.perception != "ground_truth" && s.perception != "cone_sensor" &&
             s.perception != "lidar" && s.perception != "stereo" && s.perception != "fused")
           top.fail(n, "perception",
                    "expected ground_truth, cone_sensor, lidar, stereo or "
                    "fused, got '" +
                        s.perception + "'");
       }},
      {"slam", [&](const YAML::Node& n) { read_slam(n, top, context, s); }},
      {"autonomy", [&](const YAML::Node& n) { read_autonomy(n, context, file, s, autonomy); }},
      {"driver",
       [&](const YAML::Node& n) {
         const Where w{&context, "driver"};
         read_section(n, w, driver_fields(s.driver, w));
       }},
      {"referee",
       [&](const YAML::Node& n) {
         const Where w{&context, "referee"};
         read_section(n, w, referee_fields(s.referee, w));
       }},
      {"world",
       [&](const YAML::Node& n) {
         const Where w{&context, "world"};
         read_section(
             n, w,
             {on_off("randomise", s.randomise, w),
              {"clutter",
               [&](const YAML::Node& v) {
                 const Where c{&context, "world.clutter"};
                 auto& cl = s.clutter;
                 read_section(v, c,
                              {number("objects_per_100m", cl.objects_per_100m, c),
                               number("margin_m", cl.margin_m, c),
                               number("spread_m", cl.spread_m, c),
                               {"seed_offset",
                                [&](const YAML::Node& x) {
                                  cl.seed_offset = read_integer<uint64_t>(x, c, "seed_offset");
                                }},
                               {"grass_edge", [&](const YAML::Node& x) {
                                  cl.grass_edge = read_bool(x, c, "grass_edge");
                                }}});
               }},
              {"ground", [&](const YAML::Node& v) {
                 const Where c{&context, "world.ground"};
                 auto& g = s.ground;
                 read_section(v, c,
                              {number("grade_percent", g.grade_percent, c),
                               {"grade_heading_deg",
                                [&](const YAML::Node& x) {
                                  g.grade_heading_deg = read_number(x, c, "grade_heading_deg");
                                }},
                               number("crown_percent", g.crown_percent, c),
                               number("undulation_amplitude_m", g.undulation_amplitude_m, c),
                               number("undulation_wavelength_m", g.undulation_wavelength_m, c),
                               number("bump_height_m", g.bump_height_m, c),
                               number("bump_radius_m", g.bump_radius_m, c),
                               number("bumps_per_100m2", g.bumps_per_100m2, c),
                               {"seed_offset", [&](const YAML::Node& x) {
                                  g.seed_offset = read_integer<uint64_t>(x, c, "seed_offset");
                                }}});
               }}});
       }},
      {"sensors",
       [&](const YAML::Node& n) {
         const Where w{&context, "sensors"};
         auto& ss = s.sensors;
         read_section(
             n, w,
             {number("driver_rate_hz", ss.driver_rate_hz, w),
              on_off("realism", ss.realism, w),
              number("cone_range_m", ss.cone_range_m, w),
              number("cone_fov_deg", ss.cone_fov_deg, w),
              {"cone_sensor",
               [&](const YAML::Node& v) {
                 const Where c{&context, "sensors.cone_sensor"};
                 auto& cs = ss.cone_sensor;
                 read_section(
                     v, c,
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
                      number("colour_confusion_probability", cs.colour_confusion_probability, c),
                      number("detection_probability_near", cs.detection_probability_near, c),
                      number("detection_probability_far", cs.detection_probability_far, c),
                      number("detection_falloff_start_m", cs.detection_falloff_start_m, c),
                      number("false_positives_per_frame", cs.false_positives_per_frame, c),
                      {"track", [&](const YAML::Node& x) {
                         ss.cone_sensor_track = read_bool(x, c, "track");
                       }}});
               }},
              {"imu",
               [&](const YAML::Node& v) {
                 const Where c{&context, "sensors.imu"};
                 auto& imu = ss.imu;
                 read_section(
                     v, c,
                     {number("gyro_noise_density_rps_rthz", imu.gyro_noise_density_rps_rthz, c),
                      number("gyro_bias_walk_rps_rts", imu.gyro_bias_walk_rps_rts, c),
                      number("gyro_initial_bias_rps", imu.gyro_initial_bias_rps, c)});
               }},
              {"wheel_encoders",
               [&](const YAML::Node& v) {
                 const Where c{&context, "sensors.wheel_encoders"};
                 read_section(v, c, {number("noise_rps", ss.wheel_encoders.noise_rps, c)});
               }},
              {"lidar",
               [&](const YAML::Node& v) {
                 const Where c{&context, "sensors.lidar"};
                 read_section(
                     v, c,
                     {{"enabled",
                       [&](const YAML::Node& x) {
                         ss.lidar_enabled = read_bool(x, c, "enabled");
                         lidar_disabled = !ss.lidar_enabled;
                       }},
                      {"model",
                       [&](const YAML::Node& x) {
                         ss.lidar_model = read_string(x, c, "model");
                         if (!sensors::lidar_preset(ss.lidar_model))
                           c.fail(x, "model",
                                  "expected vlp16, "
                                  "vlp32c or os1-64");
                       }},
                      number("latency_s", ss.lidar_latency_s, c),
                      optional_number("range_noise_sigma_m", ss.lidar_range_noise_sigma_m, c),
                      optional_number("range_noise_growth", ss.lidar_range_noise_growth, c),
                      optional_number("detection_range_10pct_m", ss.lidar_detection_range_10pct_m,
                                      c),
                      optional_number("beam_divergence_mrad", ss.lidar_beam_divergence_mrad, c),
                      {"mount", [&](const YAML::Node& x) {
                         ss.lidar_mount = read_string(x, c, "mount");
                         if (!sensors::lidar_mount_preset(ss.lidar_mount))
                           c.fail(x, "mount",
                                  "expected front_wing "
                                  "or main_hoop");
                       }}});
               }},
              {"camera", [&](const YAML::Node& v) {
                 const Where c{&context, "sensors.camera"};
                 auto& cam = ss.camera;
                 read_section(
                     v, c,
                     {{"enabled",
                       [&](const YAML::Node& x) {
                         ss.camera_enabled = read_bool(x, c, "enabled");
                         camera_disabled = !ss.camera_enabled;
                       }},
                      {"depth",
                       [&](const YAML::Node& x) { ss.camera_depth = read_bool(x, c, "depth"); }},
                      number("rate_hz", ss.camera_rate_hz, c),
                      number("latency_s", ss.camera_latency_s, c),
                      integer("width_px", cam.width_px, c),
                      integer("height_px", cam.height_px, c),
                      number("horizontal_fov_deg", cam.horizontal_fov_deg, c),
                      number("baseline_m", cam.baseline_m, c),
                      number("mount_x_m", cam.mount_x_m, c),
                      number("mount_z_m", cam.mount_z_m, c),
                      number("pitch_down_deg", cam.pitch_down_deg, c),
                      number("light_ambient", cam.light_ambient, c),
                      number("light_diffuse", cam.light_diffuse, c),
                      number("exposure_ev", cam.response.exposure_ev, c),
                      number("gamma", cam.response.gamma, c),
                      {"full_well_e",
                       [&](const YAML::Node& x) {
                         cam.response.full_well_e = read_number(x, c, "full_well_e");
                         camera_noise_given = true;
                       }},
                      number("read_noise_e", cam.response.read_noise_e, c),
                      {"distortion",
                       [&](const YAML::Node& x) {
                         if (!x.IsSequence() || x.size() != 5)
                           c.fail(x, "distortion",
                                  "expected a list of five numbers [k1, k2, p1, p2, k3] (OpenCV's "
                                  "lens model)");
                         for (size_t i = 0; i < 5; ++i)
                           cam.distortion[i] = read_number(x[i], c, "distortion");
                         lens_given = true;
                       }},
                      {"exposure_time_ms",
                       [&](const YAML::Node& x) {
                         cam.exposure_time_ms = read_number(x, c, "exposure_time_ms");
                         exposure_given = true;
                       }},
                      {"ground_texture",
                       [&](const YAML::Node& x) {
                         cam.ground_texture = read_bool(x, c, "ground_texture");
                         texture_given = true;
                       }},
                      {"sun", [&](const YAML::Node& x) {
                         const Where sun{&context, "sensors.camera.sun"};
                         read_section(x, sun,
                                      {number("elevation_deg", cam.sun_elevation_deg, sun),
                                       number("azimuth_deg", cam.sun_azimuth_deg, sun),
                                       {"diffuse",
                                        [&](const YAML::Node& d) {
                                          cam.sun_diffuse = read_number(d, sun, "diffuse");
                                          sun_given = true;
                                        }},
                                       number("shadow_strength", cam.shadow_strength, sun)});
                       }}});
               }}});
       }},
      {"faults", [&](const YAML::Node& n) { s.faults = read_faults(n, context); }},
      {"pass",
       [&](const YAML::Node& n) {
         const Where w{&context, "pass"};
         read_section(
             n, w,
             {{"completed",
               [&](const YAML::Node& v) { s.pass.completed = read_bool(v, w, "completed"); }},
              integer("max_cones_hit", s.pass.max_cones_hit, w),
              integer("max_off_course", s.pass.max_off_course, w),
              number("max_final_time_s", s.pass.max_final_time_s, w),
              optional_number("max_map_rmse_m", s.pass.max_map_rmse_m, w),
              optional_number("max_ate_rmse_m", s.pass.max_ate_rmse_m, w),
              optional_number("min_da_correct_fraction", s.pass.min_da_correct_fraction, w),
              optional_integer("max_false_loop_closures", s.pass.max_false_loop_closures, w),
              optional_number("max_map_missed_fraction", s.pass.max_map_missed_fraction, w)});
       }},
  };
  read_section(root, top, fields);
  if (!has_event)
    context.fail("event", "missing; expected skidpad, acceleration, autocross or trackdrive");

  // a generated circuit without its own seed follows the scenario seed
  if (generate_seed) {
    if (*generate_seed != std::numeric_limits<uint64_t>::max())
      s.track.generate_seed = generate_seed;
    else
      s.track.generate_seed = s.seed;
  }

  // without the sensors' realism the images carry no noise (unless the noise is asked for);
  // with it the lens distorts as a common machine-vision lens does (unless another is given)
  if (!s.sensors.realism && !camera_noise_given) s.sensors.camera.response.full_well_e = 0.0;
  if (!lens_given)
    s.sensors.camera.distortion =
        s.sensors.realism ? sensors::kTypicalLensDistortion : std::array<double, 5>{};
  // and the asphalt has its grain and the sun shines, casting shadows
  if (!texture_given) s.sensors.camera.ground_texture = s.sensors.realism;
  // the image integrates the light over its exposure, the car moving meanwhile
  if (!exposure_given)
    s.sensors.camera.exposure_time_ms = s.sensors.realism ? sensors::kTypicalExposureTimeMs : 0.0;
  if (!sun_given)
    s.sensors.camera.sun_diffuse = s.sensors.realism ? sensors::kTypicalSunDiffuse : 0.0;
  if (s.randomise) randomise_look(s);

  // check the values as a whole
  if (const std::string e = s.vehicle.validate(); !e.empty()) context.fail_check("vehicle", e);
  if (const std::string e = s.driver.validate(); !e.empty()) context.fail_check("driver", e);
  if (!(s.sensors.driver_rate_hz >= 1.0 && s.sensors.driver_rate_hz <= 500.0) ||
      !core::whole_physics_steps(s.sensors.driver_rate_hz))
    context.fail("sensors.driver_rate_hz",
                 "expected a rate from 1 to 500 Hz whose period is a whole number of "
                 "physics steps of 2 ms (e.g. 10, 20, 25, 50, 100)");
  if (!(s.sensors.cone_range_m > 0.0 && s.sensors.cone_range_m <= 200.0))
    context.fail("sensors.cone_range_m", "expected a range in (0, 200] m");
  if (!(s.sensors.cone_fov_deg > 0.0 && s.sensors.cone_fov_deg <= 360.0))
    context.fail("sensors.cone_fov_deg", "expected a field of view in (0, 360] degrees");
  if (const std::string e = s.sensors.cone_sensor.validate(); !e.empty())
    context.fail_check("sensors", e);
  if (const std::string e = s.sensors.imu.validate(); !e.empty()) context.fail_check("sensors", e);
  if (const std::string e = s.sensors.wheel_encoders.validate(); !e.empty())
    context.fail_check("sensors", e);
  if (const std::string e = s.sensors.camera.validate(); !e.empty())
    context.fail_check("sensors.camera", e);
  if (const std::string e = s.sensors.lidar_config().validate(); !e.empty())
    context.fail_check("sensors.lidar", e);
  {
    if (!core::whole_physics_steps(s.sensors.camera_rate_hz))
      context.fail("sensors.camera.rate_hz",
                   "expected a rate whose period is a whole number of physics steps of 2 ms "
                   "(e.g. 10, 20, 25, 50)");
  }
  if (s.pass.max_cones_hit < 0 || s.pass.max_off_course < 0 || s.pass.max_final_time_s < 0.0)
    context.fail("pass", "expected limits >= 0");
  if (s.pass.max_map_rmse_m && !(*s.pass.max_map_rmse_m > 0.0))
    context.fail("pass.max_map_rmse_m", "expected a distance > 0 m");
  if (s.pass.max_ate_rmse_m && !(*s.pass.max_ate_rmse_m > 0.0))
    context.fail("pass.max_ate_rmse_m", "expected a distance > 0 m");
  if (s.pass.min_da_correct_fraction &&
      !(*s.pass.min_da_correct_fraction >= 0.0 && *s.pass.min_da_correct_fraction <= 1.0))
    context.fail("pass.min_da_correct_fraction", "expected a fraction from 0 to 1");
  if (s.pass.max_false_loop_closures && *s.pass.max_false_loop_closures < 0)
    context.fail("pass.max_false_loop_closures", "expected a count >= 0");
  if (s.pass.max_map_missed_fraction &&
      !(*s.pass.max_map_missed_fraction >= 0.0 && *s.pass.max_map_missed_fraction <= 1.0))
    context.fail("pass.max_map_missed_fraction", "expected a fraction from 0 to 1");
  {
    const PassCriteria& p = s.pass;
    const bool slam_criteria = p.max_map_rmse_m || p.max_ate_rmse_m || p.min_da_correct_fraction ||
                               p.max_false_loop_closures || p.max_map_missed_fraction;
    if (slam_criteria && s.slam == "none")
      context.fail("pass",
                   "SLAM criteria (max_map_rmse_m, max_ate_rmse_m, min_da_correct_fraction, "
                   "max_false_loop_closures, max_map_missed_fraction) need slam: graph, ekf, "
                   "fastslam1 or fastslam2");
  }
  if (!(s.start_delay_s >= 0.0 && s.start_delay_s <= 60.0))
    context.fail("start_delay_s", "expected a delay from 0 to 60 s");
  {
    const double sweep_s = 1.0 / sensors::lidar_preset(s.sensors.lidar_model)->rate_hz;
    if (!(s.sensors.lidar_latency_s >= 0.0 && s.sensors.lidar_latency_s < sweep_s))
      context.fail(
          "sensors.lidar.latency_s",
          "expected a latency from 0 s to less than one sweep (" + std::to_string(sweep_s) + " s)");
    if (!(s.sensors.camera_latency_s >= 0.0 && s.sensors.camera_latency_s <= 1.0))
      context.fail("sensors.camera.latency_s", "expected a latency from 0 to 1 s");
  }
  if (!(s.slam_latency_s >= 0.0 && s.slam_latency_s <= 1.0))
    context.fail("slam_latency_s", "expected a latency from 0 to 1 s");
  if (s.slam == "none" && !s.slam_shadows.empty())
    context.fail("slam.shadow", "shadow back-ends run beside a driving one: set slam.drive to " +
                                    slam::backend_list());
  if (const auto it = s.slam_association.find(s.slam);
      it != s.slam_association.end() && it->second == slam::AssociationMethod::kIdeal)
    context.fail("slam.association",
                 "ideal reads the ground-truth labels: it is for shadow back-ends only (e.g. "
                 "shadow: [" +
                     s.slam + ":ideal]), never for the one that drives");
  // the association each lane runs: no association only in shadow and only where the map can
  // hold every observation; tracking-aided needs a back-end with track memory
  {
    auto method_of = [&](const std::string& backend, std::optional<slam::AssociationMethod> own) {
      if (own) return own;
      const auto it = s.slam_association.find(backend);
      return it == s.slam_association.end() ? std::optional<slam::AssociationMethod>{}
                                            : std::optional{it->second};
    };
    using M = slam::AssociationMethod;
    if (s.slam != "none" && method_of(s.slam, std::nullopt) == M::kNone)
      context.fail("slam.association",
                   "none (every observation a new landmark) is for shadow back-ends only (e.g. "
                   "shadow: [graph:none]), never for the one that drives");
    std::vector<SlamShadow> lanes = s.slam_shadows;
    if (s.slam != "none") lanes.push_back({s.slam, std::nullopt, {}});
    for (const SlamShadow& lane : lanes) {
      const auto m = method_of(lane.backend, lane.association);
      const std::string key = lane.association ? "slam.shadow" : "slam.association";
      if (m == M::kNone && lane.backend != "graph" && lane.backend != "odometry")
        context.fail(key,
                     "none (every observation a new landmark) runs on graph or odometry, "
                     "whose maps can hold thousands of landmarks; " +
                         lane.backend + " keeps them in a joint state or in every particle");
      if (m == M::kTrackingAided && lane.backend == "odometry")
        context.fail(key,
                     "odometry (dead reckoning) has no track memory: expected nn, ml, scnn, "
                     "jcbb, ideal or none");
    }
  }
  if (std::string e = s.slam_settings.odometry.validate(); !e.empty())
    context.fail_check("slam.odometry", e);
  // (the association's parameters sit beside the others under slam.ekf)
  if (std::string e = s.slam_settings.ekf.validate(); !e.empty())
    context.fail_check("slam.ekf", e.starts_with("association.") ? e.substr(12) : e);
  if (std::string e = s.slam_settings.fastslam.validate(); !e.empty()) {
    // the loop closure's keys are read without their section's prefix; its fraction is the
    // thesis's loop closure factor
    if (e.starts_with("loop_closure.returned_fraction"))
      e = "loop_closure_factor" + e.substr(30);
    else if (e.starts_with("loop_closure.min_travel_m"))
      e = "loop_min_travel_m" + e.substr(25);
    else if (e.starts_with("loop_closure."))
      e = e.substr(13);
    context.fail_check("slam.fastslam", e);
  }
  if (std::string e = s.slam_settings.graph.validate(); !e.empty())
    context.fail_check("slam.graph", e.starts_with("graph_slam.") ? e.substr(11) : e);
  if (!(s.slam_settings.graph.association.gate_chi2 > 0.0))
    context.fail("slam.graph.gate_chi2", "expected a chi-square gate > 0");
  if (!(s.slam_settings.graph.association.track_memory_frames >= 1.0))
    context.fail("slam.graph.track_memory_frames", "expected >= 1 frame");
  if (!(s.slam_settings.graph.association.ambiguity_margin >= 0.0 &&
        s.slam_settings.graph.association.ambiguity_margin <= 100.0))
    context.fail("slam.graph.ambiguity_margin",
                 "expected a cost margin from 0 (pair every observation) to 100");
  // autonomy: chooses over the top-level perception: and slam: (a shipped scenario's stack with
  // one part swapped: --set autonomy.slam=plugin:PATH)
  if (autonomy.perception) s.perception = *autonomy.perception;
  if (autonomy.slam) s.slam = *autonomy.slam;
  if (s.slam_plugin && !s.slam_shadows.empty() &&
      std::any_of(s.slam_shadows.begin(), s.slam_shadows.end(),
                  [&](const SlamShadow& sh) { return sh.lane_name() == s.slam; }))
    context.fail("slam.shadow", "a shadow lane has the plug-in's name");
  // a perception plug-in switches on the sensors it is given
  if (s.perception_plugin) {
    s.sensors.lidar_enabled = s.sensors.lidar_enabled || s.perception_plugin->lidar;
    s.sensors.camera_enabled = s.sensors.camera_enabled || s.perception_plugin->camera;
  }
  if (s.slam != "none" && s.perception == "ground_truth")
    context.fail("slam",
                 "SLAM needs observations with noise: set perception to "
                 "cone_sensor, lidar, stereo or fused");
  if (s.track.file && s.track.generate_seed)
    context.fail("track", "give either file or generate, not both");

  // the run folder's name
  if (const std::string e = run_name_error(s.name); !e.empty()) {
    if (context.lines.count("name") || context.origin("name")) context.fail("name", e);
    throw InputError(fname, 0, "the file name gives the run folder's name: " + e);
  }

  // the scenery's density and where it may stand
  if (const std::string e = s.clutter.validate(); !e.empty())
    context.fail_check("world.clutter", e);
  if (const std::string e = s.ground.validate(); !e.empty()) context.fail_check("world.ground", e);

  // the referee's rules, with the lap count the driver is given; times within what the sim
  // clock (integer microseconds) holds many times over
  {
    RefereeParams referee = s.referee;
    referee.trackdrive_laps = s.driver.trackdrive_laps;
    if (const std::string e = referee.validate(); !e.empty()) context.fail_check("referee", e);
    const std::pair<const char*, double> bounded[] = {
        {"cone_penalty_s", s.referee.cone_penalty_s},
        {"off_course_penalty_s", s.referee.off_course_penalty_s},
        {"timeout_acceleration_s", s.referee.timeout_acceleration_s},
        {"timeout_skidpad_s", s.referee.timeout_skidpad_s},
        {"timeout_autocross_s", s.referee.timeout_autocross_s},
        {"timeout_trackdrive_first_lap_s", s.referee.timeout_trackdrive_first_lap_s},
        {"timeout_trackdrive_total_s", s.referee.timeout_trackdrive_total_s},
        {"stuck_time_s", s.referee.stuck_time_s},
        {"stopped_time_s", s.referee.stopped_time_s}};
    for (const auto& [key, value] : bounded)
      if (value > kMaxRefereeSeconds)
        context.fail(std::string("referee.") + key,
                     "expected at most " + std::to_string(static_cast<int>(kMaxRefereeSeconds)) +
                         " s, got " + (std::ostringstream() << value).str());
    if (!(s.referee.stuck_speed_mps <= 100.0 && s.referee.stopped_speed_mps <= 100.0 &&
          s.referee.left_track_distance_m <= 1000.0))
      context.fail("referee", "expected speeds up to 100 m/s and a distance up to 1000 m");
  }

  // a sensor switched off explicitly cannot feed the perception that needs it
  const bool raw_lidar = s.perception == "lidar" || s.perception == "fused";
  const bool raw_camera = s.perception == "stereo" || s.perception == "fused";
  if (lidar_disabled && raw_lidar)
    context.fail("sensors.lidar.enabled",
                 "false contradicts perception: " + s.perception + ", which needs the LiDAR");
  if (camera_disabled && raw_camera)
    context.fail("sensors.camera.enabled",
                 "false contradicts perception: " + s.perception + ", which needs the camera");

  check_faults(s, context);

  // the camera renders into the car model's offscreen buffer
  {
    const vehicle_models::MjcfOptions buffer;
    if (s.sensors.camera.width_px > buffer.offscreen_width_px)
      context.fail("sensors.camera.width_px", "expected at most " +
                                                  std::to_string(buffer.offscreen_width_px) +
                                                  " px (the offscreen buffer), got " +
                                                  std::to_string(s.sensors.camera.width_px));
    if (s.sensors.camera.height_px > buffer.offscreen_height_px)
      context.fail("sensors.camera.height_px", "expected at most " +
                                                   std::to_string(buffer.offscreen_height_px) +
                                                   " px (the offscreen buffer), got " +
                                                   std::to_string(s.sensors.camera.height_px));
  }
  s.warnings = std::move(context.warnings);
  return s;
}

namespace {

// world.randomise's stream of the scenario seed
constexpr uint64_t kLookStream = 0x100c;

}  // namespace

void randomise_look(Scenario& s) {
  // each value from its own range, in a fixed order (so that the same seed gives the same look
  // whatever else the scenario says), rounded for the reader of metrics.json
  core::Rng rng(core::derive_seed(s.seed, kLookStream));
  auto draw = [&](const char* key, double lo, double hi, double per_unit) {
    const double v = std::round(core::uniform(rng, lo, hi) * per_unit) / per_unit;
    s.look[key] = v;
    return v;
  };
  sensors::StereoCameraConfig& cam = s.sensors.camera;
  cam.light_ambient = draw("camera_light_ambient", 0.25, 0.6, 100);
  cam.light_diffuse = draw("camera_light_diffuse", 0.3, 0.8, 100);
  cam.response.exposure_ev = draw("camera_exposure_ev", -1.0, 1.0, 100);
  // a full well from 3000 to 30000 electrons, even in its logarithm
  cam.response.full_well_e =
      std::round(std::exp(core::uniform(rng, std::log(3000.0), std::log(30000.0))) / 10.0) * 10.0;
  s.look["camera_full_well_e"] = cam.response.full_well_e;
  cam.response.read_noise_e = draw("camera_read_noise_e", 5.0, 30.0, 10);
  s.sensors.lidar_range_noise_scale = draw("lidar_range_noise_scale", 0.8, 1.5, 100);
  s.sensors.lidar_detection_range_scale = draw("lidar_detection_range_scale", 0.8, 1.25, 100);
  s.sensors.lidar_ground_reflectivity = draw("lidar_ground_reflectivity", 0.06, 0.2, 200);
  // the sun: anywhere round the sky, from a low morning sun to noon, hazy to clear (the
  // asphalt's grain is drawn from the run's seed already)
  cam.sun_azimuth_deg = draw("camera_sun_azimuth_deg", 0.0, 360.0, 1);
  cam.sun_elevation_deg = draw("camera_sun_elevation_deg", 15.0, 75.0, 1);
  cam.sun_diffuse = draw("camera_sun_diffuse", 0.2, 0.7, 100);
  cam.exposure_time_ms = draw("camera_exposure_time_ms", 0.5, 4.0, 10);
}

sensors::LidarConfig SensorSettings::lidar_config() const {
  std::optional<sensors::LidarConfig> c = sensors::lidar_preset(lidar_model);
  const std::optional<core::Pose3> mount = sensors::lidar_mount_preset(lidar_mount);
  if (!c) throw std::invalid_argument("sensors.lidar.model: unknown model " + lidar_model);
  if (!mount) throw std::invalid_argument("sensors.lidar.mount: unknown mount " + lidar_mount);
  c->mount = *mount;
  if (!realism) c->clear_realism();
  if (lidar_range_noise_sigma_m) c->range_noise_sigma_m = *lidar_range_noise_sigma_m;
  if (lidar_range_noise_growth) c->range_noise_growth = *lidar_range_noise_growth;
  if (lidar_detection_range_10pct_m) c->detection_range_10pct_m = *lidar_detection_range_10pct_m;
  if (lidar_beam_divergence_mrad) c->beam_divergence_mrad = *lidar_beam_divergence_mrad;
  c->range_noise_sigma_m *= lidar_range_noise_scale;
  c->range_noise_growth *= lidar_range_noise_scale;
  c->detection_range_10pct_m *= lidar_detection_range_scale;
  if (lidar_ground_reflectivity) c->reflectivity.ground = *lidar_ground_reflectivity;
  return *c;
}

}  // namespace conesim::sim
