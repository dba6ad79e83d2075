#pragma once
// Scenarios: what to run (event, track, vehicle, seed, perception, SLAM, driver, sensors) and
// what counts as a pass. Read from YAML here, at the edge; the rest of conesim sees structs.

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "control/driver.hpp"
#include "core/event.hpp"
#include "sensors/cone_sensor.hpp"
#include "sensors/lidar_config.hpp"
#include "sensors/stereo_camera.hpp"
#include "sensors/vehicle_sensors.hpp"
#include "sim/autonomy.hpp"
#include "sim/faults.hpp"
#include "sim/referee.hpp"
#include "slam/factory.hpp"
#include "tracks/generator.hpp"
#include "tracks/ground.hpp"
#include "tracks/scenery.hpp"
#include "vehicle_models/vehicle_params.hpp"

namespace conesim::sim {

/// Where the track comes from: a file, or the FSG layout / a generated circuit.
struct TrackSource {
  /// A track file (any format tracks::read_track reads); relative paths are resolved against
  /// the scenario file's folder, then the working directory.
  std::optional<std::filesystem::path> file;
  /// Seed of a generated circuit (autocross, trackdrive); defaults to the scenario seed.
  std::optional<uint64_t> generate_seed;
  /// Profile of a generated circuit (`track: {generate: {profile: hairpins}}`).
  tracks::GeneratorProfile generate_profile = tracks::GeneratorProfile::kStandard;
};

/// Rates and ranges of what the car perceives (the cone sensor and the schedule).
struct SensorSettings {
  /// How often perception, SLAM and the driver run, Hz (a divisor of 1 MHz).
  double driver_rate_hz = 20.0;
  /// Perfect perception: cones within this range and field of view are seen.
  double cone_range_m = 20.0;
  double cone_fov_deg = 200.0;
  /// The detection-level cone sensor (`perception: cone_sensor`).
  sensors::ConeSensorConfig cone_sensor;
  /// Run the perception's tracker on the cone sensor's frames (`sensors.cone_sensor.track`):
  /// observations get track ids (for tracking-aided association) and the tracks' colour votes.
  bool cone_sensor_track = false;
  /// The LiDAR sweeps while the car drives when enabled (or dumped).
  bool lidar_enabled = false;
  /// A preset of sensors::lidar_preset (vlp16, vlp32c, os1-64) and a mount preset.
  std::string lidar_model = "vlp16";
  std::string lidar_mount = "front_wing";
  /// `sensors.realism`: on, each sensor model's realism (the LiDAR's range noise growing with
  /// range, weak returns fading, a spot with a width); off, the ideal sensors of before.
  bool realism = true;
  /// `sensors.lidar.<key>`: the model's noise and realism overridden (unset: the model's).
  std::optional<double> lidar_range_noise_sigma_m, lidar_range_noise_growth,
      lidar_detection_range_10pct_m, lidar_beam_divergence_mrad;
  /// The LiDAR's range noise and detection range times these, and the asphalt's reflectivity
  /// (`world.randomise` draws them; 1, 1 and the model's otherwise).
  double lidar_range_noise_scale = 1.0, lidar_detection_range_scale = 1.0;
  std::optional<double> lidar_ground_reflectivity;
  /// The LiDAR these settings describe: the model's preset on its mount, its realism cleared
  /// when realism is off, then the overrides (std::invalid_argument for an unknown model).
  sensors::LidarConfig lidar_config() const;
  /// Time from a sweep's end until its cones reach SLAM (`perception: lidar|fused`), seconds;
  /// less than one sweep.
  double lidar_latency_s = 0.05;
  /// The stereo camera renders at camera_rate_hz when enabled (or dumped).
  bool camera_enabled = false;
  double camera_rate_hz = 10.0;
  bool camera_depth = false;
  /// Time from an exposure until its cones reach SLAM (`perception: stereo`), seconds.
  double camera_latency_s = 0.05;
  sensors::StereoCameraConfig camera;
  /// The IMU and wheel encoders that feed SLAM's odometry (`sensors.imu`,
  /// `sensors.wheel_encoders`: their noise).
  sensors::ImuConfig imu;
  sensors::WheelEncoderConfig wheel_encoders;
};

/// What a run must achieve to pass.
struct PassCriteria {
  bool completed = true;
  int max_cones_hit = 0;
  int max_off_course = 0;
  /// Upper bound of the final time, seconds (0: none).
  double max_final_time_s = 0.0;
  /// The SLAM estimate's quality (runs with slam only; unset: not checked): map and trajectory
  /// RMSE against the truth (metrics.json slam.<backend>.map_rmse_m and ate_rmse_m), m, the
  /// fraction of correct associations and the false loop closures allowed.
  std::optional<double> max_map_rmse_m;
  std::optional<double> max_ate_rmse_m;
  std::optional<double> min_da_correct_fraction;
  std::optional<int> max_false_loop_closures;
  /// The largest share of the true cones in the perception's view that the map may miss
  /// (metrics.json slam.<backend>.map_missed_fraction: map_missed / map_cones_in_view).
  std::optional<double> max_map_missed_fraction;
};

/// A shadow back-end: its name, when given (`ekf:jcbb`) its association method, and the
/// ablations it runs with (`graph:ideal+global_only+no_icr`, see slam_ablations()).
struct SlamShadow {
  std::string backend;
  std::optional<slam::AssociationMethod> association;
  std::vector<std::string> ablations;
  /// The lane's name in outputs: the back-end's, with "-METHOD" when a method is given and
  /// "+ABLATION" for each ablation.
  std::string lane_name() const {
    std::string name =
        association ? backend + "-" + std::string(slam::to_string(*association)) : backend;
    for (const std::string& a : ablations) name += "+" + a;
    return name;
  }
};

/// The ablations a back-end can run with as a shadow (`NAME+ABLATION`): graph's
/// global_only, no_landmark_edges and no_icr (RaceUp), ekf's no_preliminary (Monash); none for
/// the others.
const std::vector<std::string>& slam_ablations(const std::string& backend);

/// The back-ends' parameters as conesim runs them: GraphSLAM's no-lateral-motion constraint
/// allows the MuJoCo car's rear-axle slip (slip angles up to about 1 degree).
inline slam::BackendSettings default_slam_settings() {
  slam::BackendSettings settings;
  settings.graph.icr_sigma_m = 0.3;
  return settings;
}

/// One scenario, fully resolved.
struct Scenario {
  std::string name;
  core::EventType event = core::EventType::kTrackdrive;
  TrackSource track;
  /// "default" or a vehicle YAML file.
  std::string vehicle_source = "default";
  vehicle_models::VehicleParams vehicle;
  uint64_t seed = 1;
  /// ground_truth, cone_sensor (detection-level mock), or raw-data perception: lidar, stereo,
  /// fused (LiDAR cones coloured by the camera).
  std::string perception = "ground_truth";
  /// The back-end that drives the car: none, graph, ekf (`slam: NAME` or `slam.drive`).
  std::string slam = "none";
  /// Back-ends run beside it on the same input, scored only (`slam.shadow`).
  std::vector<SlamShadow> slam_shadows;
  /// The association method per back-end name (`slam.association`); a back-end not named
  /// keeps its own default.
  std::map<std::string, slam::AssociationMethod> slam_association;
  /// Every back-end's parameters (`slam.graph`, `slam.ekf`, `slam.fastslam`, `slam.odometry`).
  slam::BackendSettings slam_settings = default_slam_settings();
  /// How long a SLAM update takes on the sim clock, seconds: its estimate reaches the driver at
  /// the first driver tick this long after the frame's delivery, and meanwhile the driver has
  /// the previous estimate carried forward by the odometry. 0: at once (the update takes no
  /// time). With more, the update runs on a thread of its own while the car drives on.
  double slam_latency_s = 0.0;
  control::DriverParams driver;
  /// Plug-ins of the stack (`autonomy: {perception|slam|driver: plugin:PATH}`); unset for the
  /// built-in one. With a perception plug-in `perception` is "plugin"; with a SLAM plug-in
  /// `slam` is "plugin:NAME".
  std::optional<PluginSpec> perception_plugin;
  std::optional<PluginSpec> slam_plugin;
  std::optional<PluginSpec> driver_plugin;
  SensorSettings sensors;
  RefereeParams referee;
  PassCriteria pass;
  /// The car stands still this long before the driver may go (the go signal), seconds; the
  /// odometry learns the gyro bias meanwhile.
  double start_delay_s = 1.0;
  /// Scenery and clutter beside the track (`world.clutter`): seen by the LiDAR and the
  /// camera, never by the physics. A density of 0 (the default) places nothing.
  tracks::ClutterConfig clutter;
  /// The ground under the track (`world.ground`): one height model for the physics, the LiDAR,
  /// the camera and the cones. All zero (the default) is the flat plane z = 0.
  tracks::GroundConfig ground;
  /// `world.randomise`: the sensors' look drawn from the seed (domain randomisation): the
  /// camera's light, exposure and noise, the LiDAR's noise, fading and the asphalt's
  /// reflectivity. What was drawn, by key, for metrics.json's world.look (empty when off).
  bool randomise = false;
  std::map<std::string, double> look;
  /// Sensor and vehicle faults (`faults:`), in the order read: kinds in fault_kind_names()
  /// order, each kind's windows in the order given. Empty: none.
  std::vector<Fault> faults;
  /// Where the scenario was read from (empty for a built-in default).
  std::filesystem::path source_file;
  /// What the reader let pass but the user should hear of ("file:line: key: given again").
  std::vector<std::string> warnings;
};

/// Finds a scenario by file path or by the name of a shipped one (scenarios/<name>.yaml).
/// Throws core::InputError when neither exists.
std::filesystem::path find_scenario(const std::string& name_or_path);

/// Reads a scenario file, applying `seed` (as --seed gives it) and then `overrides`
/// ("key.path=value", as --set gives them) before the values are checked. Every value is checked
/// here, before anything runs or is written. Throws core::InputError naming the file, line and key,
/// or the option ("--set: key: ...", "--seed: ...") for a value from the command line. A key
/// given twice is a warning in Scenario::warnings, and the last one counts.
Scenario load_scenario(const std::filesystem::path& file,
                       const std::vector<std::string>& overrides = {},
                       std::optional<uint64_t> seed = std::nullopt);

/// world.randomise: draws the sensors' look from the scenario's seed into `s` (overriding what
/// the scenario said of those keys) and records it in s.look. load_scenario calls it.
void randomise_look(Scenario& s);

/// Reads a vehicle parameter file (keys of VehicleParams). Throws core::InputError.
vehicle_models::VehicleParams load_vehicle(const std::filesystem::path& file);

/// The folder of the shipped scenarios (next to the executable's source tree).
std::filesystem::path shipped_scenarios_dir();

}  // namespace conesim::sim
