#pragma once
// Configuration of the spinning LiDAR: the beam pattern of the model, the mount on the car,
// the reflectivity of each surface and the noise and faults. Presets by name.

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/measurements.hpp"
#include "core/time.hpp"
#include "sensors/cone_mesh.hpp"

namespace conesim::sensors {

/// Diffuse reflectivity (0-1) of each surface: white and yellow paint bright, black and blue
/// dark, orange in between, asphalt dark.
struct Reflectivity {
  double ground = 0.12;
  double blue = 0.15;
  double yellow = 0.65;
  double orange = 0.45;
  double white = 0.85;
  double black = 0.05;

  /// The reflectivity of a material.
  double of(SurfaceMaterial m) const;
};

/// A spinning multi-beam LiDAR. The defaults are a Velodyne VLP-16 (datasheet 63-9229 Rev-C:
/// 16 channels from -15 to +15 degrees every 2 degrees, 0.2 degrees azimuth at 10 Hz, 100 m range,
/// range accuracy "up to +-3 cm (typical)") on the front wing. The sensor frame is x forward,
/// y left, z up; ring 0 is the lowest beam.
struct LidarConfig {
  /// Model name, for reports.
  std::string model = "vlp16";
  /// Elevation of each channel, degrees, any order (rings are numbered by elevation).
  std::vector<double> elevations_deg{-15, -13, -11, -9, -7, -5, -3, -1, 1, 3, 5, 7, 9, 11, 13, 15};
  /// Azimuth columns in one revolution (1800: 0.2 degrees).
  int columns = 1800;
  /// Revolutions per second; one sweep lasts 1 / rate_hz.
  double rate_hz = 10.0;
  /// Returns nearer than this are not reported.
  double min_range_m = 0.4;
  /// Returns farther than this are missed.
  double max_range_m = 100.0;
  /// Azimuth of the first column, degrees from the sensor's x axis (180: the sweep starts and
  /// ends behind the car, as drivers cut the scan by default).
  double start_azimuth_deg = 180.0;
  /// Spin direction seen from above (Velodyne and Ouster spin clockwise).
  bool clockwise = true;
  /// Sensor frame in the vehicle frame (rear axle centre on the ground, x forward, z up).
  core::Pose3 mount = front_wing_mount();

  /// Gaussian range noise, metres. 0.015 m reads the VLP-16 datasheet's "+-3 cm typical" as a
  /// two-sigma bound (95 % of returns within 3 cm).
  double range_noise_sigma_m = 0.015;
  /// Growth of the range noise's sigma with range: sigma(r) = range_noise_sigma_m +
  /// range_noise_growth * r. 1e-4 (1 cm more at 100 m) is a choice: the datasheets give one
  /// figure for the whole range.
  double range_noise_growth = 1e-4;
  /// Range at which a diffuse target of 10 % reflectivity at normal incidence returns with
  /// probability one half; the return's signal (reflectivity times the cosine of incidence over
  /// the squared range) sets the probability of every return, so dark surfaces and grazing
  /// ground fade first. 0: every return is kept. 35 m reads the VLP-16's 100 m as the range on an
  /// 80 % target (the range goes with the square root of the reflectivity: 100 / sqrt(8)).
  double detection_range_10pct_m = 35.0;
  /// Full horizontal beam divergence, mrad (Velodyne: 3.0). A beam whose spot falls partly on a
  /// cone gives a mixed return at its edge: the spot is cast as three rays across its width,
  /// echoes nearer each other than echo_merge_m merge at their energy-weighted range and the
  /// strongest echo is the return. 0: a thin ray.
  double beam_divergence_mrad = 3.0;
  /// Echoes closer than this merge into one return (about half the pulse's length).
  double echo_merge_m = 0.5;
  /// Probability that a return is lost (fault injection).
  double dropout_probability = 0.0;
  /// Gaussian noise on the 0-255 intensity.
  double intensity_noise_sigma = 3.0;
  /// Residual range fall-off of the intensity after the sensor's own compensation:
  /// gain 1 / (1 + (range / falloff)^2).
  double intensity_falloff_m = 40.0;
  /// Reflectivity of each surface.
  Reflectivity reflectivity;
  /// Facets of the cone meshes (24: the mesh lies within 1 mm of the true cone).
  int cone_mesh_sides = 24;

  /// Today's idealised sensor, as with `sensors.realism: off`: range noise constant over range,
  /// no fading of weak returns, thin rays.
  void clear_realism();

  /// Duration of one sweep, microseconds.
  core::TimeUs sweep_period_us() const;
  /// Empty when every value is usable; otherwise "key: what was expected" for the first bad one.
  std::string validate() const;

  /// The front wing mount: 2.1 m ahead of the rear axle, 0.18 m above the ground, level.
  static core::Pose3 front_wing_mount();
  /// The main hoop mount: 0.6 m ahead of the rear axle, 1.0 m above the ground, level.
  static core::Pose3 main_hoop_mount();
};

/// A model preset: "vlp16", "vlp32c" (Velodyne VLP-32C: 32 channels from -25 to +15 degrees,
/// 0.2 degrees at 10 Hz, 200 m) or "os1-64" (Ouster OS1-64: 64 channels evenly over 33.2
/// degrees, 1024 columns at 10 Hz, 120 m, 0.03 m range noise). Nullopt for an unknown name.
std::optional<LidarConfig> lidar_preset(std::string_view model);

/// The names lidar_preset() knows.
std::vector<std::string> lidar_preset_names();

/// A mount preset: "front_wing" or "main_hoop". Nullopt for an unknown name.
std::optional<core::Pose3> lidar_mount_preset(std::string_view name);

}  // namespace conesim::sensors
