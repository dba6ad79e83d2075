#include "sim/scenario.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>
#include <initializer_list>

#include "core/error.hpp"

namespace conesim::sim {
namespace {

namespace fs = std::filesystem;

// a scenario file in a fresh temporary folder
class ScenarioFile : public ::testing::Test {
 protected:
  fs::path write(const std::string& text, const std::string& name = "s.yaml") {
    dir_ = fs::temp_directory_path() / ("conesim-scenario-" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    const fs::path p = dir_ / name;
    std::ofstream(p) << text;
    return p;
  }
  void TearDown() override { fs::remove_all(dir_); }

  // the message of the InputError that loading throws, or "" when it loads
  std::string error_of(const std::string& text, const std::vector<std::string>& sets = {}) {
    try {
      load_scenario(write(text), sets);
    } catch (const core::InputError& e) {
      return e.what();
    }
    return "";
  }
  // each `--set` of `bad` is refused with an error that names `key`
  void expect_refused(const std::string& key, std::initializer_list<const char*> bad) {
    for (const char* set : bad) {
      const std::string e = error_of("event: trackdrive\n", {set});
      EXPECT_NE(e.find(key), std::string::npos) << set << ": " << e;
    }
  }
  fs::path dir_;
};

TEST_F(ScenarioFile, SlamBlockNamesTheDrivingAndTheShadowBackEnds) {
  const std::string head = "event: trackdrive\nperception: cone_sensor\n";
  // the plain string, and the block with shadows, associations and parameters
  EXPECT_EQ(load_scenario(write(head + "slam: ekf\n")).slam, "ekf");
  const Scenario s = load_scenario(
      write(head +
            "slam:\n  drive: graph\n  shadow: [ekf, 'ekf:jcbb', 'graph:nn']\n"
            "  association: {ekf: scnn}\n  ekf: {confirm_sightings: 2, closure_delay_m: 10}\n"));
  EXPECT_EQ(s.slam, "graph");
  ASSERT_EQ(s.slam_shadows.size(), 3u);
  EXPECT_EQ(s.slam_shadows[0].lane_name(), "ekf");
  EXPECT_EQ(s.slam_shadows[1].lane_name(), "ekf-jcbb");
  EXPECT_EQ(s.slam_shadows[2].lane_name(), "graph-nn");
  EXPECT_EQ(s.slam_association.at("ekf"), slam::AssociationMethod::kScnn);
  EXPECT_EQ(s.slam_settings.ekf.confirm_sightings, 2);
  EXPECT_DOUBLE_EQ(s.slam_settings.ekf.closure_delay_m, 10.0);
  // --set extends the plain string form
  const Scenario set = load_scenario(write(head + "slam: graph\n"), {"slam.shadow=[ekf]"});
  EXPECT_EQ(set.slam, "graph");
  ASSERT_EQ(set.slam_shadows.size(), 1u);
  EXPECT_EQ(set.slam_shadows[0].backend, "ekf");
  EXPECT_EQ(load_scenario(write(head + "slam: graph\n"), {"slam.drive=ekf"}).slam, "ekf");
  // one shadow without brackets
  const Scenario one = load_scenario(write(head + "slam: graph\n"), {"slam.shadow=ekf"});
  ASSERT_EQ(one.slam_shadows.size(), 1u);
  EXPECT_EQ(one.slam_shadows[0].lane_name(), "ekf");
}

TEST_F(ScenarioFile, AblationsAreShadowLanesAndKeys) {
  const std::string head = "event: trackdrive\nperception: cone_sensor\n";
  // NAME[:METHOD][+ABLATION...]: the lane's name keeps them all, in the order given
  const Scenario s = load_scenario(
      write(head + "slam: {drive: graph, shadow: ['graph:ideal+global_only+no_icr',\n"
                   "  graph+no_landmark_edges, 'graph:none', ekf+no_preliminary, odometry,\n"
                   "  'odometry:none']}\n"));
  ASSERT_EQ(s.slam_shadows.size(), 6u);
  EXPECT_EQ(s.slam_shadows[0].lane_name(), "graph-ideal+global_only+no_icr");
  EXPECT_EQ(s.slam_shadows[0].ablations, (std::vector<std::string>{"global_only", "no_icr"}));
  EXPECT_EQ(s.slam_shadows[1].lane_name(), "graph+no_landmark_edges");
  EXPECT_EQ(s.slam_shadows[2].association, slam::AssociationMethod::kNone);
  EXPECT_EQ(s.slam_shadows[3].lane_name(), "ekf+no_preliminary");
  EXPECT_EQ(s.slam_shadows[4].backend, "odometry");
  EXPECT_EQ(s.slam_shadows[5].lane_name(), "odometry-none");
  // the same switches as keys, for every lane of the back-end
  const Scenario k = load_scenario(
      write(head + "slam: {drive: graph, graph: {global_only: true, landmark_edges: false,\n"
                   "  icr: false}, ekf: {preliminary_list: false},\n"
                   "  odometry: {confirm_sightings: 2, nn_radius_m: 0.8}}\n"));
  EXPECT_TRUE(k.slam_settings.graph.global_only);
  EXPECT_FALSE(k.slam_settings.graph.landmark_edges);
  EXPECT_EQ(k.slam_settings.graph.icr_sigma_m, 0.0);
  EXPECT_FALSE(k.slam_settings.ekf.preliminary_list);
  EXPECT_EQ(k.slam_settings.odometry.confirm_sightings, 2);
  EXPECT_DOUBLE_EQ(k.slam_settings.odometry.association.nn_radius_m, 0.8);
  // icr: true keeps today's edge and its sigma
  EXPECT_DOUBLE_EQ(load_scenario(write(head + "slam: {drive: graph, graph: {icr: true}}\n"))
                       .slam_settings.graph.icr_sigma_m,
                   default_slam_settings().graph.icr_sigma_m);
  // dead reckoning may drive
  EXPECT_EQ(load_scenario(write(head + "slam: odometry\n")).slam, "odometry");
}

TEST_F(ScenarioFile, OdometrySensorNoiseIsAScenarioKey) {
  const std::string head = "event: trackdrive\nperception: cone_sensor\nslam: graph\n";
  const Scenario s =
      load_scenario(write(head + "sensors: {imu: {gyro_noise_density_rps_rthz: 1.2e-3},\n"
                                 "  wheel_encoders: {noise_rps: 0.2}}\n"));
  EXPECT_DOUBLE_EQ(s.sensors.imu.gyro_noise_density_rps_rthz, 1.2e-3);
  EXPECT_DOUBLE_EQ(s.sensors.wheel_encoders.noise_rps, 0.2);
  EXPECT_NE(error_of(head + "sensors: {imu: {gyro_noise_density_rps_rthz: -1}}\n")
                .find("sensors.imu.gyro_noise_density_rps_rthz"),
            std::string::npos);
  EXPECT_NE(error_of(head + "sensors: {wheel_encoders: {teeth: 3}}\n")
                .find("sensors.wheel_encoders.teeth: unknown key"),
            std::string::npos);
}

// sensors.realism and the LiDAR's realism keys (issue 17): on by default with the model's
// values, off clears them, a key beside it still applies, bad values refused at their key
TEST_F(ScenarioFile, SensorRealismIsAScenarioKey) {
  const std::string head = "event: trackdrive\nperception: lidar\n";
  const sensors::LidarConfig model = *sensors::lidar_preset("vlp32c");
  const Scenario on = load_scenario(write(head + "sensors: {lidar: {model: vlp32c}}\n"));
  EXPECT_TRUE(on.sensors.realism);
  EXPECT_EQ(on.sensors.lidar_config().detection_range_10pct_m, model.detection_range_10pct_m);
  EXPECT_GT(on.sensors.lidar_config().beam_divergence_mrad, 0.0);
  const Scenario off = load_scenario(
      write(head + "sensors: {realism: off, lidar: {model: vlp32c, range_noise_growth: 2e-4}}\n"));
  EXPECT_FALSE(off.sensors.realism);
  const sensors::LidarConfig ideal = off.sensors.lidar_config();
  EXPECT_EQ(ideal.detection_range_10pct_m, 0.0);
  EXPECT_EQ(ideal.beam_divergence_mrad, 0.0);
  EXPECT_EQ(ideal.range_noise_growth, 2e-4);
  EXPECT_EQ(ideal.elevations_deg, model.elevations_deg);
  EXPECT_NE(
      error_of(head + "sensors: {realism: maybe}\n").find("sensors.realism: expected on or off"),
      std::string::npos);
  EXPECT_NE(error_of(head + "sensors: {lidar: {beam_divergence_mrad: -1}}\n")
                .find("sensors.lidar.beam_divergence_mrad: a full angle in [0, 50] mrad"),
            std::string::npos);
  EXPECT_NE(error_of(head + "sensors: {lidar: {detection_range_10pct_m: 0.5}}\n")
                .find("sensors.lidar.detection_range_10pct_m"),
            std::string::npos);
  // the camera: noise on with realism, off without it unless asked for
  EXPECT_GT(on.sensors.camera.response.full_well_e, 0.0);
  EXPECT_EQ(off.sensors.camera.response.full_well_e, 0.0);
  const Scenario asked = load_scenario(
      write(head +
            "sensors: {realism: off, camera: {full_well_e: 5000, exposure_ev: -0.5, gamma: 2}}\n"));
  EXPECT_EQ(asked.sensors.camera.response.full_well_e, 5000.0);
  EXPECT_EQ(asked.sensors.camera.response.exposure_ev, -0.5);
  EXPECT_EQ(asked.sensors.camera.response.gamma, 2.0);
  EXPECT_NE(
      error_of(head + "sensors: {camera: {gamma: 0}}\n").find("sensors.camera.gamma: expected"),
      std::string::npos);
  // the asphalt's grain and the sun: on with realism, off without it unless asked for
  EXPECT_TRUE(on.sensors.camera.ground_texture);
  EXPECT_EQ(on.sensors.camera.sun_diffuse, sensors::kTypicalSunDiffuse);
  EXPECT_FALSE(off.sensors.camera.ground_texture);
  EXPECT_EQ(off.sensors.camera.sun_diffuse, 0.0);
  EXPECT_EQ(on.sensors.camera.exposure_time_ms, sensors::kTypicalExposureTimeMs);
  EXPECT_EQ(off.sensors.camera.exposure_time_ms, 0.0);
  EXPECT_NE(error_of(head + "sensors: {camera: {exposure_time_ms: -1}}\n")
                .find("sensors.camera.exposure_time_ms: must be 0-50"),
            std::string::npos);
  const Scenario sunny = load_scenario(write(
      head +
      "sensors: {realism: off, camera: {ground_texture: on,\n"
      "  sun: {elevation_deg: 20, azimuth_deg: 270, diffuse: 0.6, shadow_strength: 0.8}}}\n"));
  EXPECT_TRUE(sunny.sensors.camera.ground_texture);
  EXPECT_EQ(sunny.sensors.camera.sun_elevation_deg, 20.0);
  EXPECT_EQ(sunny.sensors.camera.sun_azimuth_deg, 270.0);
  EXPECT_EQ(sunny.sensors.camera.sun_diffuse, 0.6);
  EXPECT_EQ(sunny.sensors.camera.shadow_strength, 0.8);
  EXPECT_NE(error_of(head + "sensors: {camera: {sun: {elevation_deg: 2}}}\n")
                .find("sun.elevation_deg: must be 5-90"),
            std::string::npos);
  EXPECT_NE(error_of(head + "sensors: {camera: {sun: {height: 2}}}\n")
                .find("sensors.camera.sun.height: unknown key"),
            std::string::npos);
}

// world.randomise (issue 17): the sensors' look drawn from the seed, the same for the same seed
// and another for another, every value within its range and recorded; off leaves the defaults
TEST_F(ScenarioFile, RandomisedLookComesFromTheSeed) {
  const std::string text = "event: autocross\nperception: fused\nworld: {randomise: on}\n";
  const Scenario a = load_scenario(write(text), {"seed=5"});
  const Scenario b = load_scenario(write(text), {"seed=5"});
  const Scenario c = load_scenario(write(text), {"seed=6"});
  EXPECT_EQ(a.look, b.look);
  EXPECT_NE(a.look, c.look);
  ASSERT_EQ(a.look.size(), 12u);
  EXPECT_EQ(a.look.at("camera_sun_azimuth_deg"), a.sensors.camera.sun_azimuth_deg);
  EXPECT_EQ(a.look.at("camera_exposure_ev"), a.sensors.camera.response.exposure_ev);
  EXPECT_EQ(a.look.at("camera_full_well_e"), a.sensors.camera.response.full_well_e);
  EXPECT_EQ(a.look.at("camera_light_diffuse"), a.sensors.camera.light_diffuse);
  EXPECT_EQ(a.sensors.camera.validate(), "");
  EXPECT_EQ(a.sensors.lidar_config().validate(), "");
  // over many seeds every value stays in its range and the ranges are used
  double lowest = 1e9, highest = -1e9;
  for (uint64_t seed = 1; seed <= 40; ++seed) {
    const Scenario s = load_scenario(write(text), {"seed=" + std::to_string(seed)});
    const double ev = s.sensors.camera.response.exposure_ev;
    EXPECT_GE(ev, -1.0);
    EXPECT_LE(ev, 1.0);
    EXPECT_GE(s.sensors.camera.response.full_well_e, 3000.0);
    EXPECT_LE(s.sensors.camera.response.full_well_e, 30000.0);
    EXPECT_GE(*s.sensors.lidar_ground_reflectivity, 0.06);
    EXPECT_LE(*s.sensors.lidar_ground_reflectivity, 0.2);
    lowest = std::min(lowest, ev);
    highest = std::max(highest, ev);
  }
  EXPECT_LT(lowest, -0.5);
  EXPECT_GT(highest, 0.5);
  const Scenario plain = load_scenario(write("event: autocross\n"));
  EXPECT_TRUE(plain.look.empty());
  EXPECT_EQ(plain.sensors.camera.response.exposure_ev, 0.0);
  EXPECT_NE(error_of("event: autocross\nworld: {randomise: sometimes}\n")
                .find("world.randomise: expected on or off"),
            std::string::npos);
}

// world.clutter (issue 17): read, 0 by default, a bad value refused at its key with the range
TEST_F(ScenarioFile, ClutterDensityIsAScenarioKey) {
  const std::string head = "event: trackdrive\nperception: lidar\n";
  EXPECT_EQ(load_scenario(write(head)).clutter.objects_per_100m, 0.0);
  EXPECT_FALSE(load_scenario(write(head)).clutter.grass_edge);
  const Scenario s = load_scenario(
      write(head + "world: {clutter: {objects_per_100m: 2.5, margin_m: 4, seed_offset: 7,\n"
                   "  grass_edge: true}}\n"));
  EXPECT_TRUE(s.clutter.grass_edge);
  EXPECT_DOUBLE_EQ(s.clutter.objects_per_100m, 2.5);
  EXPECT_DOUBLE_EQ(s.clutter.margin_m, 4.0);
  EXPECT_EQ(s.clutter.seed_offset, 7u);
  using ::testing::HasSubstr;
  EXPECT_THAT(
      error_of(head + "world: {clutter: {objects_per_100m: 250}}\n"),
      HasSubstr(":3: world.clutter.objects_per_100m: expected a number in [0, 100], got 250"));
  EXPECT_THAT(error_of(head, {"world.clutter.margin_m=0.2"}),
              HasSubstr("--set: world.clutter.margin_m: expected a number in [1, 50], got 0.2"));
  EXPECT_THAT(error_of(head + "world: {clutter: {density: 1}}\n"),
              HasSubstr("world.clutter.density: unknown key; expected one of: objects_per_100m, "
                        "margin_m, spread_m, seed_offset, grass_edge"));
}

// world.ground (issue 17): flat by default, every key read, a bad value refused at its key with
// the range it must lie in
TEST_F(ScenarioFile, GroundShapeIsAScenarioKey) {
  const std::string head = "event: trackdrive\nperception: lidar\n";
  EXPECT_TRUE(load_scenario(write(head)).ground.flat());
  EXPECT_FALSE(load_scenario(write(head)).ground.grade_heading_deg.has_value());
  const Scenario s = load_scenario(
      write(head +
            "world: {ground: {grade_percent: 2, grade_heading_deg: 90, crown_percent: 1.5,\n"
            "  undulation_amplitude_m: 0.1, undulation_wavelength_m: 60, bump_height_m: 0.03,\n"
            "  bump_radius_m: 0.6, bumps_per_100m2: 2, seed_offset: 3}}\n"));
  EXPECT_FALSE(s.ground.flat());
  EXPECT_DOUBLE_EQ(s.ground.grade_percent, 2.0);
  EXPECT_DOUBLE_EQ(s.ground.grade_heading_deg.value_or(0.0), 90.0);
  EXPECT_DOUBLE_EQ(s.ground.crown_percent, 1.5);
  EXPECT_DOUBLE_EQ(s.ground.undulation_amplitude_m, 0.1);
  EXPECT_DOUBLE_EQ(s.ground.undulation_wavelength_m, 60.0);
  EXPECT_DOUBLE_EQ(s.ground.bump_height_m, 0.03);
  EXPECT_DOUBLE_EQ(s.ground.bump_radius_m, 0.6);
  EXPECT_DOUBLE_EQ(s.ground.bumps_per_100m2, 2.0);
  EXPECT_EQ(s.ground.seed_offset, 3u);
  using ::testing::HasSubstr;
  EXPECT_THAT(error_of(head + "world: {ground: {grade_percent: 8}}\n"),
              HasSubstr(":3: world.ground.grade_percent: expected a number in [0, 5], got 8"));
  EXPECT_THAT(error_of(head, {"world.ground.crown_percent=-1"}),
              HasSubstr("--set: world.ground.crown_percent: expected a number in [0, 5], got -1"));
  EXPECT_THAT(error_of(head, {"world.ground.bump_height_m=0.5"}),
              HasSubstr("world.ground.bump_height_m: expected a number in [0, 0.1], got 0.5"));
  EXPECT_THAT(error_of(head, {"world.ground.bump_radius_m=0.05"}),
              HasSubstr("world.ground.bump_radius_m: expected a number in [0.2, 2], got 0.05"));
  EXPECT_THAT(error_of(head, {"world.ground.undulation_wavelength_m=2"}),
              HasSubstr("world.ground.undulation_wavelength_m: expected a number in [10, 200]"));
  EXPECT_THAT(error_of(head + "world: {ground: {slope: 1}}\n"),
              HasSubstr("world.ground.slope: unknown key; expected one of: grade_percent, "
                        "grade_heading_deg, crown_percent"));
}

TEST_F(ScenarioFile, BadAblationsNameTheKeyAndWhatWasExpected) {
  const std::string head = "event: trackdrive\nperception: cone_sensor\n";
  EXPECT_NE(error_of(head + "slam: {drive: graph, shadow: [graph+no_gps]}\n")
                .find("slam.shadow: unknown ablation 'no_gps' in 'graph+no_gps': graph has "
                      "global_only, no_landmark_edges, no_icr"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {drive: graph, shadow: [fastslam1+global_only]}\n")
                .find("unknown ablation 'global_only' in 'fastslam1+global_only': fastslam1 "
                      "has none"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {drive: graph, shadow: [ekf+no_icr]}\n")
                .find("ekf has no_preliminary"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {drive: graph, shadow: ['ekf:none']}\n")
                .find("slam.shadow: none (every observation a new landmark) runs on graph or "
                      "odometry"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {drive: graph, association: none}\n")
                .find("slam.association: none (every observation a new landmark) is for shadow "
                      "back-ends only"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {drive: graph, shadow: ['odometry:tracking']}\n")
                .find("slam.shadow: odometry (dead reckoning) has no track memory"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {drive: graph, graph: {icr: maybe}}\n").find("slam.graph.icr:"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {drive: graph, ekf: {preliminary_list: 3}}\n")
                .find("slam.ekf.preliminary_list:"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {drive: graph, odometry: {confirm_sightings: 0}}\n")
                .find("slam.odometry.confirm_sightings: expected a count >= 1"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {drive: graph, odometry: {reach: 3}}\n")
                .find("slam.odometry.reach: unknown key"),
            std::string::npos);
}

TEST_F(ScenarioFile, BadSlamBlocksNameTheKeyAndWhatWasExpected) {
  const std::string head = "event: trackdrive\nperception: cone_sensor\n";
  EXPECT_NE(error_of(head + "slam: fastslam9\n")
                .find("s.yaml:3: slam: expected none or a SLAM back-end (graph, ekf, fastslam1, "
                      "fastslam2, odometry), got "
                      "'fastslam9'"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {drive: graph, shadow: [ekf, foo]}\n")
                .find("slam.shadow: expected back-ends (graph, ekf"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {drive: graph, shadow: ['ekf:magic']}\n")
                .find("slam.shadow: expected NAME:METHOD with a method of nn, ml, scnn, jcbb, "
                      "tracking"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {drive: graph, association: psychic}\n")
                .find("slam.association: expected an association method (nn, ml, scnn, jcbb, "
                      "tracking, ideal, none), got 'psychic'"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {drive: graph, association: {ekf: x}}\n")
                .find("slam.association.ekf: expected an association method"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {drive: graph, bogus: 1}\n")
                .find("slam.bogus: unknown key; expected one of: drive, shadow, association, ekf, "
                      "fastslam, odometry, graph"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {shadow: [ekf]}\n")
                .find("slam.shadow: shadow back-ends run beside a driving one"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {drive: ekf, ekf: {confirm_sightings: 0}}\n")
                .find("slam.ekf.confirm_sightings: expected a count >= 1"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {drive: graph, graph: {window_poses: 0}}\n")
                .find("slam.graph.window_poses: expected >= 1"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {drive: graph, graph: {track_memory_frames: 0.5}}\n")
                .find("slam.graph.track_memory_frames: expected >= 1 frame"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {drive: graph, graph: {ambiguity_margin: -1}}\n")
                .find("slam.graph.ambiguity_margin: expected a cost margin from 0"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {drive: ekf, ekf: {ambiguity_margin: 101}}\n")
                .find("slam.ekf.ambiguity_margin: expected a cost margin from 0 to 100"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {drive: fastslam2, fastslam: {particles: 0}}\n")
                .find("slam.fastslam.particles: expected a count from 1 to 10000"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {drive: fastslam1, fastslam: {loop_closure_factor: 1.5}}\n")
                .find("slam.fastslam.loop_closure_factor: expected in [0, 1]"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: {drive: fastslam1, fastslam: {parts: 5}}\n")
                .find("slam.fastslam.parts: unknown key"),
            std::string::npos);
  {
    const Scenario f = load_scenario(
        write(head +
              "slam: {drive: fastslam2, shadow: [fastslam1, 'fastslam1:jcbb'],\n"
              "  fastslam: {particles: 20, unseen_penalty: 0.8, loop_closure_factor: 0.7}}\n"));
    EXPECT_EQ(f.slam, "fastslam2");
    ASSERT_EQ(f.slam_shadows.size(), 2u);
    EXPECT_EQ(f.slam_shadows[1].lane_name(), "fastslam1-jcbb");
    EXPECT_EQ(f.slam_settings.fastslam.particles, 20);
    EXPECT_DOUBLE_EQ(f.slam_settings.fastslam.unseen_penalty, 0.8);
    EXPECT_DOUBLE_EQ(f.slam_settings.fastslam.loop_closure.returned_fraction, 0.7);
    // one association for all back-ends reaches the particle filters too
    EXPECT_EQ(load_scenario(write(head + "slam: {drive: graph, association: scnn}\n"))
                  .slam_association.at("fastslam2"),
              slam::AssociationMethod::kScnn);
  }
  EXPECT_NE(error_of(head + "slam: {drive: ekf, ekf: {joint_probability: 2}}\n")
                .find("slam.ekf.joint_probability: expected a probability in (0.5, 1)"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: graph\n", {"slam.shadow=[nope]"})
                .find("--set: slam.shadow: expected back-ends"),
            std::string::npos);
  EXPECT_NE(error_of(head + "slam: [graph]\n").find("slam: expected a map"), std::string::npos);
  // the ideal association reads the labels: a shadow may use it, the driving back-end may not
  EXPECT_NE(error_of(head + "slam: {drive: ekf, association: {ekf: ideal}}\n")
                .find("slam.association: ideal reads the ground-truth labels: it is for shadow "
                      "back-ends only"),
            std::string::npos);
  EXPECT_EQ(error_of(head + "slam: {drive: graph, shadow: ['graph:ideal', 'ekf:ideal']}\n"), "");
}

TEST_F(ScenarioFile, ShippedScenariosLoadForAllFourEvents) {
  for (const char* name : {"skidpad", "acceleration", "autocross", "trackdrive"}) {
    const Scenario s = load_scenario(find_scenario(name));
    EXPECT_EQ(core::to_string(s.event), name);
    EXPECT_FALSE(s.track.file.has_value()) << name << " should run without a track file";
  }
  const Scenario td = load_scenario(find_scenario("trackdrive"));
  EXPECT_EQ(td.track.generate_seed, td.seed);
  EXPECT_EQ(td.driver.trackdrive_laps, 10);
}

TEST_F(ScenarioFile, OverridesApplyBeforeValidation) {
  const fs::path p = write("event: trackdrive\nseed: 4\ntrack: {generate: {}}\n");
  const Scenario s = load_scenario(p, {"seed=9", "driver.fast_speed_mps=12.5"});
  EXPECT_EQ(s.seed, 9u);
  EXPECT_EQ(s.track.generate_seed, 9u);
  EXPECT_DOUBLE_EQ(s.driver.fast_speed_mps, 12.5);
  EXPECT_NE(error_of("event: trackdrive\n", {"driver.fast_speed_mps=-1"}).find("fast_speed_mps"),
            std::string::npos);
  EXPECT_NE(error_of("event: trackdrive\n", {"nonsense"}).find("key.path=value"),
            std::string::npos);
}

TEST_F(ScenarioFile, LapOneGripIsAShareOfTheMeasuredGrip) {
  // lap 1's grip share is its own key, read like the fast laps' and held to (0, 1]
  const Scenario s =
      load_scenario(write("event: autocross\ndriver: {explore_grip_fraction: 0.5}\n"));
  EXPECT_DOUBLE_EQ(s.driver.explore_grip_fraction, 0.5);
  EXPECT_DOUBLE_EQ(load_scenario(write("event: autocross\n")).driver.explore_grip_fraction, 0.55);
  expect_refused("explore_grip_fraction",
                 {"driver.explore_grip_fraction=1.2", "driver.explore_grip_fraction=0"});
}

TEST_F(ScenarioFile, TheTightTurnMarginIsItsOwnKey) {
  // the racing line's margin about the turns near full lock, read like the footprint margin
  // and held to metres from 0 to 2
  const Scenario s =
      load_scenario(write("event: trackdrive\ndriver: {tight_turn_margin_m: 0.4}\n"));
  EXPECT_DOUBLE_EQ(s.driver.tight_turn_margin_m, 0.4);
  const Scenario d = load_scenario(write("event: trackdrive\n"));
  EXPECT_DOUBLE_EQ(d.driver.tight_turn_margin_m, 0.3);
  EXPECT_DOUBLE_EQ(d.driver.footprint_margin_m, 0.3);
  expect_refused("tight_turn_margin_m",
                 {"driver.tight_turn_margin_m=-0.1", "driver.tight_turn_margin_m=nan"});
}

TEST_F(ScenarioFile, GeneratedCircuitTakesAProfile) {
  // the profile by name, the scenario seed when the circuit has none; an unknown name is an
  // error that names the key and the profiles there are
  const Scenario s =
      load_scenario(write("event: autocross\nseed: 5\ntrack: {generate: {profile: hairpins}}\n"));
  EXPECT_EQ(s.track.generate_profile, tracks::GeneratorProfile::kHairpins);
  EXPECT_EQ(s.track.generate_seed, 5u);
  const Scenario t = load_scenario(write("event: trackdrive\ntrack: {generate: {seed: 3}}\n"));
  EXPECT_EQ(t.track.generate_profile, tracks::GeneratorProfile::kStandard);
  const std::string bad =
      error_of("event: trackdrive\ntrack:\n  generate: {seed: 1, profile: wiggly}\n");
  EXPECT_NE(bad.find("track.generate.profile"), std::string::npos) << bad;
  EXPECT_NE(bad.find("straight-into-hairpin"), std::string::npos) << bad;
}

TEST_F(ScenarioFile, BadInputNamesFileLineAndKey) {
  // an unknown key, with its line and the keys that exist
  const std::string unknown = error_of("event: autocross\ndriver:\n  top_speed: 3\n");
  EXPECT_NE(unknown.find("s.yaml:3: driver.top_speed: unknown key"), std::string::npos) << unknown;
  EXPECT_NE(unknown.find("explore_speed_mps"), std::string::npos);
  // not a number, NaN, a bad event, malformed YAML, an empty file, a missing event
  EXPECT_NE(error_of("event: autocross\nseed: abc\n").find("s.yaml:2: seed: expected a"),
            std::string::npos);
  EXPECT_NE(error_of("event: autocross\ndriver: {fast_speed_mps: .nan}\n").find("finite"),
            std::string::npos);
  EXPECT_NE(error_of("event: drag_race\n").find("s.yaml:1: event: expected skidpad"),
            std::string::npos);
  EXPECT_NE(error_of("event: [autocross\n").find("malformed YAML"), std::string::npos);
  EXPECT_NE(error_of("").find("empty scenario"), std::string::npos);
  EXPECT_NE(error_of("seed: 3\n").find("event: missing"), std::string::npos);
  EXPECT_NE(error_of("event: autocross\nsensors: {driver_rate_hz: 33}\n").find("driver_rate_hz"),
            std::string::npos);
  EXPECT_NE(error_of("event: autocross\nvehicle: {mass_kg: -3}\n").find("mass_kg"),
            std::string::npos);
  EXPECT_NE(error_of("event: autocross\nperception: radar\n")
                .find("s.yaml:2: perception: "
                      "expected ground_truth"),
            std::string::npos);
  EXPECT_NE(error_of("event: autocross\nslam: graph\n").find("slam: SLAM needs"),
            std::string::npos);
  EXPECT_NE(error_of("event: autocross\nsensors: {lidar: {latency_s: 0.2}}\n")
                .find("sensors.lidar.latency_s"),
            std::string::npos);
  // a 25 ms period is no whole number of 2 ms physics steps: the camera would fire at 20 Hz
  EXPECT_NE(error_of("event: autocross\nsensors: {camera: {rate_hz: 40}}\n")
                .find("sensors.camera.rate_hz: expected a rate whose period is a whole number of "
                      "physics steps"),
            std::string::npos);
  EXPECT_NE(error_of("event: autocross\nsensors: {driver_rate_hz: 40}\n").find("driver_rate_hz"),
            std::string::npos);
  // SLAM pass criteria: sane values, and only where SLAM runs
  const std::string slam = "event: autocross\nperception: cone_sensor\nslam: graph\n";
  EXPECT_NE(error_of(slam + "pass: {max_map_rmse_m: -1}\n").find("pass.max_map_rmse_m"),
            std::string::npos);
  EXPECT_NE(error_of(slam + "pass: {min_da_correct_fraction: 1.5}\n")
                .find("pass.min_da_correct_fraction: expected a fraction"),
            std::string::npos);
  EXPECT_NE(error_of(slam + "pass: {max_false_loop_closures: x}\n").find("max_false_loop_closures"),
            std::string::npos);
  EXPECT_NE(error_of(slam + "pass: {max_map_missed_fraction: 2}\n")
                .find("pass.max_map_missed_fraction: expected a fraction"),
            std::string::npos);
  EXPECT_NE(
      error_of("event: autocross\npass: {max_map_missed_fraction: 0.1}\n").find("need slam: graph"),
      std::string::npos);
  EXPECT_NE(error_of("event: autocross\npass: {max_ate_rmse_m: 0.2}\n").find("need slam: graph"),
            std::string::npos);
  // the SLAM latency: a time from 0 to 1 s
  EXPECT_NE(error_of(slam + "slam_latency_s: -0.05\n").find("slam_latency_s: expected a latency"),
            std::string::npos);
  EXPECT_NE(error_of(slam + "slam_latency_s: .nan\n").find("slam_latency_s"), std::string::npos);
}

// issue 20 item 1: a whole number is read exactly and never narrowed or wrapped
TEST_F(ScenarioFile, WholeNumbersOutOfRangeAreRefusedNotWrapped) {
  const std::string laps = error_of("event: trackdrive\ndriver: {trackdrive_laps: 4294967297}\n");
  EXPECT_NE(laps.find("s.yaml:2: driver.trackdrive_laps: expected a whole number"),
            std::string::npos)
      << laps;
  const std::string width =
      error_of("event: skidpad\nsensors:\n  camera: {width_px: 4294967936}\n");
  EXPECT_NE(width.find("s.yaml:3: sensors.camera.width_px: expected a whole number"),
            std::string::npos)
      << width;
  EXPECT_NE(error_of("event: skidpad\npass: {max_cones_hit: 2.5}\n").find("pass.max_cones_hit"),
            std::string::npos);
  // within range: digits, or a whole number written as a float
  const Scenario s = load_scenario(write("event: trackdrive\ndriver: {trackdrive_laps: 3.0}\n"));
  EXPECT_EQ(s.driver.trackdrive_laps, 3);
  // wider than the buffer the camera renders into
  EXPECT_NE(error_of("event: skidpad\nsensors: {camera: {width_px: 2000}}\n")
                .find("sensors.camera.width_px: expected at most 1280"),
            std::string::npos);
}

// issue 20 item 7: every 64-bit seed reads exactly; command-line values are blamed on the option
TEST_F(ScenarioFile, SeedsReadExactlyAndOptionsAreNamed) {
  const fs::path p = write("event: skidpad\n");
  EXPECT_EQ(load_scenario(p, {}, 9007199254740993ull).seed, 9007199254740993ull);
  EXPECT_EQ(load_scenario(p, {"seed=18446744073709551615"}).seed, 18446744073709551615ull);
  EXPECT_EQ(load_scenario(write("event: skidpad\nseed: 9007199254740993\n")).seed,
            9007199254740993ull);
  // a bad --set value names --set and the key, not the file's first line
  const std::string bad_seed = error_of("event: skidpad\n", {"seed=18446744073709551616"});
  EXPECT_EQ(bad_seed.rfind("--set: seed: expected a whole number", 0), 0u) << bad_seed;
  const std::string bad_speed = error_of("event: skidpad\n", {"driver.fast_speed_mps=-1"});
  EXPECT_EQ(bad_speed.rfind("--set: driver.fast_speed_mps: expected", 0), 0u) << bad_speed;
  const std::string empty = error_of("event: skidpad\n", {"driver.fast_speed_mps="});
  EXPECT_NE(empty.find("--set: driver.fast_speed_mps: expected a value after '=', got nothing"),
            std::string::npos)
      << empty;
  // the file's own mistakes still name the file and line of the key
  const std::string in_file = error_of("event: skidpad\ndriver:\n  fast_speed_mps: -1\n");
  EXPECT_NE(in_file.find("s.yaml:3: driver.fast_speed_mps: expected"), std::string::npos)
      << in_file;
}

// issue 20 item 3: the referee's values are checked with the scenario, naming the key
TEST_F(ScenarioFile, RefereeValuesAreCheckedWithTheScenario) {
  EXPECT_NE(error_of("event: skidpad\n", {"referee.cone_penalty_s=-5"})
                .find("--set: referee.cone_penalty_s: expected a number >= 0"),
            std::string::npos);
  EXPECT_NE(error_of("event: skidpad\nreferee:\n  stuck_time_s: 0\n")
                .find("s.yaml:3: referee.stuck_time_s: expected a number > 0"),
            std::string::npos);
  // item 2: a timeout past what a run can last
  EXPECT_NE(error_of("event: skidpad\n", {"referee.timeout_skidpad_s=1e13"})
                .find("--set: referee.timeout_skidpad_s: expected at most 100000 s"),
            std::string::npos);
}

// issue 20 item 5: the name becomes a folder under runs/, so it must be a plain name
TEST_F(ScenarioFile, NameMustBeAPlainFolderName) {
  for (const char* name : {"/tmp/elsewhere", "../../x", "a/b", "..", "''", "\"a\\tb\""}) {
    const std::string e = error_of(std::string("name: ") + name + "\nevent: skidpad\n");
    EXPECT_NE(e.find("s.yaml:1: name: expected a plain name"), std::string::npos)
        << name << ": " << e;
  }
  EXPECT_NE(error_of("event: skidpad\n", {"name=../x"}).find("--set: name: expected a plain"),
            std::string::npos);
  EXPECT_EQ(load_scenario(write("name: my-run_2.b\nevent: skidpad\n")).name, "my-run_2.b");
}

// issue 20 items 6 and 8: complex keys are bad input; a key given twice is a warning with its
// lines; a sensor switched off cannot feed the perception that needs it
TEST_F(ScenarioFile, ComplexKeysDuplicatesAndContradictions) {
  EXPECT_NE(error_of("event: skidpad\n? [a, b]\n: 1\n").find("s.yaml:2: top level: expected key"),
            std::string::npos);
  const Scenario s = load_scenario(write("event: skidpad\nevent: acceleration\n"));
  EXPECT_EQ(core::to_string(s.event), "acceleration");
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("s.yaml:2: event: given again (also on line 1)"), std::string::npos)
      << s.warnings[0];
  // --set reaches the key that counts
  const Scenario d = load_scenario(
      write("event: skidpad\ndriver: {fast_speed_mps: 5}\ndriver: {fast_speed_mps: 6}\n"),
      {"driver.fast_speed_mps=7"});
  EXPECT_DOUBLE_EQ(d.driver.fast_speed_mps, 7.0);
  EXPECT_NE(error_of("event: skidpad\nperception: lidar\nsensors: {lidar: {enabled: false}}\n")
                .find("s.yaml:3: sensors.lidar.enabled: false contradicts perception: lidar"),
            std::string::npos);
  EXPECT_NE(error_of("event: skidpad\nperception: stereo\n", {"sensors.camera.enabled=false"})
                .find("--set: sensors.camera.enabled: false contradicts perception: stereo"),
            std::string::npos);
  EXPECT_NE(error_of("event: skidpad\nperception: fused\n", {"sensors.camera.enabled=no"})
                .find("sensors.camera.enabled"),
            std::string::npos);
}

TEST_F(ScenarioFile, UnknownScenarioNameListsTheShippedOnes) {
  try {
    find_scenario("trackdirve");
    FAIL() << "a misspelt scenario was accepted";
  } catch (const core::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("trackdrive"), std::string::npos);
  }
}

TEST_F(ScenarioFile, DefaultVehicleFileMatchesTheBuiltInDefaults) {
  const auto file =
      load_vehicle(fs::path(CONESIM_SOURCE_DIR) / "vehicle_models/params/default.yaml");
  const vehicle_models::VehicleParams builtin;
  EXPECT_EQ(file.name, builtin.name);
  EXPECT_DOUBLE_EQ(file.mass_kg, builtin.mass_kg);
  EXPECT_DOUBLE_EQ(file.ackermann_factor, builtin.ackermann_factor);
  EXPECT_DOUBLE_EQ(file.max_power_w, builtin.max_power_w);
  EXPECT_DOUBLE_EQ(file.suspension_travel_m, builtin.suspension_travel_m);
}

}  // namespace
}  // namespace conesim::sim
