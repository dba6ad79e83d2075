#include "slam/backends/dead_reckoning.hpp"

#include <Eigen/Geometry>
#include <chrono>
#include <cmath>

#include "slam/odometry.hpp"

namespace conesim::slam {

std::string DeadReckoningConfig::validate() const {
  if (confirm_sightings < 1) return "confirm_sightings: expected a count >= 1";
  if (!(tentative_max_travel_m > 0.0)) return "tentative_max_travel_m: expected > 0 m";
  if (!(reach_m > 0.0)) return "reach_m: expected > 0 m";
  if (!(association.nn_radius_m > 0.0)) return "nn_radius_m: expected > 0 m";
  if (association.method == AssociationMethod::kTrackingAided)
    return "association: tracking needs a back-end that keeps track memory; expected nn, ml, "
           "scnn, jcbb, ideal or none";
  return "";
}

DeadReckoning::DeadReckoning(const DeadReckoningConfig& config) : config_(config) {
  reset({}, 0);
}

void DeadReckoning::reset(const core::Pose2& initial_pose, core::TimeUs stamp) {
  pose_ = initial_pose;
  pose_covariance_ = Eigen::Vector3d(1e-6, 1e-6, 1e-8).asDiagonal();
  landmarks_.clear();
  associations_.clear();
  stamp_ = stamp;
  localising_ = false;
  travel_m_ = 0.0;
  speed_mps_ = 0.0;
  yaw_rate_rps_ = 0.0;
}

void DeadReckoning::set_prior_map(const std::vector<core::MapCone>& map) {
  // a known layout: its cones, fixed; observations are then only paired, never added
  landmarks_.clear();
  for (const core::MapCone& cone : map) {
    Landmark lm;
    lm.id = static_cast<int>(landmarks_.size());
    lm.sum = cone.position;
    lm.covariance_sum = cone.covariance;
    if (cone.cls != core::ConeClass::kUnknown) lm.class_votes[static_cast<int>(cone.cls)] = 100;
    lm.sightings = 1;
    lm.fixed = true;
    landmarks_.push_back(lm);
  }
  localising_ = true;
}

void DeadReckoning::process(const SlamInput& input) {
  // predict, associate, place the observations; nothing ever corrects the pose
  predict(input.odometry);
  associate(input);
  update(input.observations);
}

void DeadReckoning::predict(const OdometryDelta& odometry) {
  // the odometry composed onto the pose, its covariance grown by the delta's
  const core::Pose2 from = pose_;
  pose_ = from.compose(odometry.delta);
  pose_covariance_ = compose_covariance(from, odometry, pose_covariance_);
  stamp_ = odometry.to;
  travel_m_ += odometry.distance_m;
  speed_mps_ = odometry.speed_mps;
  yaw_rate_rps_ = odometry.yaw_rate_rps;
}

void DeadReckoning::associate(const SlamInput& input) {
  // the landmarks in reach, then the configured method; forgotten ones take no part
  const auto start = std::chrono::steady_clock::now();
  std::vector<LandmarkCandidate> candidates;
  if (config_.association.method != AssociationMethod::kNone) {
    for (Landmark& lm : landmarks_) {
      if (lm.forgotten) continue;
      if (!lm.confirmed(confirm_sightings()) &&
          travel_m_ - lm.first_travel_m > config_.tentative_max_travel_m) {
        lm.forgotten = true;
        continue;
      }
      const core::Vec2 p = lm.position();
      if ((p - pose_.position()).norm() > config_.reach_m) continue;
      LandmarkCandidate c;
      c.id = lm.id;
      c.position = p;
      c.covariance = lm.covariance_sum / static_cast<double>(lm.sightings * lm.sightings);
      c.class_votes = lm.class_votes;
      c.label = lm.label;
      candidates.push_back(c);
    }
  }
  AssociationConfig gates;
  gates.use_track_ids = false;
  associations_ =
      associate_with_method(config_.association, gates, pose_, &pose_covariance_, candidates,
                            input.observations, !localising_, &input.true_ids);
  association_us_ =
      std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count();
  // the labels of the new landmarks (ideal association pairs by them later)
  for (size_t i = 0; i < associations_.size(); ++i) {
    if (associations_[i].kind != Association::Kind::kNew) continue;
    Landmark lm;
    lm.id = static_cast<int>(landmarks_.size());
    lm.first_travel_m = travel_m_;
    if (i < input.true_ids.size()) lm.label = input.true_ids[i];
    associations_[i].landmark_id = lm.id;
    landmarks_.push_back(lm);
  }
}

void DeadReckoning::update(const core::ConeObservations& observations) {
  // each paired or new observation placed on the dead-reckoned pose, into its landmark's mean
  const Eigen::Matrix2d rotation = Eigen::Rotation2Dd(pose_.yaw).toRotationMatrix();
  for (size_t i = 0; i < observations.cones.size(); ++i) {
    const Association& a = associations_[i];
    if (a.kind == Association::Kind::kRejected) continue;
    Landmark& lm = landmarks_[a.landmark_id];
    if (lm.fixed) continue;
    const core::ConeObservation& o = observations.cones[i];
    lm.sum += pose_.transform(o.position);
    lm.covariance_sum += rotation * o.covariance * rotation.transpose();
    ++lm.sightings;
    if (o.cls != core::ConeClass::kUnknown) ++lm.class_votes[static_cast<int>(o.cls)];
  }
}

core::Estimate DeadReckoning::estimate() const {
  core::Estimate e;
  e.stamp = stamp_;
  e.pose = pose_;
  e.speed_mps = speed_mps_;
  e.yaw_rate_rps = yaw_rate_rps_;
  // confirmed landmarks: the mean placement, its spread from the observations plus the pose's
  const Eigen::Matrix2d pose_position = pose_covariance_.topLeftCorner<2, 2>();
  for (const Landmark& lm : landmarks_) {
    if (lm.forgotten || !lm.confirmed(confirm_sightings())) continue;
    const double n = lm.sightings;
    e.map.push_back(
        {lm.id, voted_class(lm.class_votes), lm.position(),
         lm.covariance_sum / (n * n) + (lm.fixed ? Eigen::Matrix2d::Zero() : pose_position)});
  }
  e.phase = localising_ ? core::SlamPhase::kLocalisation : core::SlamPhase::kMapping;
  e.map_complete = localising_;
  return e;
}

std::vector<std::pair<std::string, double>> DeadReckoning::statistics() const {
  int confirmed = 0;
  for (const Landmark& lm : landmarks_)
    confirmed += !lm.forgotten && lm.confirmed(confirm_sightings());
  return {{"landmarks", static_cast<double>(confirmed)},
          {"landmarks_made", static_cast<double>(landmarks_.size())}};
}

}  // namespace conesim::slam
