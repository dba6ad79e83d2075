#include "sensors/cone_sensor.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>

#include "core/validate.hpp"

namespace conesim::sensors {

namespace {

std::string check(const std::string& key, double v, double lo, double hi) {
  return core::check_range("cone_sensor." + key, v, lo, hi);
}

// a Poisson count by inversion (small means only)
int poisson(core::Rng& rng, double mean) {
  const double limit = std::exp(-mean);
  double p = core::uniform(rng, 0.0, 1.0);
  int k = 0;
  while (p > limit && k < 1000) {
    p *= core::uniform(rng, 0.0, 1.0);
    ++k;
  }
  return k;
}

// the colour perception reports for a true class, given it is confused
core::ConeClass confused(core::ConeClass c) {
  using core::ConeClass;
  switch (c) {
    case ConeClass::kBlue:
      return ConeClass::kYellow;
    case ConeClass::kYellow:
      return ConeClass::kBlue;
    case ConeClass::kOrangeBig:
      return ConeClass::kOrangeSmall;
    default:
      return ConeClass::kUnknown;
  }
}

}  // namespace

std::string ConeSensorConfig::validate() const {
  for (const std::string& e :
       {timing.validate("cone_sensor"), check("mount_x_m", mount_x_m, -5, 5),
        check("min_range_m", min_range_m, 0, max_range_m),
        check("max_range_m", max_range_m, 0.5, 200), check("fov_deg", fov_deg, 1, 360),
        check("range_sigma_m", range_sigma_m, 0, 5),
        check("bearing_sigma_rad", bearing_sigma_rad, 0, 0.5),
        check("colour_range_m", colour_range_m, 0, 200),
        check("colour_probability", colour_probability, 0, 1),
        check("colour_confusion_probability", colour_confusion_probability, 0, 1),
        check("detection_probability_near", detection_probability_near, 0, 1),
        check("detection_probability_far", detection_probability_far, 0, 1),
        check("detection_falloff_start_m", detection_falloff_start_m, 0, 200),
        check("false_positives_per_frame", false_positives_per_frame, 0, 100)}) {
    if (!e.empty()) return e;
  }
  return {};
}

ConeSensor::ConeSensor(const ConeSensorConfig& config, uint64_t seed)
    : config_(config), rng_(seed) {}

double ConeSensor::detection_probability(double range_m) const {
  const auto& c = config_;
  if (range_m <= c.detection_falloff_start_m || c.max_range_m <= c.detection_falloff_start_m)
    return c.detection_probability_near;
  const double s = std::clamp(
      (range_m - c.detection_falloff_start_m) / (c.max_range_m - c.detection_falloff_start_m), 0.0,
      1.0);
  return c.detection_probability_near +
         s * (c.detection_probability_far - c.detection_probability_near);
}

core::ConeObservation ConeSensor::make_observation(double range_m, double bearing_rad) {
  // polar noise at the mount, then into the vehicle frame with its covariance
  const double r = std::max(0.0, range_m + core::gaussian(rng_, 0.0, config_.range_sigma_m));
  const double b = bearing_rad + core::gaussian(rng_, 0.0, config_.bearing_sigma_rad);
  core::ConeObservation o;
  o.position = {config_.mount_x_m + r * std::cos(b), r * std::sin(b)};
  Eigen::Matrix2d jacobian;
  jacobian << std::cos(b), -r * std::sin(b), std::sin(b), r * std::cos(b);
  const Eigen::Matrix2d polar =
      Eigen::Vector2d(config_.range_sigma_m * config_.range_sigma_m,
                      config_.bearing_sigma_rad * config_.bearing_sigma_rad)
          .asDiagonal();
  o.covariance = jacobian * polar * jacobian.transpose() + Eigen::Matrix2d::Identity() * 1e-8;
  return o;
}

std::pair<core::ConeObservations, core::ObservationLabels> ConeSensor::sample(
    const tracks::Track& track, const core::Pose2& vehicle_pose, core::TimeUs stamp,
    const std::function<bool(int)>& is_knocked) {
  const auto& c = config_;
  const core::Pose2 mount = vehicle_pose.compose({c.mount_x_m, 0.0, 0.0});
  const double half_fov = 0.5 * c.fov_deg * std::numbers::pi / 180.0;
  core::ConeObservations obs;
  obs.stamp = stamp;
  core::ObservationLabels labels;

  // true cones in view, each detected with its range's probability
  for (const tracks::Cone& cone : track.cones) {
    const core::Vec2 local = mount.inverse_transform(cone.position);
    const double range = local.norm();
    if (range < c.min_range_m || range > c.max_range_m) continue;
    const double bearing = std::atan2(local.y(), local.x());
    if (std::abs(bearing) > half_fov) continue;
    if (is_knocked && is_knocked(cone.id)) continue;
    if (!core::bernoulli(rng_, detection_probability(range))) continue;

    core::ConeObservation o = make_observation(range, bearing);
    // colour: known close by with some probability, and now and then the wrong one
    o.cls = core::ConeClass::kUnknown;
    if (range <= c.colour_range_m && core::bernoulli(rng_, c.colour_probability)) {
      o.cls = core::bernoulli(rng_, c.colour_confusion_probability) ? confused(cone.cls) : cone.cls;
    }
    obs.cones.push_back(o);
    labels.cone_id.push_back(cone.id);
  }

  // false positives, anywhere in the field of view
  const int spurious = poisson(rng_, c.false_positives_per_frame);
  for (int i = 0; i < spurious; ++i) {
    const double range = core::uniform(rng_, c.min_range_m, c.max_range_m);
    const double bearing = core::uniform(rng_, -half_fov, half_fov);
    core::ConeObservation o = make_observation(range, bearing);
    o.cls = core::ConeClass::kUnknown;
    obs.cones.push_back(o);
    labels.cone_id.push_back(core::ObservationLabels::kFalsePositive);
  }
  return {obs, labels};
}

}  // namespace conesim::sensors
