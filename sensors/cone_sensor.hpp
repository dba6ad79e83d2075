#pragma once
// A detection-level cone sensor, like FSSIM's and PacSim's mock perception: cones within a
// field of view and range, with range and bearing noise, detection probability falling with
// distance, colour known only close by, colour confusion, false positives and latency.

#include <functional>
#include <string>
#include <utility>

#include "core/autonomy_types.hpp"
#include "core/measurements.hpp"
#include "core/rng.hpp"
#include "sensors/vehicle_sensors.hpp"
#include "tracks/track.hpp"

namespace conesim::sensors {

/// Defaults follow FSSIM's LiDAR pipeline model: range sigma 0.05 m, bearing sigma 0.007 rad,
/// 15 m radius, colour known within 10 m with likelihood 0.8.
struct ConeSensorConfig {
  SensorTiming timing{10.0, 0.05};
  /// Mount point ahead of the rear axle (front-wing LiDAR), metres.
  double mount_x_m = 2.1;
  double min_range_m = 1.0;
  double max_range_m = 15.0;
  double fov_deg = 180.0;
  double range_sigma_m = 0.05;
  double bearing_sigma_rad = 0.007;
  /// Colour is reported within this range, with this probability (else unknown).
  double colour_range_m = 10.0;
  double colour_probability = 0.8;
  /// Probability that a reported colour is the wrong one (blue <-> yellow, orange -> unknown).
  double colour_confusion_probability = 0.01;
  /// Detection probability: constant up to falloff_start_m, then linear to far at max range.
  double detection_probability_near = 0.98;
  double detection_probability_far = 0.7;
  double detection_falloff_start_m = 10.0;
  /// Mean number of false positives per frame (Poisson), placed uniformly in the field of view.
  double false_positives_per_frame = 0.05;

  std::string validate() const;
};

/// The cone sensor. Observations are in the vehicle frame; labels carry the true cone ids.
class ConeSensor {
 public:
  ConeSensor(const ConeSensorConfig& config, uint64_t seed);

  /// Observes the track from the vehicle pose at truth.stamp; cones for which is_knocked is
  /// true are not seen.
  std::pair<core::ConeObservations, core::ObservationLabels> sample(
      const tracks::Track& track, const core::Pose2& vehicle_pose, core::TimeUs stamp,
      const std::function<bool(int)>& is_knocked);

  /// Probability of detecting a cone at this range.
  double detection_probability(double range_m) const;

  const ConeSensorConfig& config() const { return config_; }

 private:
  core::ConeObservation make_observation(double range_m, double bearing_rad);

  ConeSensorConfig config_;
  core::Rng rng_;
};

}  // namespace conesim::sensors
