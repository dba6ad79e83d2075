#include "slam/association/ml_association.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>

namespace conesim::slam {

namespace {

// one candidate pairing of observation and landmark, with its cost and the offset from where
// the observation puts the cone to the landmark (map frame)
struct Pairing {
  double cost = 0.0;
  int observation = 0;
  int candidate = 0;
  core::Vec2 offset = core::Vec2::Zero();
  bool old = false;
  bool tight = false;
};

// the old pairings that agree on the offset most observations share (empty without support)
std::vector<Pairing> consensus(const AssociationConfig& config,
                               const std::vector<Pairing>& pairings) {
  std::vector<Pairing> best;
  size_t best_support = 0;
  double best_offset = 0.0;
  for (const Pairing& hypothesis : pairings) {
    if (!hypothesis.old) continue;
    // the pairings that agree with this offset, counted by distinct observations
    std::vector<Pairing> agree;
    std::vector<int> observations;
    for (const Pairing& p : pairings) {
      if (!p.old || (p.offset - hypothesis.offset).norm() > config.consensus_tolerance_m) continue;
      agree.push_back(p);
      if (std::find(observations.begin(), observations.end(), p.observation) == observations.end())
        observations.push_back(p.observation);
    }
    const double offset = hypothesis.offset.norm();
    if (observations.size() > best_support ||
        (observations.size() == best_support && offset < best_offset)) {
      best = std::move(agree);
      best_support = observations.size();
      best_offset = offset;
    }
  }
  if (static_cast<int>(best_support) < config.consensus_min_support) return {};
  return best;
}

// innovation covariance of an observation of a landmark
Eigen::Matrix2d innovation_covariance(const core::Pose2& pose,
                                      const Eigen::Matrix3d* pose_covariance,
                                      const LandmarkCandidate& landmark,
                                      const core::ConeObservation& observation) {
  Eigen::Matrix<double, 2, 3> h_pose;
  Eigen::Matrix2d h_landmark;
  predict_observation(pose, landmark.position, &h_pose, &h_landmark);
  const Eigen::Matrix2d p_landmark =
      landmark.covariance + Eigen::Matrix2d::Identity() * landmark.drift_variance_m2;
  Eigen::Matrix2d s = h_landmark * p_landmark * h_landmark.transpose() + observation.covariance;
  if (pose_covariance) s += h_pose * *pose_covariance * h_pose.transpose();
  return s;
}

}  // namespace

core::ConeClass voted_class(const std::array<int, 5>& votes) {
  int best = static_cast<int>(core::ConeClass::kUnknown);
  int best_votes = 0;
  for (int c = 0; c < 4; ++c) {
    if (votes[c] > best_votes) {
      best = c;
      best_votes = votes[c];
    }
  }
  return static_cast<core::ConeClass>(best);
}

bool class_compatible(core::ConeClass observed, const std::array<int, 5>& votes, int margin) {
  if (observed == core::ConeClass::kUnknown) return true;
  const core::ConeClass landmark = voted_class(votes);
  if (landmark == core::ConeClass::kUnknown || landmark == observed) return true;
  // a different class only counts against the pairing once it leads clearly
  return votes[static_cast<int>(landmark)] - votes[static_cast<int>(observed)] < margin;
}

core::Vec2 predict_observation(const core::Pose2& pose, const core::Vec2& landmark,
                               Eigen::Matrix<double, 2, 3>* h_pose, Eigen::Matrix2d* h_landmark) {
  const double c = std::cos(pose.yaw), s = std::sin(pose.yaw);
  const double dx = landmark.x() - pose.x, dy = landmark.y() - pose.y;
  const core::Vec2 z(c * dx + s * dy, -s * dx + c * dy);
  // z = R^T (l - p): by l it is R^T, by p it is -R^T, by yaw it is (z.y, -z.x)
  if (h_landmark) *h_landmark << c, s, -s, c;
  if (h_pose) *h_pose << -c, -s, z.y(), s, -c, -z.x();
  return z;
}

double mahalanobis2(const core::Pose2& pose, const Eigen::Matrix3d* pose_covariance,
                    const LandmarkCandidate& landmark, const core::ConeObservation& observation) {
  const core::Vec2 innovation = observation.position - predict_observation(pose, landmark.position);
  const Eigen::Matrix2d s = innovation_covariance(pose, pose_covariance, landmark, observation);
  return innovation.dot(s.ldlt().solve(innovation));
}

std::vector<Association> associate(const AssociationConfig& config, const core::Pose2& pose,
                                   const Eigen::Matrix3d* pose_covariance,
                                   const std::vector<LandmarkCandidate>& candidates,
                                   const core::ConeObservations& observations, bool allow_new,
                                   const TrackBindings* tracks, std::vector<int>* evidence) {
  const int n_obs = static_cast<int>(observations.cones.size());
  const int n_cand = static_cast<int>(candidates.size());
  std::vector<Association> out(n_obs);
  std::vector<bool> taken(n_cand, false);
  std::vector<double> nearest_d2(n_obs, std::numeric_limits<double>::infinity());
  std::vector<double> nearest_m(n_obs, std::numeric_limits<double>::infinity());

  // every gated pairing, with its negative log-likelihood as the cost
  std::vector<Pairing> pairings;
  for (int i = 0; i < n_obs; ++i) {
    const core::ConeObservation& obs = observations.cones[i];
    const core::Vec2 obs_map = pose.transform(obs.position);
    for (int j = 0; j < n_cand; ++j) {
      const LandmarkCandidate& lm = candidates[j];
      const double distance_m = (lm.position - obs_map).norm();
      nearest_m[i] = std::min(nearest_m[i], distance_m);
      if (distance_m > 6.0) continue;  // far beyond any gate: skip the algebra
      const core::Vec2 innovation = obs.position - predict_observation(pose, lm.position);
      const Eigen::Matrix2d s = innovation_covariance(pose, pose_covariance, lm, obs);
      const double d2 = innovation.dot(s.ldlt().solve(innovation));
      nearest_d2[i] = std::min(nearest_d2[i], d2);
      if (!class_compatible(obs.cls, lm.class_votes, config.class_vote_margin)) continue;
      const double cost = d2 + std::log(s.determinant());
      Pairing pairing{
          cost, i, j, lm.position - obs_map, lm.drift_variance_m2 > config.old_drift_variance_m2,
          false};
      if (d2 >= config.gate_chi2) continue;
      // old landmarks: also whether the pairing passes without the drift allowance
      if (pairing.old) {
        LandmarkCandidate undrifted = lm;
        undrifted.drift_variance_m2 = 0.0;
        pairing.tight = mahalanobis2(pose, pose_covariance, undrifted, obs) < config.gate_chi2;
      }
      pairings.push_back(pairing);
    }
  }

  // old landmarks only along the consensus offset, or within the tight gate without one
  const std::vector<Pairing> agreed = consensus(config, pairings);
  std::vector<Pairing> kept;
  for (const Pairing& p : pairings) {
    const bool in_consensus = std::any_of(agreed.begin(), agreed.end(), [&](const Pairing& a) {
      return a.observation == p.observation && a.candidate == p.candidate;
    });
    if (!p.old || in_consensus || (agreed.empty() && p.tight)) kept.push_back(p);
  }
  pairings = std::move(kept);

  // greedy with mutual exclusion, likeliest first: the frame's own evidence, then with each
  // pairing's cost less its track's prior (tracking-aided)
  const auto by_cost = [](const Pairing& a, const Pairing& b) { return a.cost < b.cost; };
  std::stable_sort(pairings.begin(), pairings.end(), by_cost);
  const auto greedy = [&](std::vector<int>& pairing_of) {
    pairing_of.assign(n_obs, -1);
    std::fill(taken.begin(), taken.end(), false);
    for (const Pairing& p : pairings) {
      if (pairing_of[p.observation] >= 0 || taken[p.candidate]) continue;
      pairing_of[p.observation] = p.candidate;
      taken[p.candidate] = true;
    }
  };
  std::vector<int> pairing_of;
  if (evidence) {
    greedy(pairing_of);
    evidence->assign(n_obs, -1);
    for (int i = 0; i < n_obs; ++i)
      if (pairing_of[i] >= 0) (*evidence)[i] = candidates[pairing_of[i]].id;
  }
  if (config.use_track_ids && tracks) {
    for (Pairing& p : pairings)
      p.cost -=
          tracks->bonus(observations.cones[p.observation].track_id, candidates[p.candidate].id);
    std::stable_sort(pairings.begin(), pairings.end(), by_cost);
  }
  greedy(pairing_of);
  // tracking-aided, while mapping: an ambiguous observation of a track waits for a later frame
  // (rejected, never new), and the landmark it held goes back to the others. On a fixed map a
  // wrong pairing stays out of the map and the pose needs every observation it can get
  std::vector<char> waits(n_obs, 0);
  if (config.use_track_ids && tracks && allow_new) {
    waits = ambiguous_observations(pairings, pairing_of, config.ambiguity_margin);
    for (int i = 0; i < n_obs; ++i)
      if (observations.cones[i].track_id < 0) waits[i] = 0;
    // returning to landmarks not seen for long, the drift consensus above decides: holding
    // those observations back would starve the pose of the very corrections that close the loop
    for (const Pairing& p : pairings)
      if (p.old && pairing_of[p.observation] == p.candidate) waits[p.observation] = 0;
    if (std::find(waits.begin(), waits.end(), 1) != waits.end()) {
      std::erase_if(pairings, [&](const Pairing& p) { return waits[p.observation] != 0; });
      greedy(pairing_of);
    }
  }
  for (int i = 0; i < n_obs; ++i)
    if (pairing_of[i] >= 0) out[i] = {candidates[pairing_of[i]].id, Association::Kind::kMatched};

  // the rest: new when far from everything, else rejected
  for (int i = 0; i < n_obs; ++i) {
    if (out[i].kind == Association::Kind::kMatched || waits[i]) continue;
    const bool far = nearest_d2[i] > config.new_landmark_chi2 &&
                     nearest_m[i] > config.new_landmark_min_distance_m;
    out[i].kind = allow_new && far ? Association::Kind::kNew : Association::Kind::kRejected;
  }
  return out;
}

namespace {

// the association's view of marginal landmarks and a pose covariance
class MarginalProblem : public AssociationProblem {
 public:
  MarginalProblem(const AssociationConfig& config, const core::Pose2& pose,
                  const Eigen::Matrix3d* pose_covariance,
                  const std::vector<LandmarkCandidate>& candidates,
                  const core::ConeObservations& observations, const std::vector<int>* labels)
      : config_(config),
        pose_(pose),
        candidates_(candidates),
        observations_(observations),
        labels_(labels) {
    pose_covariance_ = pose_covariance ? *pose_covariance : Eigen::Matrix3d::Zero();
    for (const LandmarkCandidate& c : candidates) {
      Eigen::Matrix<double, 2, 3> hp;
      Eigen::Matrix2d hl;
      predicted_.push_back(predict_observation(pose, c.position, &hp, &hl));
      h_pose_.push_back(hp);
      landmark_term_.push_back(
          hl * (c.covariance + Eigen::Matrix2d::Identity() * c.drift_variance_m2) * hl.transpose());
    }
    for (const auto& o : observations.cones) in_map_.push_back(pose.transform(o.position));
  }
  int observations() const override { return static_cast<int>(observations_.cones.size()); }
  int candidates() const override { return static_cast<int>(candidates_.size()); }
  Eigen::Vector2d innovation(int i, int j) const override {
    return observations_.cones[i].position - predicted_[j];
  }
  Eigen::Matrix2d innovation_covariance(int i, int j, int k, int m) const override {
    Eigen::Matrix2d s = h_pose_[j] * pose_covariance_ * h_pose_[m].transpose();
    if (j == m) s += landmark_term_[j];
    if (i == k) s += observations_.cones[i].covariance;
    return s;
  }
  core::Vec2 observation_in_map(int i) const override { return in_map_[i]; }
  core::Vec2 candidate_position(int j) const override { return candidates_[j].position; }
  bool allowed(int i, int j) const override {
    if ((in_map_[i] - candidates_[j].position).squaredNorm() > 36.0) return false;
    return class_compatible(observations_.cones[i].cls, candidates_[j].class_votes,
                            config_.class_vote_margin);
  }
  int observation_track(int i) const override { return observations_.cones[i].track_id; }
  int candidate_landmark(int j) const override { return candidates_[j].id; }
  int observation_label(int i) const override {
    return labels_ && i < static_cast<int>(labels_->size()) ? (*labels_)[i] : -1;
  }
  int candidate_label(int j) const override { return candidates_[j].label; }

 private:
  const AssociationConfig& config_;
  core::Pose2 pose_;
  Eigen::Matrix3d pose_covariance_;
  const std::vector<LandmarkCandidate>& candidates_;
  const core::ConeObservations& observations_;
  const std::vector<int>* labels_;
  std::vector<core::Vec2> predicted_, in_map_;
  std::vector<Eigen::Matrix<double, 2, 3>> h_pose_;
  std::vector<Eigen::Matrix2d> landmark_term_;
};

}  // namespace

std::vector<Association> associate_with_method(
    const AssociationParams& params, const AssociationConfig& config, const core::Pose2& pose,
    const Eigen::Matrix3d* pose_covariance, const std::vector<LandmarkCandidate>& candidates,
    const core::ConeObservations& observations, bool allow_new, const std::vector<int>* labels,
    const TrackBindings* tracks, std::vector<int>* evidence) {
  // no association: every observation is a landmark of its own (the map is not searched)
  if (params.method == AssociationMethod::kNone) {
    if (evidence) evidence->assign(observations.cones.size(), -1);
    return std::vector<Association>(
        observations.cones.size(),
        allow_new ? Association{Association::kNoLandmark, Association::Kind::kNew} : Association{});
  }
  const MarginalProblem problem(config, pose, pose_covariance, candidates, observations, labels);
  AssociationParams patient = params;  // held back only while mapping (as in associate())
  if (!allow_new) patient.ambiguity_margin = 0.0;
  const std::vector<int> pairing = associate(patient, problem, tracks, evidence);
  if (evidence)
    for (int& e : *evidence)
      if (e >= 0) e = candidates[e].id;
  const int n_obs = problem.observations();
  std::vector<Association> out(n_obs);
  for (int i = 0; i < n_obs; ++i) {
    if (pairing[i] >= 0) {
      out[i] = {candidates[pairing[i]].id, Association::Kind::kMatched};
      continue;
    }
    // the rest: new when far from every landmark, else rejected (as associate() does)
    double nearest_d2 = std::numeric_limits<double>::infinity();
    double nearest_m = std::numeric_limits<double>::infinity();
    for (int j = 0; j < problem.candidates(); ++j) {
      const double d_m = (problem.observation_in_map(i) - problem.candidate_position(j)).norm();
      nearest_m = std::min(nearest_m, d_m);
      if (d_m > 6.0) continue;
      const Eigen::Vector2d v = problem.innovation(i, j);
      nearest_d2 =
          std::min(nearest_d2, v.dot(problem.innovation_covariance(i, j, i, j).ldlt().solve(v)));
    }
    const bool far =
        nearest_d2 > config.new_landmark_chi2 && nearest_m > config.new_landmark_min_distance_m;
    out[i].kind = allow_new && far ? Association::Kind::kNew : Association::Kind::kRejected;
  }
  return out;
}

}  // namespace conesim::slam
