#include "sensors/lidar_config.hpp"

#include <cmath>
#include <sstream>

namespace conesim::sensors {

double Reflectivity::of(SurfaceMaterial m) const {
  switch (m) {
    case SurfaceMaterial::kGround:
      return ground;
    case SurfaceMaterial::kBlue:
      return blue;
    case SurfaceMaterial::kYellow:
      return yellow;
    case SurfaceMaterial::kOrange:
      return orange;
    case SurfaceMaterial::kWhite:
      return white;
    case SurfaceMaterial::kBlack:
      return black;
  }
  return ground;
}

core::TimeUs LidarConfig::sweep_period_us() const {
  return core::from_seconds(1.0 / rate_hz);
}

core::Pose3 LidarConfig::front_wing_mount() {
  core::Pose3 p;
  p.position = {2.1, 0.0, 0.18};
  return p;
}

core::Pose3 LidarConfig::main_hoop_mount() {
  core::Pose3 p;
  p.position = {0.6, 0.0, 1.0};
  return p;
}

std::string LidarConfig::validate() const {
  std::ostringstream err;
  auto bad = [&](const char* key, const std::string& expected) {
    err << key << ": " << expected;
    return err.str();
  };

  // beam pattern and timing
  if (elevations_deg.empty()) return bad("elevations_deg", "at least one channel");
  for (double e : elevations_deg)
    if (!std::isfinite(e) || e <= -90.0 || e >= 90.0)
      return bad("elevations_deg", "angles inside (-90, 90) degrees");
  if (columns < 1) return bad("columns", "at least 1");
  if (!(rate_hz > 0.0 && rate_hz <= 100.0)) return bad("rate_hz", "a rate in (0, 100] Hz");
  if (columns > sweep_period_us()) return bad("columns", "at most one column per microsecond");
  if (!(min_range_m >= 0.0)) return bad("min_range_m", "a range >= 0");
  if (!(max_range_m > min_range_m && max_range_m <= 1000.0))
    return bad("max_range_m", "a range above min_range_m and at most 1000 m");
  if (!std::isfinite(start_azimuth_deg)) return bad("start_azimuth_deg", "a finite angle");
  if (!mount.position.allFinite() || std::abs(mount.orientation.norm() - 1.0) > 1e-6)
    return bad("mount", "a finite position and a unit quaternion");

  // noise and faults
  if (!(range_noise_sigma_m >= 0.0 && range_noise_sigma_m < 1.0))
    return bad("range_noise_sigma_m", "a sigma in [0, 1) m");
  if (!(range_noise_growth >= 0.0 && range_noise_growth < 0.01))
    return bad("range_noise_growth", "a growth in [0, 0.01) m per m of range");
  if (!(detection_range_10pct_m == 0.0 ||
        (detection_range_10pct_m >= 1.0 && detection_range_10pct_m <= 1000.0)))
    return bad("detection_range_10pct_m", "0 (off) or a range in [1, 1000] m");
  if (!(beam_divergence_mrad >= 0.0 && beam_divergence_mrad <= 50.0))
    return bad("beam_divergence_mrad", "a full angle in [0, 50] mrad");
  if (!(echo_merge_m >= 0.0 && echo_merge_m <= 10.0))
    return bad("echo_merge_m", "a distance in [0, 10] m");
  if (!(dropout_probability >= 0.0 && dropout_probability <= 1.0))
    return bad("dropout_probability", "a probability in [0, 1]");
  if (!(intensity_noise_sigma >= 0.0 && intensity_noise_sigma <= 255.0))
    return bad("intensity_noise_sigma", "a sigma in [0, 255]");
  if (!(intensity_falloff_m > 0.0)) return bad("intensity_falloff_m", "a distance > 0");
  const std::pair<const char*, double> surfaces[] = {
      {"reflectivity.ground", reflectivity.ground}, {"reflectivity.blue", reflectivity.blue},
      {"reflectivity.yellow", reflectivity.yellow}, {"reflectivity.orange", reflectivity.orange},
      {"reflectivity.white", reflectivity.white},   {"reflectivity.black", reflectivity.black}};
  for (const auto& [key, value] : surfaces)
    if (!(value >= 0.0 && value <= 1.0)) return bad(key, "a reflectivity in [0, 1]");
  if (cone_mesh_sides < 6 || cone_mesh_sides > 256)
    return bad("cone_mesh_sides", "between 6 and 256 facets");
  return {};
}

void LidarConfig::clear_realism() {
  range_noise_growth = 0.0;
  detection_range_10pct_m = 0.0;
  beam_divergence_mrad = 0.0;
}

std::optional<LidarConfig> lidar_preset(std::string_view model) {
  // the VLP-16 is the default configuration
  if (model == "vlp16") return LidarConfig{};

  // VLP-32C: the manual's per-laser elevations (dense around the horizon), 200 m
  if (model == "vlp32c") {
    LidarConfig c;
    c.model = "vlp32c";
    c.elevations_deg = {-25.0,  -1.0,  -1.667, -15.639, -11.31, 0.0,   -0.667, -8.843,
                        -7.254, 0.333, -0.333, -6.148,  -5.333, 1.333, 0.667,  -4.0,
                        -4.667, 1.667, 1.0,    -3.667,  -3.333, 3.333, 2.333,  -2.667,
                        -3.0,   7.0,   4.667,  -2.333,  -2.0,   15.0,  10.333, -1.333};
    c.max_range_m = 200.0;
    c.detection_range_10pct_m = 200.0 / std::sqrt(8.0);  // 200 m on 80 %, as for the VLP-16
    return c;
  }

  // Ouster OS1-64 (gen 1): 64 channels evenly over 33.2 degrees, 1024 x 10 Hz, 120 m;
  // datasheet range precision 1.5-5 cm, taken as 3 cm sigma
  if (model == "os1-64") {
    LidarConfig c;
    c.model = "os1-64";
    c.elevations_deg.clear();
    for (int i = 0; i < 64; ++i) c.elevations_deg.push_back(-16.6 + 33.2 * i / 63.0);
    c.columns = 1024;
    c.max_range_m = 120.0;
    c.min_range_m = 0.8;
    c.range_noise_sigma_m = 0.03;
    c.detection_range_10pct_m = 40.0;  // the datasheet's range on a 10 % target
    c.beam_divergence_mrad = 3.1;      // 0.18 degrees
    return c;
  }
  return std::nullopt;
}

std::vector<std::string> lidar_preset_names() {
  return {"vlp16", "vlp32c", "os1-64"};
}

std::optional<core::Pose3> lidar_mount_preset(std::string_view name) {
  if (name == "front_wing") return LidarConfig::front_wing_mount();
  if (name == "main_hoop") return LidarConfig::main_hoop_mount();
  return std::nullopt;
}

}  // namespace conesim::sensors
