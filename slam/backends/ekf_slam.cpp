#include "slam/backends/ekf_slam.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>

#include "slam/association/ml_association.hpp"
#include "slam/loop_closure.hpp"

namespace conesim::slam {

namespace {

// how far beyond the farthest observation a landmark may be and still be a candidate, m
constexpr double kReachMarginM = 3.0;
// a candidate pairing is considered only within this distance in the map frame, m (far beyond
// any gate at the filter's uncertainty; saves the algebra)
constexpr double kPrefilterM = 4.0;

}  // namespace

std::string EkfSlamConfig::validate() const {
  if (confirm_sightings < 1) return "confirm_sightings: expected a count >= 1";
  if (!(preliminary_max_travel_m > 0.0)) return "preliminary_max_travel_m: expected > 0 m";
  if (!(preliminary_radius_m > 0.0)) return "preliminary_radius_m: expected > 0 m";
  if (!(new_landmark_min_distance_m >= 0.0)) return "new_landmark_min_distance_m: expected >= 0 m";
  if (!(new_landmark_chi2 > 0.0)) return "new_landmark_chi2: expected > 0";
  if (!(unseen_exclusion_m > 0.0)) return "unseen_exclusion_m: expected > 0 m";
  if (!(loop_min_travel_m >= 0.0)) return "loop_min_travel_m: expected >= 0 m";
  if (!(start_radius_m > 0.0)) return "start_radius_m: expected > 0 m";
  if (!(closure_delay_m >= 0.0)) return "closure_delay_m: expected >= 0 m";
  if (closure_min_pairs < 1) return "closure_min_pairs: expected a count >= 1";
  if (!(closure_max_heading_rad > 0.0 && closure_max_heading_rad <= 3.2))
    return "closure_max_heading_rad: expected an angle in (0, 3.2] rad";
  if (!(odometry_noise_scale > 0.0 && odometry_noise_scale <= 1000.0))
    return "odometry_noise_scale: expected a factor in (0, 1000]";
  if (!(yaw_noise_per_m >= 0.0)) return "yaw_noise_per_m: expected >= 0";
  if (!(association.gate_chi2 > 0.0)) return "association.gate_chi2: expected > 0";
  if (!(association.joint_probability > 0.5 && association.joint_probability < 1.0))
    return "association.joint_probability: expected a probability in (0.5, 1)";
  if (!(association.nn_radius_m > 0.0)) return "association.nn_radius_m: expected > 0 m";
  if (!(association.track_memory_frames >= 1.0))
    return "association.track_memory_frames: expected >= 1 frame";
  if (!(association.ambiguity_margin >= 0.0 && association.ambiguity_margin <= 100.0))
    return "association.ambiguity_margin: expected a cost margin from 0 to 100";
  return {};
}

EkfSlam::EkfSlam(const EkfSlamConfig& config) : config_(config) {
  reset({}, 0);
}

core::Pose2 EkfSlam::motion(const core::Pose2& pose, const core::Pose2& d, Eigen::Matrix3d* f_pose,
                            Eigen::Matrix3d* f_delta) {
  const double c = std::cos(pose.yaw), s = std::sin(pose.yaw);
  if (f_pose) *f_pose << 1, 0, -s * d.x - c * d.y, 0, 1, c * d.x - s * d.y, 0, 0, 1;
  if (f_delta) *f_delta << c, -s, 0, s, c, 0, 0, 0, 1;
  return {pose.x + c * d.x - s * d.y, pose.y + s * d.x + c * d.y,
          core::normalize_angle(pose.yaw + d.yaw)};
}

core::Vec2 EkfSlam::landmark_from(const core::Pose2& pose, const core::Vec2& z,
                                  Eigen::Matrix<double, 2, 3>* l_pose, Eigen::Matrix2d* l_z) {
  const double c = std::cos(pose.yaw), s = std::sin(pose.yaw);
  if (l_pose) *l_pose << 1, 0, -s * z.x() - c * z.y(), 0, 1, c * z.x() - s * z.y();
  if (l_z) *l_z << c, -s, s, c;
  return {pose.x + c * z.x() - s * z.y(), pose.y + s * z.x() + c * z.y()};
}

void EkfSlam::reset(const core::Pose2& initial_pose, core::TimeUs stamp) {
  x_ = Eigen::Vector3d(initial_pose.x, initial_pose.y, initial_pose.yaw);
  start_ = initial_pose;
  // the start pose is the gauge: known up to a trace of uncertainty (P stays definite)
  p_ = Eigen::Vector3d(1e-8, 1e-8, 1e-10).asDiagonal();
  landmarks_.clear();
  preliminary_.clear();
  fixed_covariance_.clear();
  fixed_position_.clear();
  associations_.clear();
  track_bindings_ = TrackBindings(config_.association.track_memory_frames);
  next_id_ = 0;
  preliminary_dropped_ = 0;
  phase_ = core::SlamPhase::kMapping;
  map_complete_ = false;
  loop_open_ = false;
  closure_travel_m_ = -1.0;
  loop_closures_ = 0;
  travel_m_ = 0.0;
  turned_rad_ = 0.0;
  speed_mps_ = 0.0;
  yaw_rate_rps_ = 0.0;
  stamp_ = stamp;
  association_us_ = 0.0;
}

void EkfSlam::set_prior_map(const std::vector<core::MapCone>& map) {
  // the known cones become the fixed map; the filter localises on it from the start
  for (const core::MapCone& cone : map) {
    Landmark lm;
    lm.id = next_id_++;
    if (cone.cls != core::ConeClass::kUnknown) lm.class_votes[static_cast<int>(cone.cls)] = 100;
    lm.index = static_cast<int>(fixed_position_.size());
    fixed_position_.push_back(cone.position);
    fixed_covariance_.push_back(cone.covariance);
    landmarks_.push_back(lm);
  }
  x_.conservativeResize(3);
  const Eigen::Matrix3d pose_cov = p_.topLeftCorner<3, 3>();
  p_ = pose_cov;
  phase_ = core::SlamPhase::kLocalisation;
  map_complete_ = true;
  loop_open_ = true;
}

void EkfSlam::predict(const OdometryDelta& odometry) {
  // block form: only the pose rows and the pose-landmark cross terms change
  Eigen::Matrix3d f, g;
  const core::Pose2 next = motion(pose(), odometry.delta, &f, &g);
  Eigen::Matrix3d q = odometry.covariance * config_.odometry_noise_scale;
  q(2, 2) += config_.yaw_noise_per_m * odometry.distance_m;
  x_.head<3>() = Eigen::Vector3d(next.x, next.y, next.yaw);
  const int n = static_cast<int>(x_.size());
  const Eigen::Matrix3d pose_block =
      f * p_.topLeftCorner<3, 3>() * f.transpose() + g * q * g.transpose();
  p_.topLeftCorner<3, 3>() = 0.5 * (pose_block + pose_block.transpose());
  if (n > 3) {
    p_.topRightCorner(3, n - 3) = f * p_.topRightCorner(3, n - 3);
    p_.bottomLeftCorner(n - 3, 3) = p_.topRightCorner(3, n - 3).transpose();
  }
  travel_m_ += odometry.distance_m;
  turned_rad_ += odometry.delta.yaw;
  speed_mps_ = odometry.speed_mps;
  yaw_rate_rps_ = odometry.yaw_rate_rps;
}

namespace {

// the association's view of the filter: predicted observations, Jacobians and covariance blocks
class EkfProblem : public AssociationProblem {
 public:
  struct Candidate {
    int landmark = 0;                          // index into the landmarks
    int row = -1;                              // first state row, -1 when fixed (localisation)
    core::Vec2 position = core::Vec2::Zero();  // map frame
    // fixed landmark's covariance (localisation)
    Eigen::Matrix2d fixed_cov = Eigen::Matrix2d::Zero();
    core::Vec2 predicted = core::Vec2::Zero();
    Eigen::Matrix<double, 2, 3> h_pose = Eigen::Matrix<double, 2, 3>::Zero();
    Eigen::Matrix2d h_landmark = Eigen::Matrix2d::Zero();
    std::array<int, 5> votes{};
    int id = 0;  // the landmark's id
    int label = -1;
    // an old landmark of the start, a candidate only for closing the loop (with big orange
    // cones at the start, only big orange cones may pair with it)
    bool start_only = false;
  };

  EkfProblem(const core::Pose2& pose, const Eigen::MatrixXd& p,
             const core::ConeObservations& observations, std::vector<Candidate> candidates,
             int class_vote_margin, const std::vector<char>& usable, bool big_orange_closure,
             const std::vector<int>& labels)
      : pose_(pose),
        p_(p),
        obs_(observations),
        cand_(std::move(candidates)),
        margin_(class_vote_margin),
        usable_(usable),
        big_orange_closure_(big_orange_closure),
        labels_(labels) {
    for (Candidate& c : cand_)
      c.predicted = predict_observation(pose, c.position, &c.h_pose, &c.h_landmark);
    for (const auto& o : obs_.cones) in_map_.push_back(pose.transform(o.position));
  }

  int observations() const override { return static_cast<int>(obs_.cones.size()); }
  int candidates() const override { return static_cast<int>(cand_.size()); }
  Eigen::Vector2d innovation(int i, int j) const override {
    return obs_.cones[i].position - cand_[j].predicted;
  }
  Eigen::Matrix2d innovation_covariance(int i, int j, int k, int m) const override {
    const Candidate& a = cand_[j];
    const Candidate& b = cand_[m];
    Eigen::Matrix2d s = a.h_pose * p_.topLeftCorner<3, 3>() * b.h_pose.transpose();
    if (a.row >= 0 && b.row >= 0) {
      s += a.h_pose * p_.block<3, 2>(0, b.row) * b.h_landmark.transpose() +
           a.h_landmark * p_.block<2, 3>(a.row, 0) * b.h_pose.transpose() +
           a.h_landmark * p_.block<2, 2>(a.row, b.row) * b.h_landmark.transpose();
    } else if (j == m) {
      s += a.h_landmark * a.fixed_cov * a.h_landmark.transpose();
    }
    if (i == k) s += obs_.cones[i].covariance;
    return s;
  }
  core::Vec2 observation_in_map(int i) const override { return in_map_[i]; }
  core::Vec2 candidate_position(int j) const override { return cand_[j].position; }
  bool allowed(int i, int j) const override {
    if (!usable_[i]) return false;
    const Candidate& c = cand_[j];
    if ((in_map_[i] - c.position).squaredNorm() > kPrefilterM * kPrefilterM) return false;
    const core::ConeClass cls = obs_.cones[i].cls;
    if (c.start_only && big_orange_closure_ && cls != core::ConeClass::kOrangeBig) return false;
    return class_compatible(cls, c.votes, margin_);
  }
  int observation_track(int i) const override { return obs_.cones[i].track_id; }
  int candidate_landmark(int j) const override { return cand_[j].id; }
  int observation_label(int i) const override {
    return i < static_cast<int>(labels_.size()) ? labels_[i] : -1;
  }
  int candidate_label(int j) const override { return cand_[j].label; }
  const Candidate& candidate(int j) const { return cand_[j]; }

 private:
  core::Pose2 pose_;
  const Eigen::MatrixXd& p_;
  const core::ConeObservations& obs_;
  std::vector<Candidate> cand_;
  int margin_;
  const std::vector<char>& usable_;
  bool big_orange_closure_;
  const std::vector<int>& labels_;
  std::vector<core::Vec2> in_map_;
};

}  // namespace

void EkfSlam::process(const SlamInput& input) {
  stamp_ = input.observations.stamp;
  labels_ = input.true_ids;
  predict(input.odometry);
  const core::ConeObservations& obs = input.observations;
  const int n_obs = static_cast<int>(obs.cones.size());
  associations_.assign(n_obs, Association{});
  const bool localising = phase_ == core::SlamPhase::kLocalisation;

  // observations within the range used
  std::vector<char> usable(n_obs, 1);
  double farthest_m = 0.0;
  for (int i = 0; i < n_obs; ++i) {
    const double range = (obs.cones[i].position - core::Vec2(config_.sensor_x_m, 0.0)).norm();
    if (config_.max_range_m > 0.0 && range > config_.max_range_m) usable[i] = 0;
    if (usable[i]) farthest_m = std::max(farthest_m, obs.cones[i].position.norm());
  }

  // the landmarks that may take part: in reach, and before the loop closes seen recently (the
  // start's big orange cones excepted once the car may be back)
  const core::Pose2 now = pose();
  const double reach = farthest_m + kReachMarginM;
  // the loop may close once the car has come round: far enough driven, near the start pose and
  // heading the start's way (a leg passing the start the other way sees its cones too), having
  // turned once around (a leg alongside the start the same way, reached through two opposite
  // hairpins, has turned by none: loop_closure.hpp, back_at_start)
  const bool may_close =
      !loop_open_ && travel_m_ >= config_.loop_min_travel_m &&
      (now.position() - start_.position()).norm() <= 2.0 * config_.start_radius_m &&
      std::abs(core::normalize_angle(now.yaw - start_.yaw)) <= config_.closure_max_heading_rad &&
      turned_once_around(turned_rad_, config_.closure_max_heading_rad);
  // the loop closes on the start's big orange cones; a layout without them (some published
  // ones) closes on the start's other landmarks, several at once
  bool big_orange_closure = false;
  for (const Landmark& lm : landmarks_)
    if (lm.at_start && voted_class(lm.class_votes) == core::ConeClass::kOrangeBig)
      big_orange_closure = true;
  std::vector<EkfProblem::Candidate> candidates;
  for (size_t k = 0; k < landmarks_.size(); ++k) {
    const Landmark& lm = landmarks_[k];
    const core::Vec2 position = localising ? fixed_position_[lm.index] : landmark_position(lm);
    if ((position - now.position()).squaredNorm() > reach * reach) continue;
    const bool recent = travel_m_ - lm.last_seen_travel_m <= config_.unseen_exclusion_m;
    const bool start_cone =
        may_close && lm.at_start &&
        (!big_orange_closure || voted_class(lm.class_votes) == core::ConeClass::kOrangeBig);
    if (!loop_open_ && !recent && !start_cone) continue;
    EkfProblem::Candidate c;
    c.landmark = static_cast<int>(k);
    c.row = localising ? -1 : lm.index;
    c.position = position;
    c.fixed_cov = localising ? fixed_covariance_[lm.index] : Eigen::Matrix2d::Zero();
    c.votes = lm.class_votes;
    c.id = lm.id;
    c.label = lm.label;
    c.start_only = !loop_open_ && !recent;
    candidates.push_back(c);
  }
  const EkfProblem problem(now, p_, obs, std::move(candidates), config_.class_vote_margin, usable,
                           big_orange_closure, labels_);
  const auto start = std::chrono::steady_clock::now();
  const bool tracking = config_.association.method == AssociationMethod::kTrackingAided;
  std::vector<int> evidence;
  AssociationParams patient = config_.association;  // held back only while mapping
  if (localising) patient.ambiguity_margin = 0.0;
  const std::vector<int> pairing =
      associate(patient, problem, tracking ? &track_bindings_ : nullptr,
                tracking ? &evidence : nullptr);
  association_us_ =
      std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count();

  // the loop closure the pairings make: one big orange cone of the start, or without them
  // closure_min_pairs of the start's landmarks in one frame; fewer are dropped (not applied)
  int start_pairs = 0;
  for (int i = 0; i < n_obs; ++i)
    if (pairing[i] >= 0 && problem.candidate(pairing[i]).start_only) ++start_pairs;
  const bool closing =
      start_pairs >= (big_orange_closure ? 1 : std::max(1, config_.closure_min_pairs));

  // the pairs and the bookkeeping
  std::vector<std::pair<int, int>> pairs;
  for (int i = 0; i < n_obs; ++i) {
    if (pairing[i] < 0) continue;
    const EkfProblem::Candidate& c = problem.candidate(pairing[i]);
    if (c.start_only && !closing) continue;
    pairs.emplace_back(i, c.landmark);
    Landmark& lm = landmarks_[c.landmark];
    associations_[i] = {lm.id, Association::Kind::kMatched};
    lm.last_seen_travel_m = travel_m_;
    if (obs.cones[i].cls != core::ConeClass::kUnknown)
      ++lm.class_votes[static_cast<int>(obs.cones[i].cls)];
  }
  if (closing) {
    // back at the start: every landmark may be associated again
    loop_open_ = true;
    ++loop_closures_;
    closure_travel_m_ = travel_m_;
  }
  update(obs, pairs, localising);
  if (!localising) handle_unmatched(obs);
  if (tracking) {
    // each track's evidence: the landmark its observation paired with without the tracks, or
    // for one the association left unpaired the preliminary landmark it started or was seen as
    std::vector<int> tracks(n_obs);
    for (int i = 0; i < n_obs; ++i) {
      tracks[i] = obs.cones[i].track_id;
      if (evidence[i] >= 0)
        evidence[i] = problem.candidate(evidence[i]).id;
      else if (pairing[i] < 0 && associations_[i].kind != Association::Kind::kRejected)
        evidence[i] = associations_[i].landmark_id;
    }
    track_bindings_.record(tracks, evidence);
  }
  for (int i = 0; i < n_obs; ++i)
    if (!usable[i]) associations_[i] = {};

  // the map is fixed some way after the closure
  if (!localising && config_.localise_after_loop_closure && closure_travel_m_ >= 0.0 &&
      travel_m_ >= closure_travel_m_ + config_.closure_delay_m)
    enter_localisation();
}

void EkfSlam::update(const core::ConeObservations& obs,
                     const std::vector<std::pair<int, int>>& pairs, bool pose_only) {
  const int m = static_cast<int>(pairs.size());
  if (m == 0) return;
  const int n = static_cast<int>(x_.size());
  const core::Pose2 now = pose();
  // H is sparse: per pair a 2x3 block at the pose and a 2x2 block at the landmark, so
  // P H^T is gathered from those columns of P (n x 2m) instead of a product with a dense H
  Eigen::MatrixXd pht(n, 2 * m);
  Eigen::VectorXd innovation(2 * m);
  Eigen::MatrixXd r = Eigen::MatrixXd::Zero(2 * m, 2 * m);
  std::vector<Eigen::Matrix<double, 2, 3>> h_pose(m);
  std::vector<Eigen::Matrix2d> h_landmark(m);
  std::vector<int> rows(m, -1);
  for (int a = 0; a < m; ++a) {
    const auto& [i, k] = pairs[a];
    const Landmark& lm = landmarks_[k];
    const core::Vec2 l = pose_only ? fixed_position_[lm.index] : landmark_position(lm);
    const core::Vec2 z = predict_observation(now, l, &h_pose[a], &h_landmark[a]);
    innovation.segment<2>(2 * a) = obs.cones[i].position - z;
    r.block<2, 2>(2 * a, 2 * a) = obs.cones[i].covariance;
    pht.middleCols<2>(2 * a) = p_.leftCols<3>() * h_pose[a].transpose();
    if (pose_only) {
      // the fixed map's own uncertainty adds to the measurement's
      r.block<2, 2>(2 * a, 2 * a) +=
          h_landmark[a] * fixed_covariance_[lm.index] * h_landmark[a].transpose();
    } else {
      rows[a] = lm.index;
      pht.middleCols<2>(2 * a) += p_.middleCols<2>(lm.index) * h_landmark[a].transpose();
    }
  }
  // S = H P H^T + R from the rows of P H^T that H picks
  Eigen::MatrixXd s = r;
  for (int a = 0; a < m; ++a) {
    s.middleRows<2>(2 * a) += h_pose[a] * pht.topRows<3>();
    if (rows[a] >= 0) s.middleRows<2>(2 * a) += h_landmark[a] * pht.middleRows<2>(rows[a]);
  }
  s = (0.5 * (s + s.transpose())).eval();  // eval: the transpose must not alias the result
  // K = P H^T S^-1 through an LDLT factorisation of S (no explicit inverse)
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(s);
  const Eigen::MatrixXd k = ldlt.solve(pht.transpose()).transpose();
  x_ += k * innovation;
  x_(2) = core::normalize_angle(x_(2));
  // Joseph form (I - KH) P (I - KH)^T + K R K^T, expanded with the sparse P H^T:
  // P - K (PH^T)^T - (PH^T) K^T + K S K^T. Unlike P - K S K^T it is first-order insensitive to
  // errors in K (round-off in the solve), so P stays positive semi-definite; it costs three
  // n x n x 2m products instead of one. The result is symmetrised against round-off.
  const Eigen::MatrixXd kpht = k * pht.transpose();
  p_ += -kpht - kpht.transpose() + k * s * k.transpose();
  p_ = (0.5 * (p_ + p_.transpose())).eval();  // eval: the transpose must not alias the result
}

void EkfSlam::add_landmark(const core::ConeObservation& o, int id, int label) {
  // augment the state: l = p (+) z, with its covariance and its cross terms through the pose
  Eigen::Matrix<double, 2, 3> l_pose;
  Eigen::Matrix2d l_z;
  const core::Vec2 l = landmark_from(pose(), o.position, &l_pose, &l_z);
  const int n = static_cast<int>(x_.size());
  x_.conservativeResize(n + 2);
  x_.tail<2>() = l;
  Eigen::MatrixXd grown = Eigen::MatrixXd::Zero(n + 2, n + 2);
  grown.topLeftCorner(n, n) = p_;
  const Eigen::MatrixXd cross = l_pose * p_.topRows<3>();  // 2 x n
  grown.bottomLeftCorner(2, n) = cross;
  grown.topRightCorner(n, 2) = cross.transpose();
  const Eigen::Matrix2d landmark_block =
      l_pose * p_.topLeftCorner<3, 3>() * l_pose.transpose() + l_z * o.covariance * l_z.transpose();
  grown.bottomRightCorner<2, 2>() = 0.5 * (landmark_block + landmark_block.transpose());
  p_ = std::move(grown);
  Landmark lm;
  lm.id = id;
  lm.index = n;
  if (o.cls != core::ConeClass::kUnknown) lm.class_votes[static_cast<int>(o.cls)] = 1;
  lm.label = label;
  lm.first_travel_m = travel_m_;
  lm.last_seen_travel_m = travel_m_;
  lm.at_start = (l - start_.position()).norm() < config_.start_radius_m &&
                travel_m_ < config_.loop_min_travel_m / 2;
  landmarks_.push_back(lm);
}

void EkfSlam::handle_unmatched(const core::ConeObservations& obs) {
  // forget the preliminary landmarks that were not confirmed in time
  preliminary_dropped_ += static_cast<int>(std::erase_if(preliminary_, [&](const Preliminary& p) {
    return travel_m_ - p.first_travel_m > config_.preliminary_max_travel_m;
  }));
  const core::Pose2 now = pose();
  std::vector<char> seen_now(preliminary_.size(), 0);
  const int n_obs = static_cast<int>(obs.cones.size());
  for (int i = 0; i < n_obs; ++i) {
    if (associations_[i].kind == Association::Kind::kMatched) continue;
    const core::ConeObservation& o = obs.cones[i];
    const core::Vec2 q = now.transform(o.position);
    // near a landmark (also an old one) and statistically possibly the same cone: a duplicate
    // or clutter, nothing new (the pose's and the landmark's marginal covariances, without
    // their cross term: a wider gate, so fewer duplicates); a cone a few decimetres from a
    // landmark that the uncertainty cannot explain (the paired big orange cones of a gate) is new
    bool near = false;
    for (const Landmark& lm : landmarks_) {
      const core::Vec2 l = landmark_position(lm);
      if ((l - q).norm() >= config_.new_landmark_min_distance_m) continue;
      Eigen::Matrix<double, 2, 3> h_pose;
      Eigen::Matrix2d h_landmark;
      const core::Vec2 predicted = predict_observation(now, l, &h_pose, &h_landmark);
      const Eigen::Matrix2d s =
          h_pose * p_.topLeftCorner<3, 3>() * h_pose.transpose() +
          h_landmark * p_.block<2, 2>(lm.index, lm.index) * h_landmark.transpose() + o.covariance;
      const Eigen::Vector2d v = o.position - predicted;
      if (v.dot(s.ldlt().solve(v)) < config_.new_landmark_chi2) near = true;
    }
    if (near) continue;  // rejected
    // the nearest preliminary landmark of a compatible class, once per frame
    int best = -1;
    double best_d = config_.preliminary_radius_m;
    for (size_t k = 0; k < preliminary_.size(); ++k) {
      if (seen_now[k]) continue;
      const double d = (preliminary_[k].position - q).norm();
      // (the ideal association pairs by the true cone)
      const bool ideal = config_.association.method == AssociationMethod::kIdeal;
      if (ideal ? label_of(i) >= 0 && preliminary_[k].label == label_of(i)
                : d < best_d && class_compatible(o.cls, preliminary_[k].class_votes, 1)) {
        best_d = d;
        best = static_cast<int>(k);
      }
    }
    if (best < 0) {
      Preliminary p;
      p.id = next_id_++;
      p.position = q;
      if (o.cls != core::ConeClass::kUnknown) p.class_votes[static_cast<int>(o.cls)] = 1;
      p.sightings = 1;
      p.first_travel_m = travel_m_;
      p.label = label_of(i);
      preliminary_.push_back(p);
      seen_now.push_back(1);
      associations_[i] = {p.id, Association::Kind::kNew};
      if (confirm_sightings() <= 1) {
        add_landmark(o, p.id, p.label);
        preliminary_.pop_back();
        seen_now.pop_back();
      }
      continue;
    }
    Preliminary& p = preliminary_[best];
    seen_now[best] = 1;
    ++p.sightings;
    p.position += (q - p.position) / p.sightings;
    if (o.cls != core::ConeClass::kUnknown) ++p.class_votes[static_cast<int>(o.cls)];
    associations_[i] = {p.id, Association::Kind::kMatched};
    if (p.sightings >= confirm_sightings()) {
      // confirmed: into the filter from this sighting, with the votes gathered so far
      const std::array<int, 5> votes = p.class_votes;
      add_landmark(o, p.id, p.label);
      landmarks_.back().class_votes = votes;
      preliminary_.erase(preliminary_.begin() + best);
      seen_now.erase(seen_now.begin() + best);
    }
  }
}

std::vector<std::pair<std::string, double>> EkfSlam::statistics() const {
  return {{"landmarks", static_cast<double>(landmarks_.size())},
          {"preliminary_dropped", static_cast<double>(preliminary_dropped_)}};
}

void EkfSlam::enter_localisation() {
  // the map is fixed with its marginal covariances; the state keeps the pose only
  fixed_position_.clear();
  fixed_covariance_.clear();
  for (Landmark& lm : landmarks_) {
    fixed_position_.push_back(landmark_position(lm));
    fixed_covariance_.push_back(p_.block<2, 2>(lm.index, lm.index));
    lm.index = static_cast<int>(fixed_position_.size()) - 1;
  }
  x_.conservativeResize(3);
  const Eigen::Matrix3d pose_cov = p_.topLeftCorner<3, 3>();
  p_ = pose_cov;
  preliminary_dropped_ += static_cast<int>(preliminary_.size());
  preliminary_.clear();
  phase_ = core::SlamPhase::kLocalisation;
  map_complete_ = true;
}

core::Estimate EkfSlam::estimate() const {
  core::Estimate e;
  e.stamp = stamp_;
  e.pose = pose();
  e.speed_mps = speed_mps_;
  e.yaw_rate_rps = yaw_rate_rps_;
  e.phase = phase_;
  e.map_complete = map_complete_;
  const bool localising = phase_ == core::SlamPhase::kLocalisation;
  for (const Landmark& lm : landmarks_) {
    core::MapCone c;
    c.id = lm.id;
    c.cls = voted_class(lm.class_votes);
    c.position = localising ? fixed_position_[lm.index] : landmark_position(lm);
    c.covariance = localising ? fixed_covariance_[lm.index] : p_.block<2, 2>(lm.index, lm.index);
    e.map.push_back(c);
  }
  return e;
}

}  // namespace conesim::slam
