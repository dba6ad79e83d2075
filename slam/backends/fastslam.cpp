#include "slam/backends/fastslam.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "slam/association/ml_association.hpp"
#include "slam/backends/ekf_slam.hpp"

namespace conesim::slam {

namespace {

// the spatial index's cell, m
constexpr double kCellM = 5.0;
// landmarks move from where they were made by their updates: the index is searched this much
// wider, m
constexpr double kIndexSlackM = 2.0;
// how far beyond the farthest observation a landmark may be and still be a candidate, m
constexpr double kReachMarginM = 3.0;
// a candidate pairing is considered only within this distance in the map frame, m
constexpr double kPrefilterM = 4.0;

std::int64_t cell_key(std::int64_t cx, std::int64_t cy) {
  return (cx << 32) ^ (cy & 0xffffffffLL);
}

// log of the Gaussian density of v with covariance s
double log_gaussian(const Eigen::Vector2d& v, const Eigen::Matrix2d& s) {
  return -0.5 * v.dot(s.ldlt().solve(v)) -
         0.5 * std::log((2.0 * M_PI) * (2.0 * M_PI) * s.determinant());
}

// a standard normal 3-vector
Eigen::Vector3d normal3(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  const double a = n(rng), b = n(rng), c = n(rng);
  return {a, b, c};
}

// the Cholesky factor of a covariance (zero rows where it is not positive definite)
Eigen::Matrix3d factor(const Eigen::Matrix3d& c) {
  const Eigen::LLT<Eigen::Matrix3d> llt(0.5 * (c + c.transpose()));
  if (llt.info() == Eigen::Success) return llt.matrixL();
  // semi-definite: through the eigen-decomposition
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(0.5 * (c + c.transpose()));
  return eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();
}

// one particle's view of the association: its landmarks near the pose with their EKFs, and
// the pose covariance of the prediction (FastSLAM 2.0; zero for 1.0, whose pose is sampled)
class ParticleProblem : public AssociationProblem {
 public:
  struct Candidate {
    int id = 0;
    const FastLandmark* landmark = nullptr;
    core::Vec2 predicted = core::Vec2::Zero();
    Eigen::Matrix<double, 2, 3> h_pose = Eigen::Matrix<double, 2, 3>::Zero();
    Eigen::Matrix2d landmark_term = Eigen::Matrix2d::Zero();
    // the drift allowance: isotropic variance added to the landmark's, m^2
    double drift_m2 = 0.0;
  };

  ParticleProblem(const core::Pose2& pose, const Eigen::Matrix3d& pose_cov,
                  const core::ConeObservations& obs, std::vector<Candidate> candidates, int margin,
                  const std::vector<int>& labels)
      : pose_cov_(pose_cov),
        obs_(obs),
        cand_(std::move(candidates)),
        margin_(margin),
        labels_(labels) {
    for (Candidate& c : cand_) {
      Eigen::Matrix2d hl;
      c.predicted = predict_observation(pose, c.landmark->mean, &c.h_pose, &hl);
      c.landmark_term =
          hl * c.landmark->covariance * hl.transpose() + Eigen::Matrix2d::Identity() * c.drift_m2;
    }
    for (const auto& o : obs.cones) in_map_.push_back(pose.transform(o.position));
  }
  int observations() const override { return static_cast<int>(obs_.cones.size()); }
  int candidates() const override { return static_cast<int>(cand_.size()); }
  Eigen::Vector2d innovation(int i, int j) const override {
    return obs_.cones[i].position - cand_[j].predicted;
  }
  Eigen::Matrix2d innovation_covariance(int i, int j, int k, int m) const override {
    Eigen::Matrix2d s = cand_[j].h_pose * pose_cov_ * cand_[m].h_pose.transpose();
    if (j == m) s += cand_[j].landmark_term;
    if (i == k) s += obs_.cones[i].covariance;
    return s;
  }
  core::Vec2 observation_in_map(int i) const override { return in_map_[i]; }
  core::Vec2 candidate_position(int j) const override { return cand_[j].landmark->mean; }
  bool allowed(int i, int j) const override {
    if ((in_map_[i] - cand_[j].landmark->mean).squaredNorm() > kPrefilterM * kPrefilterM)
      return false;
    return class_compatible(obs_.cones[i].cls, cand_[j].landmark->class_votes, margin_);
  }
  int observation_track(int i) const override { return obs_.cones[i].track_id; }
  int candidate_landmark(int j) const override { return cand_[j].id; }
  int observation_label(int i) const override {
    return i < static_cast<int>(labels_.size()) ? labels_[i] : -1;
  }
  int candidate_label(int j) const override { return cand_[j].landmark->label; }
  const Candidate& candidate(int j) const { return cand_[j]; }

 private:
  Eigen::Matrix3d pose_cov_;
  const core::ConeObservations& obs_;
  std::vector<Candidate> cand_;
  int margin_;
  const std::vector<int>& labels_;
  std::vector<core::Vec2> in_map_;
};

}  // namespace

std::string FastSlamConfig::validate() const {
  if (version != 1 && version != 2) return "version: expected 1 or 2";
  if (particles < 1 || particles > 10000) return "particles: expected a count from 1 to 10000";
  if (!(resample_fraction >= 0.0 && resample_fraction <= 1.0))
    return "resample_fraction: expected a fraction from 0 to 1";
  if (!(new_landmark_likelihood > 0.0)) return "new_landmark_likelihood: expected > 0 (per m^2)";
  if (!(unseen_penalty > 0.0 && unseen_penalty <= 1.0))
    return "unseen_penalty: expected a factor in (0, 1]";
  if (!(colour_mismatch_penalty > 0.0 && colour_mismatch_penalty <= 1.0))
    return "colour_mismatch_penalty: expected a factor in (0, 1]";
  if (!(new_landmark_min_distance_m >= 0.0)) return "new_landmark_min_distance_m: expected >= 0 m";
  if (!(new_landmark_chi2 > 0.0)) return "new_landmark_chi2: expected > 0";
  if (confirm_sightings < 1) return "confirm_sightings: expected a count >= 1";
  if (!(tentative_max_travel_m > 0.0)) return "tentative_max_travel_m: expected > 0 m";
  if (!(odometry_noise_scale > 0.0 && odometry_noise_scale <= 1000.0))
    return "odometry_noise_scale: expected a factor in (0, 1000]";
  if (!(yaw_noise_per_m >= 0.0)) return "yaw_noise_per_m: expected >= 0";
  if (!(max_range_m > min_range_m && min_range_m >= 0.0))
    return "max_range_m: expected a range above min_range_m >= 0";
  if (!(fov_deg > 0.0 && fov_deg <= 360.0)) return "fov_deg: expected an angle in (0, 360]";
  if (!(fov_margin_m >= 0.0)) return "fov_margin_m: expected >= 0 m";
  if (!(drift_variance_m2_per_m >= 0.0)) return "drift_variance_m2_per_m: expected >= 0";
  if (!(max_drift_variance_m2 >= 0.0)) return "max_drift_variance_m2: expected >= 0";
  if (!(return_gap_m > 0.0)) return "return_gap_m: expected > 0 m";
  if (!(hold_drift_m >= 0.0)) return "hold_drift_m: expected >= 0 m";
  if (!(closure_max_spread_m > 0.0)) return "closure_max_spread_m: expected > 0 m";
  if (!(association.gate_chi2 > 0.0)) return "gate_chi2: expected > 0";
  if (!(association.joint_probability > 0.5 && association.joint_probability < 1.0))
    return "joint_probability: expected a probability in (0.5, 1)";
  if (!(association.nn_radius_m > 0.0)) return "nn_radius_m: expected > 0 m";
  if (!(association.track_memory_frames >= 1.0)) return "track_memory_frames: expected >= 1 frame";
  if (!(association.ambiguity_margin >= 0.0 && association.ambiguity_margin <= 100.0))
    return "ambiguity_margin: expected a cost margin from 0 to 100";
  return loop_closure.validate();
}

FastSlam::FastSlam(const FastSlamConfig& config) : config_(config) {
  reset({}, 0);
}

void FastSlam::reset(const core::Pose2& initial_pose, core::TimeUs stamp) {
  rng_.seed(config_.seed);
  track_bindings_ = TrackBindings(config_.association.track_memory_frames);
  particles_.assign(config_.particles, Particle{});
  for (Particle& p : particles_) p.pose = initial_pose;
  index_.clear();
  indexed_.clear();
  next_id_ = 0;
  phase_ = core::SlamPhase::kMapping;
  map_complete_ = false;
  closure_due_travel_m_ = -1.0;
  loop_closures_ = 0;
  resamplings_ = 0;
  ess_ = config_.particles;
  travel_m_ = 0.0;
  turned_rad_ = 0.0;
  speed_mps_ = 0.0;
  yaw_rate_rps_ = 0.0;
  stamp_ = stamp;
  start_ = initial_pose;
  frames_ = 0;
  association_us_ = 0.0;
  last_log_factors_.clear();
}

void FastSlam::set_prior_map(const std::vector<core::MapCone>& map) {
  // one map for all particles (one tree, shared), fixed: localisation from the start
  PersistentMap<FastLandmark> tree;
  for (const core::MapCone& cone : map) {
    FastLandmark lm;
    lm.mean = cone.position;
    lm.covariance = cone.covariance;
    if (cone.cls != core::ConeClass::kUnknown) lm.class_votes[static_cast<int>(cone.cls)] = 100;
    lm.confirmed = true;
    lm.sightings = 100;
    const int id = next_id_++;
    tree.set(id, lm);
    index_landmark(id, lm.mean);
  }
  for (Particle& p : particles_) p.map = tree;
  phase_ = core::SlamPhase::kLocalisation;
  map_complete_ = true;
}

void FastSlam::index_landmark(int id, const core::Vec2& p) {
  // once per id: where the first particle to make it put it
  if (id >= static_cast<int>(indexed_.size())) indexed_.resize(id + 1, 0);
  if (indexed_[id]) return;
  indexed_[id] = 1;
  const auto cx = static_cast<std::int64_t>(std::floor(p.x() / kCellM));
  const auto cy = static_cast<std::int64_t>(std::floor(p.y() / kCellM));
  index_[cell_key(cx, cy)].push_back(id);
}

std::vector<int> FastSlam::ids_near(const core::Vec2& p, double radius) const {
  std::vector<int> out;
  const auto x0 = static_cast<std::int64_t>(std::floor((p.x() - radius) / kCellM));
  const auto x1 = static_cast<std::int64_t>(std::floor((p.x() + radius) / kCellM));
  const auto y0 = static_cast<std::int64_t>(std::floor((p.y() - radius) / kCellM));
  const auto y1 = static_cast<std::int64_t>(std::floor((p.y() + radius) / kCellM));
  for (std::int64_t cx = x0; cx <= x1; ++cx)
    for (std::int64_t cy = y0; cy <= y1; ++cy)
      if (const auto it = index_.find(cell_key(cx, cy)); it != index_.end())
        out.insert(out.end(), it->second.begin(), it->second.end());
  return out;
}

bool FastSlam::in_field_of_view(const core::Pose2& pose, const core::Vec2& landmark) const {
  const core::Vec2 local = pose.inverse_transform(landmark) - core::Vec2(config_.sensor_x_m, 0.0);
  const double range = local.norm();
  if (range < config_.min_range_m + config_.fov_margin_m ||
      range > config_.max_range_m - config_.fov_margin_m)
    return false;
  const double half_fov = 0.5 * config_.fov_deg * M_PI / 180.0;
  return std::abs(std::atan2(local.y(), local.x())) <= half_fov - config_.fov_margin_m / range;
}

double FastSlam::log_weight_factor(const WeightTerms& t) const {
  return t.matched + t.new_or_rejected * std::log(config_.new_landmark_likelihood) +
         t.unseen * std::log(config_.unseen_penalty) +
         t.colour_mismatches * std::log(config_.colour_mismatch_penalty);
}

double FastSlam::fold_observation(core::Pose2& mean, Eigen::Matrix3d& covariance,
                                  const core::Vec2& z, const Eigen::Matrix2d& r,
                                  const core::Vec2& landmark, const Eigen::Matrix2d& landmark_cov) {
  // linearised at the proposal's mean: z ~ g(mean) + G_s (s - mean) + G_l (l - mu_l) + noise
  Eigen::Matrix<double, 2, 3> gs;
  Eigen::Matrix2d gl;
  const core::Vec2 predicted = predict_observation(mean, landmark, &gs, &gl);
  const Eigen::Matrix2d q = r + gl * landmark_cov * gl.transpose();
  const Eigen::Matrix2d l = (gs * covariance * gs.transpose() + q).eval();
  const Eigen::Vector2d v = z - predicted;
  const double log_likelihood = log_gaussian(v, 0.5 * (l + l.transpose()));
  // [G_s^T Q^-1 G_s + Sigma^-1]^-1 and its mean, in the equivalent Kalman form (no inverse of
  // the pose covariance, which the folds make nearly singular): K = Sigma G_s^T L^-1
  const Eigen::Matrix<double, 3, 2> k = l.ldlt().solve(gs * covariance).transpose();
  const Eigen::Vector3d dx = k * v;
  mean = {mean.x + dx(0), mean.y + dx(1), core::normalize_angle(mean.yaw + dx(2))};
  const Eigen::Matrix3d ikh = Eigen::Matrix3d::Identity() - k * gs;
  // Joseph form: stays symmetric positive semi-definite
  const Eigen::Matrix3d next = ikh * covariance * ikh.transpose() + k * q * k.transpose();
  covariance = 0.5 * (next + next.transpose());
  return log_likelihood;
}

std::vector<int> FastSlam::low_variance_resample(const std::vector<double>& weights, double u) {
  // one offset, M equally spaced pointers into the cumulative weights
  const int m = static_cast<int>(weights.size());
  std::vector<int> out;
  out.reserve(m);
  double cumulative = weights.empty() ? 0.0 : weights[0];
  int i = 0;
  for (int k = 0; k < m; ++k) {
    const double pointer = u + static_cast<double>(k) / m;
    while (pointer > cumulative && i < m - 1) cumulative += weights[++i];
    out.push_back(i);
  }
  return out;
}

double FastSlam::update_particle(Particle& particle, const SlamInput& input,
                                 const std::vector<char>& usable, double reach, int id_base,
                                 LoopClosureStats* stats) {
  const core::ConeObservations& obs = input.observations;
  const int n_obs = static_cast<int>(obs.cones.size());
  const bool localising = phase_ == core::SlamPhase::kLocalisation;
  const OdometryDelta& odo = input.odometry;
  Eigen::Matrix3d q = odo.covariance * config_.odometry_noise_scale;
  q(2, 2) += config_.yaw_noise_per_m * odo.distance_m;
  const Eigen::Matrix3d q_factor = factor(q);

  // the prediction: FastSLAM 1.0 samples the pose from the motion model now; 2.0 keeps the
  // noise-free prediction and its covariance (map frame) for the proposal
  Eigen::Matrix3d g;
  core::Pose2 pose = EkfSlam::motion(particle.pose, odo.delta, nullptr, &g);
  Eigen::Matrix3d pose_cov = Eigen::Matrix3d::Zero();
  if (config_.version == 1) {
    const Eigen::Vector3d n = q_factor * normal3(rng_);
    const core::Pose2 noisy{odo.delta.x + n(0), odo.delta.y + n(1), odo.delta.yaw + n(2)};
    pose = EkfSlam::motion(particle.pose, noisy);
  } else {
    pose_cov = g * q * g.transpose();
  }

  // the candidates: this particle's landmarks near the pose
  std::vector<ParticleProblem::Candidate> candidates;
  for (int id : ids_near(pose.position(), reach + kIndexSlackM)) {
    const FastLandmark* lm = particle.map.find(id);
    if (!lm || (lm->mean - pose.position()).squaredNorm() > reach * reach) continue;
    if (localising && !lm->confirmed) continue;
    ParticleProblem::Candidate c;
    c.id = id;
    c.landmark = lm;
    if (!localising) {
      c.drift_m2 = std::min(config_.max_drift_variance_m2,
                            config_.drift_variance_m2_per_m * (travel_m_ - lm->last_seen_travel_m));
      if (travel_m_ <= lm->held_until_travel_m)
        c.drift_m2 = std::max(c.drift_m2, lm->held_drift_m2);
    }
    candidates.push_back(c);
  }
  const ParticleProblem problem(pose, pose_cov, obs, std::move(candidates),
                                config_.class_vote_margin, labels_);
  const auto t0 = std::chrono::steady_clock::now();
  // tracking-aided: the filter's one track memory is every particle's prior (landmark ids are
  // shared between the particles that inherited a landmark); the frame's evidence is taken from
  // the best particle after the update (FastSlam::update)
  const bool tracking = config_.association.method == AssociationMethod::kTrackingAided;
  std::vector<int> evidence;
  AssociationParams patient = config_.association;  // held back only while mapping
  if (localising) patient.ambiguity_margin = 0.0;
  std::vector<int> pairing =
      associate(patient, problem, tracking ? &track_bindings_ : nullptr,
                tracking ? &evidence : nullptr);
  association_us_ +=
      std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count();
  for (int i = 0; i < n_obs; ++i)
    if (!usable[i]) pairing[i] = -1;

  // the matched observations nearest first (the proposal folds them in that order)
  std::vector<int> matched;
  for (int i = 0; i < n_obs; ++i)
    if (pairing[i] >= 0) matched.push_back(i);
  std::stable_sort(matched.begin(), matched.end(), [&](int a, int b) {
    return obs.cones[a].position.squaredNorm() < obs.cones[b].position.squaredNorm();
  });

  WeightTerms terms;
  if (config_.version == 2) {
    // the proposal: the prediction with each matched observation folded in, then one sample;
    // the weight is the likelihood of the observations under the successive proposals
    for (int i : matched) {
      const ParticleProblem::Candidate& c = problem.candidate(pairing[i]);
      terms.matched += fold_observation(
          pose, pose_cov, obs.cones[i].position, obs.cones[i].covariance, c.landmark->mean,
          c.landmark->covariance + Eigen::Matrix2d::Identity() * c.drift_m2);
    }
    const Eigen::Vector3d n = factor(pose_cov) * normal3(rng_);
    pose = {pose.x + n(0), pose.y + n(1), core::normalize_angle(pose.yaw + n(2))};
  }
  particle.pose = pose;

  // the landmark filters at the sampled pose, and the colour of each pairing
  std::vector<char> seen_candidate(problem.candidates(), 0);
  particle.associations.assign(n_obs, Association{});
  for (int i : matched) {
    const int j = pairing[i];
    seen_candidate[j] = 1;
    const int id = problem.candidate(j).id;
    const core::ConeObservation& o = obs.cones[i];
    particle.associations[i] = {id, Association::Kind::kMatched};
    const FastLandmark& before = *problem.candidate(j).landmark;
    const core::ConeClass voted = voted_class(before.class_votes);
    if (o.cls != core::ConeClass::kUnknown && voted != core::ConeClass::kUnknown && o.cls != voted)
      ++terms.colour_mismatches;
    Eigen::Matrix2d gl;
    const Eigen::Vector2d v = o.position - predict_observation(pose, before.mean, nullptr, &gl);
    const Eigen::Matrix2d s = o.covariance + gl * before.covariance * gl.transpose();
    // (the weight with the drift allowance, the landmark's filter without)
    if (config_.version == 1)
      terms.matched +=
          log_gaussian(v, s + Eigen::Matrix2d::Identity() * problem.candidate(j).drift_m2);
    if (localising) continue;  // the map is fixed
    // the landmark's EKF: K = Sigma G^T S^-1, Joseph form for the covariance
    FastLandmark& lm = *particle.map.find_mut(id);
    const Eigen::Matrix2d k = s.ldlt().solve(gl * lm.covariance).transpose();
    lm.mean += k * v;
    const Eigen::Matrix2d ikh = Eigen::Matrix2d::Identity() - k * gl;
    const Eigen::Matrix2d cov =
        ikh * lm.covariance * ikh.transpose() + k * o.covariance * k.transpose();
    lm.covariance = 0.5 * (cov + cov.transpose());
    if (o.cls != core::ConeClass::kUnknown) ++lm.class_votes[static_cast<int>(o.cls)];
    if (o.track_id >= 0) lm.track_id = o.track_id;
    if (travel_m_ - lm.last_seen_travel_m >= config_.return_gap_m) {
      lm.held_drift_m2 = problem.candidate(j).drift_m2;
      lm.held_until_travel_m = travel_m_ + config_.hold_drift_m;
    }
    lm.last_seen_travel_m = travel_m_;
    ++lm.sightings;
    if (!lm.confirmed && lm.sightings >= config_.confirm_sightings) lm.confirmed = true;
  }

  // the unmatched observations: new landmarks where far from every landmark, else rejected
  for (int i = 0; i < n_obs; ++i) {
    if (pairing[i] >= 0 || !usable[i]) continue;
    ++terms.new_or_rejected;
    if (localising) continue;
    const core::ConeObservation& o = obs.cones[i];
    const core::Vec2 at = pose.transform(o.position);
    bool near = false;
    for (int j = 0; j < problem.candidates() && !near; ++j) {
      const FastLandmark& lm = *problem.candidate(j).landmark;
      if ((lm.mean - at).norm() >= config_.new_landmark_min_distance_m) continue;
      Eigen::Matrix2d gl;
      const Eigen::Vector2d v = o.position - predict_observation(pose, lm.mean, nullptr, &gl);
      const Eigen::Matrix2d s = o.covariance + gl * lm.covariance * gl.transpose();
      near = v.dot(s.ldlt().solve(v)) < config_.new_landmark_chi2;
    }
    if (near) continue;  // rejected: a duplicate or clutter
    const int id = id_base + i;
    FastLandmark lm;
    lm.mean = at;
    // the observation's covariance turned into the map frame
    const Eigen::Matrix2d rot = Eigen::Rotation2Dd(pose.yaw).toRotationMatrix();
    lm.covariance = rot * o.covariance * rot.transpose();
    if (o.cls != core::ConeClass::kUnknown) lm.class_votes[static_cast<int>(o.cls)] = 1;
    lm.sightings = 1;
    lm.confirmed = config_.confirm_sightings <= 1;
    lm.track_id = o.track_id;
    lm.label = i < static_cast<int>(labels_.size()) ? labels_[i] : -1;
    lm.first_travel_m = travel_m_;
    lm.last_seen_travel_m = travel_m_;
    lm.first_heading_rad = pose.yaw;
    particle.map.set(id, lm);
    index_landmark(id, at);
    particle.associations[i] = {id, Association::Kind::kNew};
  }

  // the landmarks in reach that were not seen: the unseen penalty when they were expected in
  // view, the deletion of those missed more often than seen and of stale tentative ones, and
  // the loop closure state machine
  const LoopClosureConfig& lc = config_.loop_closure;
  for (int j = 0; j < problem.candidates(); ++j) {
    const int id = problem.candidate(j).id;
    const FastLandmark& lm = *problem.candidate(j).landmark;
    const bool seen = seen_candidate[j] != 0;
    const bool in_view = in_field_of_view(pose, lm.mean);
    if (in_view && !seen) ++terms.unseen;
    if (localising) continue;
    const bool missed_too_often = in_view && !seen && lm.misses + 1 > lm.sightings;
    const bool stale =
        !lm.confirmed && travel_m_ - lm.first_travel_m > config_.tentative_max_travel_m;
    if (missed_too_often || stale) {
      if (lm.loop_state == LoopState::kReturned && lm.confirmed) {
        --particle.returned;
        if (lm.first_travel_m <= lc.start_window_m) --particle.start_returned;
      }
      particle.map.erase(id);
      continue;
    }
    const double since_first_m = travel_m_ - lm.first_travel_m;
    const double heading_change = core::normalize_angle(pose.yaw - lm.first_heading_rad);
    const LoopState state =
        next_loop_state(lc, lm.loop_state, in_view, seen, since_first_m, heading_change);
    const bool returned_now =
        lm.confirmed && state == LoopState::kReturned && lm.loop_state != LoopState::kReturned;
    // the thesis's statistics: of the old landmarks seen or expected, how many returned
    if (lm.confirmed && since_first_m >= lc.returned_min_travel_m && (seen || in_view)) {
      ++stats->old_matched;
      if (seen && state == LoopState::kReturned) ++stats->old_matched_returned;
      if (seen && voted_class(lm.class_votes) == core::ConeClass::kOrangeBig &&
          std::abs(heading_change) <= lc.big_orange_heading_rad)
        stats->big_orange_returned = true;
    }
    // the tree is written only where something changed (a write copies a shared path)
    if (state != lm.loop_state || (in_view && !seen)) {
      FastLandmark& w = *particle.map.find_mut(id);
      w.loop_state = state;
      if (in_view && !seen) ++w.misses;
    }
    if (returned_now) {
      ++particle.returned;
      if (lm.first_travel_m <= lc.start_window_m) ++particle.start_returned;
    }
  }
  if (tracking) {
    // each observation's own evidence as a landmark id: the pairing without the tracks, or the
    // landmark it started
    particle.evidence.assign(n_obs, -1);
    for (int i = 0; i < n_obs; ++i) {
      if (evidence[i] >= 0)
        particle.evidence[i] = problem.candidate(evidence[i]).id;
      else if (pairing[i] < 0 && particle.associations[i].kind == Association::Kind::kNew)
        particle.evidence[i] = particle.associations[i].landmark_id;
    }
  }
  stats->travel_m = travel_m_;
  stats->returned = particle.returned;
  stats->start_returned = particle.start_returned;
  stats->near_start = back_at_start(lc, start_, pose, turned_rad_);
  return log_weight_factor(terms);
}

void FastSlam::normalise_weights() {
  double top = -std::numeric_limits<double>::infinity();
  for (const Particle& p : particles_) top = std::max(top, p.log_weight);
  double sum = 0.0;
  for (const Particle& p : particles_) sum += std::exp(p.log_weight - top);
  const double log_sum = top + std::log(sum);
  double sum_sq = 0.0;
  for (Particle& p : particles_) {
    p.log_weight -= log_sum;
    sum_sq += std::exp(2.0 * p.log_weight);
  }
  ess_ = 1.0 / sum_sq;
}

void FastSlam::resample() {
  std::vector<double> w;
  for (const Particle& p : particles_) w.push_back(std::exp(p.log_weight));
  const int m = static_cast<int>(particles_.size());
  std::uniform_real_distribution<double> offset(0.0, 1.0 / m);
  const std::vector<int> drawn = low_variance_resample(w, offset(rng_));
  std::vector<Particle> next;
  next.reserve(m);
  // a copy shares the parent's whole landmark tree
  for (int i : drawn) next.push_back(particles_[i]);
  for (Particle& p : next) p.log_weight = -std::log(static_cast<double>(m));
  particles_ = std::move(next);
  ess_ = m;
  ++resamplings_;
}

int FastSlam::best_particle() const {
  int best = 0;
  for (int k = 1; k < static_cast<int>(particles_.size()); ++k)
    if (particles_[k].log_weight > particles_[best].log_weight) best = k;
  return best;
}

core::Pose2 FastSlam::mean_pose(double* spread_m) const {
  // the weighted mean, the heading averaged as offsets from the best particle's
  const core::Pose2 ref = particles_[best_particle()].pose;
  double x = 0.0, y = 0.0, dyaw = 0.0, total = 0.0;
  for (const Particle& p : particles_) {
    const double w = std::exp(p.log_weight);
    x += w * p.pose.x;
    y += w * p.pose.y;
    dyaw += w * core::normalize_angle(p.pose.yaw - ref.yaw);
    total += w;
  }
  const core::Pose2 mean{x / total, y / total, core::normalize_angle(ref.yaw + dyaw / total)};
  if (spread_m) {
    double var = 0.0;
    for (const Particle& p : particles_)
      var += std::exp(p.log_weight) * (p.pose.position() - mean.position()).squaredNorm();
    *spread_m = std::sqrt(var / total);
  }
  return mean;
}

void FastSlam::process(const SlamInput& input) {
  stamp_ = input.observations.stamp;
  labels_ = input.true_ids;
  travel_m_ += input.odometry.distance_m;
  turned_rad_ += input.odometry.delta.yaw;
  speed_mps_ = input.odometry.speed_mps;
  yaw_rate_rps_ = input.odometry.yaw_rate_rps;
  association_us_ = 0.0;
  const core::ConeObservations& obs = input.observations;
  const int n_obs = static_cast<int>(obs.cones.size());

  // observations inside the sensor's range; the candidates' reach
  std::vector<char> usable(n_obs, 1);
  double farthest_m = 0.0;
  for (int i = 0; i < n_obs; ++i) {
    const double range = (obs.cones[i].position - core::Vec2(config_.sensor_x_m, 0.0)).norm();
    if (range > config_.max_range_m) usable[i] = 0;
    farthest_m = std::max(farthest_m, obs.cones[i].position.norm());
  }
  const double reach =
      std::max(farthest_m, config_.sensor_x_m + config_.max_range_m) + kReachMarginM;

  // every particle: predict, associate, update its landmarks, weigh
  const int id_base = next_id_;
  std::vector<LoopClosureStats> stats(particles_.size());
  last_log_factors_.assign(particles_.size(), 0.0);
  for (size_t k = 0; k < particles_.size(); ++k) {
    last_log_factors_[k] = update_particle(particles_[k], input, usable, reach, id_base, &stats[k]);
    particles_[k].log_weight += last_log_factors_[k];
  }
  next_id_ = std::max(next_id_, id_base + n_obs);
  normalise_weights();
  if (config_.association.method == AssociationMethod::kTrackingAided) {
    std::vector<int> tracks(n_obs);
    for (int i = 0; i < n_obs; ++i) tracks[i] = obs.cones[i].track_id;
    track_bindings_.record(tracks, particles_[best_particle()].evidence);
  }
  ++frames_;

  // the loop closes on the best particle's statistics once the particles agree on the pose
  const int best = best_particle();
  if (phase_ == core::SlamPhase::kMapping && closure_due_travel_m_ < 0.0 && !(loop_closures_ > 0)) {
    double spread_m = 0.0;
    mean_pose(&spread_m);
    if (spread_m <= config_.closure_max_spread_m && loop_closed(config_.loop_closure, stats[best]))
      closure_due_travel_m_ = travel_m_ + config_.loop_closure.closure_delay_m;
  }
  if (closure_due_travel_m_ >= 0.0 && loop_closures_ == 0 && travel_m_ >= closure_due_travel_m_)
    close_loop();

  if (ess_ < config_.resample_fraction * static_cast<double>(particles_.size())) resample();
}

void FastSlam::close_loop() {
  ++loop_closures_;
  if (!config_.localise_after_loop_closure) return;
  // the best particle's confirmed landmarks become every particle's fixed map (one tree)
  Particle& best = particles_[best_particle()];
  std::vector<int> tentative;
  best.map.for_each([&](int id, const FastLandmark& lm) {
    if (!lm.confirmed) tentative.push_back(id);
  });
  for (int id : tentative) best.map.erase(id);
  for (Particle& p : particles_) p.map = best.map;
  phase_ = core::SlamPhase::kLocalisation;
  map_complete_ = true;
}

const std::vector<Association>& FastSlam::last_associations() const {
  return particles_[best_particle()].associations;
}

core::Estimate FastSlam::estimate() const {
  core::Estimate e;
  e.stamp = stamp_;
  const Particle& best = particles_[best_particle()];
  e.pose = phase_ == core::SlamPhase::kLocalisation ? mean_pose() : best.pose;
  e.speed_mps = speed_mps_;
  e.yaw_rate_rps = yaw_rate_rps_;
  e.phase = phase_;
  e.map_complete = map_complete_;
  best.map.for_each([&](int id, const FastLandmark& lm) {
    if (lm.confirmed) e.map.push_back({id, voted_class(lm.class_votes), lm.mean, lm.covariance});
  });
  return e;
}

size_t FastSlam::distinct_map_nodes() const {
  std::vector<const PersistentMap<FastLandmark>*> maps;
  for (const Particle& p : particles_) maps.push_back(&p.map);
  return PersistentMap<FastLandmark>::distinct_nodes(maps);
}

std::vector<std::pair<std::string, double>> FastSlam::statistics() const {
  return {{"particles", static_cast<double>(particles_.size())},
          {"resamplings", static_cast<double>(resamplings_)},
          {"effective_sample_size", ess_},
          {"map_nodes", static_cast<double>(distinct_map_nodes())},
          {"landmarks", static_cast<double>(particles_[best_particle()].map.size())}};
}

}  // namespace conesim::slam
