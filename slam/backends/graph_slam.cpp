#include "slam/backends/graph_slam.hpp"

#include <ceres/ceres.h>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <unordered_set>

#include "slam/backends/graph_residuals.hpp"
#include "slam/odometry.hpp"

namespace conesim::slam {

namespace {

// an odometry interval driven at under this speed on average and at its end is a standstill, m/s
// (the odometry's own standstill speed for the gyro's calibration; the wheels' noise drives a
// standing car 0.2-0.4 mm in a 0.1 s interval)
constexpr double kStandstillSpeedMps = 0.05;

// solver options for small dense windows and for the big sparse global problem
ceres::Solver::Options solver_options(int iterations, bool sparse) {
  ceres::Solver::Options o;
  o.linear_solver_type = sparse ? ceres::SPARSE_NORMAL_CHOLESKY : ceres::DENSE_SCHUR;
  o.max_num_iterations = iterations;
  o.num_threads = 1;
  o.logging_type = ceres::SILENT;
  o.minimizer_progress_to_stdout = false;
  return o;
}

// problems borrow the cost and loss functions owned by the graph
ceres::Problem::Options problem_options() {
  ceres::Problem::Options o;
  o.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  o.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  return o;
}

}  // namespace

std::string GraphSlamConfig::validate() const {
  std::ostringstream s;
  if (confirm_sightings < 1)
    s << "graph_slam.confirm_sightings: expected >= 1";
  else if (window_poses < 1)
    s << "graph_slam.window_poses: expected >= 1";
  else if (!(max_range_m > min_range_m))
    s << "graph_slam.max_range_m: expected > min_range_m";
  else if (!(fov_deg > 0.0 && fov_deg <= 360.0))
    s << "graph_slam.fov_deg: expected in (0, 360]";
  else if (!(icr_sigma_m >= 0.0))
    s << "graph_slam.icr_sigma_m: expected >= 0";
  else if (!(observation_huber > 0.0))
    s << "graph_slam.observation_huber: expected > 0";
  else if (localisation_window_poses < 1)
    s << "graph_slam.localisation_window_poses: expected >= 1";
  else if (!(gyro_bias_sigma_rps >= 0.0))
    s << "graph_slam.gyro_bias_sigma_rps: expected >= 0";
  if (!s.str().empty()) return s.str();
  return loop_closure.validate();
}

GraphSlam::GraphSlam(const GraphSlamConfig& config)
    : config_(config), huber_(std::make_unique<ceres::HuberLoss>(config.observation_huber)) {
  if (config_.gyro_bias_sigma_rps > 0.0)
    gyro_bias_prior_.reset(GyroBiasPrior::Create(config_.gyro_bias_sigma_rps));
  reset({}, 0);
}

GraphSlam::~GraphSlam() = default;

void GraphSlam::reset(const core::Pose2& initial_pose, core::TimeUs stamp) {
  // the first pose node is the gauge: the given start pose, never moved
  poses_.clear();
  landmarks_.clear();
  edges_.clear();
  associations_.clear();
  track_bindings_ = TrackBindings(config_.association.track_memory_frames);
  PoseNode start;
  start.stamp = stamp;
  start.x = {initial_pose.x, initial_pose.y, initial_pose.yaw};
  poses_.push_back(std::move(start));
  pose_covariance_ = Eigen::Vector3d(1e-6, 1e-6, 1e-8).asDiagonal();
  phase_ = core::SlamPhase::kMapping;
  map_complete_ = false;
  loop_closures_ = 0;
  closure_due_travel_m_.reset();
  closure_seen_travel_m_ = 0.0;
  gyro_bias_rps_ = {0.0};
  first_localised_pose_ = 1;
  forgotten_poses_.clear();
  travel_m_ = 0.0;
  turned_rad_ = 0.0;
  speed_mps_ = 0.0;
  yaw_rate_rps_ = 0.0;
}

void GraphSlam::set_prior_map(const std::vector<core::MapCone>& map) {
  // known cones become fixed, confirmed landmarks; from now on the backend only localises
  for (const core::MapCone& cone : map) {
    Landmark lm;
    lm.id = static_cast<int>(landmarks_.size());
    lm.x = {cone.position.x(), cone.position.y()};
    lm.covariance = cone.covariance;
    if (cone.cls != core::ConeClass::kUnknown) lm.class_votes[static_cast<int>(cone.cls)] = 100;
    lm.confirmed = true;
    lm.fixed = true;
    landmarks_.push_back(std::move(lm));
  }
  phase_ = core::SlamPhase::kLocalisation;
  map_complete_ = true;
  first_localised_pose_ = static_cast<int>(poses_.size());
}

void GraphSlam::process(const SlamInput& input) {
  // predict, associate, update, optimise, then keep the map tidy and close the loop
  predict(input.odometry);
  labels_ = input.true_ids;
  associate_batch(input.observations);
  update(input.observations);
  record_tracks(input.observations);
  if (phase_ == core::SlamPhase::kLocalisation) {
    localise();
    return;
  }
  // (global-only: the poses stay where the odometry put them until the loop closes)
  if (!config_.global_only || loop_closures_ > 0) optimise_window();
  const LoopClosureStats stats = update_landmark_statistics();
  if (loop_closures_ > 0) return;
  if (!closure_due_travel_m_ && loop_closed(config_.loop_closure, stats)) {
    closure_due_travel_m_ = travel_m_ + config_.loop_closure.closure_delay_m;
    closure_seen_travel_m_ = travel_m_;
  }
  if (closure_due_travel_m_ && travel_m_ >= *closure_due_travel_m_) close_loop();
}

void GraphSlam::predict(const OdometryDelta& odometry) {
  // a new pose node where the odometry puts it (its heading change corrected by the gyro
  // bias), tied to the previous one
  const core::Pose2 previous_pose = poses_.back().pose();
  // standing still (no distance to speak of, the wheels at rest) the car does not move or turn,
  // whatever the gyro says: the odometry integrates it while it is still learning its bias, and
  // the heading the car set off with followed it, turning the whole map about the start (EPFL
  // track_3, seed 3: 2.6 mrad after the 5 s before the start, map RMSE 0.199 m, 0.034 m once
  // aligned). The edge holds the pose, with no bias term
  const double interval_s = core::to_seconds(odometry.to - odometry.from);
  const bool standstill = odometry.distance_m < kStandstillSpeedMps * interval_s &&
                          std::abs(odometry.speed_mps) < kStandstillSpeedMps;
  const double dt_s = standstill ? 0.0 : interval_s;
  const core::Pose2 measured = standstill ? core::Pose2{} : odometry.delta;
  core::Pose2 delta = measured;
  delta.yaw -= gyro_bias_rps_[0] * dt_s;
  const core::Pose2 pose = previous_pose.compose(delta);
  PoseNode node;
  node.stamp = odometry.to;
  node.x = {pose.x, pose.y, pose.yaw};
  travel_m_ += odometry.distance_m;
  turned_rad_ += delta.yaw;
  node.travel_m = travel_m_;
  node.odometry.reset(
      OdometryResidual::Create(measured, sqrt_information<3>(odometry.covariance), dt_s));
  if (config_.icr_sigma_m > 0.0) node.icr.reset(IcrResidual::Create(config_.icr_sigma_m));
  poses_.push_back(std::move(node));

  // the pose covariance grows by the odometry's, rotated into the map frame
  const core::Pose2 from = previous_pose;
  pose_covariance_ = compose_covariance(from, odometry, pose_covariance_);
  speed_mps_ = odometry.speed_mps;
  yaw_rate_rps_ = odometry.yaw_rate_rps;
}

std::vector<LandmarkCandidate> GraphSlam::candidates(double farthest_observation_m) const {
  // landmarks near enough to be seen, with the drift allowed since each was last seen: within
  // the sensor's range, and near every cone of the batch (a detector may report cones beyond
  // the range it sees reliably, and a landmark left out would be mapped again)
  const core::Pose2 pose = poses_.back().pose();
  const double reach =
      std::max(config_.sensor_x_m + config_.max_range_m, farthest_observation_m) + 3.0;
  const bool localising = phase_ == core::SlamPhase::kLocalisation;
  std::vector<LandmarkCandidate> out;
  for (const Landmark& lm : landmarks_) {
    if (lm.removed || (localising && !lm.confirmed)) continue;
    if ((lm.position() - pose.position()).squaredNorm() > reach * reach) continue;
    LandmarkCandidate c;
    c.id = lm.id;
    c.position = lm.position();
    c.covariance = lm.covariance;
    c.class_votes = lm.class_votes;
    c.label = lm.label;
    if (!localising) {
      c.drift_variance_m2 =
          std::min(config_.max_drift_variance_m2,
                   config_.drift_variance_m2_per_m * (travel_m_ - lm.last_seen_travel_m));
    }
    out.push_back(c);
  }
  return out;
}

void GraphSlam::add_observation_edge(int pose, int landmark,
                                     const core::ConeObservation& observation) {
  ObservationEdge edge;
  edge.pose = pose;
  edge.landmark = landmark;
  edge.measured = observation.position;
  edge.sqrt_information = sqrt_information<2>(observation.covariance);
  edge.cost.reset(ObservationResidual::Create(edge.measured, edge.sqrt_information));
  const int index = static_cast<int>(edges_.size());
  edges_.push_back(std::move(edge));
  poses_[pose].edges.push_back(index);
  landmarks_[landmark].edges.push_back(index);
}

void GraphSlam::add_motion_edges(ceres::Problem& problem, int pose) {
  // odometry (through the gyro bias) and ICR edges from the previous pose
  PoseNode& node = poses_[pose];
  PoseNode& previous = poses_[pose - 1];
  problem.AddResidualBlock(node.odometry.get(), nullptr, previous.x.data(), node.x.data(),
                           gyro_bias_rps_.data());
  if (node.icr) problem.AddResidualBlock(node.icr.get(), nullptr, previous.x.data(), node.x.data());
}

void GraphSlam::associate_batch(const core::ConeObservations& observations) {
  // against the landmarks in reach; new landmarks only while mapping
  double farthest_m = 0.0;
  for (const core::ConeObservation& o : observations.cones)
    farthest_m = std::max(farthest_m, o.position.norm());
  const std::vector<LandmarkCandidate> in_reach = candidates(farthest_m);
  const auto start = std::chrono::steady_clock::now();
  const bool allow_new = phase_ == core::SlamPhase::kMapping;
  const bool tracking = config_.method ? config_.method->method == AssociationMethod::kTrackingAided
                                       : config_.association.use_track_ids;
  const TrackBindings* tracks = tracking ? &track_bindings_ : nullptr;
  std::vector<int>* evidence = tracking ? &evidence_ : nullptr;
  evidence_.clear();
  associations_ = config_.method
                      ? associate_with_method(*config_.method, config_.association,
                                              poses_.back().pose(), &pose_covariance_, in_reach,
                                              observations, allow_new, &labels_, tracks, evidence)
                      : associate(config_.association, poses_.back().pose(), &pose_covariance_,
                                  in_reach, observations, allow_new, tracks, evidence);
  association_us_ =
      std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count();
}

void GraphSlam::update(const core::ConeObservations& observations) {
  const int pose_index = static_cast<int>(poses_.size()) - 1;
  const core::Pose2 pose = poses_.back().pose();
  const bool mapping = phase_ == core::SlamPhase::kMapping;
  Eigen::Matrix3d pose_information = pose_covariance_.inverse();

  for (size_t i = 0; i < observations.cones.size(); ++i) {
    const core::ConeObservation& obs = observations.cones[i];
    Association& a = associations_[i];
    if (a.kind == Association::Kind::kRejected) continue;

    // a new landmark where the observation puts it, with the observation's covariance
    if (a.kind == Association::Kind::kNew) {
      Landmark lm;
      lm.id = static_cast<int>(landmarks_.size());
      const core::Vec2 p = pose.transform(obs.position);
      lm.x = {p.x(), p.y()};
      const Eigen::Matrix2d rot = Eigen::Rotation2Dd(pose.yaw).toRotationMatrix();
      lm.covariance = rot * obs.covariance * rot.transpose();
      lm.first_travel_m = travel_m_;
      lm.first_heading_rad = pose.yaw;
      if (i < labels_.size()) lm.label = labels_[i];
      landmarks_.push_back(std::move(lm));
      a.landmark_id = landmarks_.back().id;
    }
    Landmark& lm = landmarks_[a.landmark_id];

    // a matched observation informs the pose (for the next gate)
    if (a.kind == Association::Kind::kMatched) {
      Eigen::Matrix<double, 2, 3> h_pose;
      Eigen::Matrix2d h_landmark;
      predict_observation(pose, lm.position(), &h_pose, &h_landmark);
      const Eigen::Matrix2d r =
          obs.covariance + h_landmark * lm.covariance * h_landmark.transpose();
      pose_information += h_pose.transpose() * r.inverse() * h_pose;
    }

    // the landmark's EKF refines it with the observation (the pose taken as known)
    if (a.kind == Association::Kind::kMatched && !lm.fixed) {
      Eigen::Matrix2d h;
      const core::Vec2 predicted = predict_observation(pose, lm.position(), nullptr, &h);
      const Eigen::Matrix2d s = h * lm.covariance * h.transpose() + obs.covariance;
      const Eigen::Matrix2d k = lm.covariance * h.transpose() * s.inverse();
      const core::Vec2 x = lm.position() + k * (obs.position - predicted);
      lm.x = {x.x(), x.y()};
      lm.covariance = (Eigen::Matrix2d::Identity() - k * h) * lm.covariance;
    }

    // bookkeeping: sightings, class votes, track id, and an edge while mapping
    ++lm.sightings;
    lm.last_seen_travel_m = travel_m_;
    if (obs.cls != core::ConeClass::kUnknown) ++lm.class_votes[static_cast<int>(obs.cls)];
    if (lm.sightings >= config_.confirm_sightings) lm.confirmed = true;
    if (mapping) {
      add_observation_edge(pose_index, lm.id, obs);
    } else {
      poses_.back().localisation.push_back(
          {std::unique_ptr<ceres::CostFunction>(
               ObservationResidual::Create(obs.position, sqrt_information<2>(obs.covariance))),
           lm.id});
    }
  }
  pose_covariance_ = pose_information.inverse();
}

void GraphSlam::record_tracks(const core::ConeObservations& observations) {
  // tracking-aided: each track's evidence is the landmark its observation paired with without
  // the tracks, or the landmark it started
  if (evidence_.size() != observations.cones.size()) return;
  std::vector<int> tracks(observations.cones.size());
  for (size_t i = 0; i < tracks.size(); ++i) {
    tracks[i] = observations.cones[i].track_id;
    if (evidence_[i] < 0 && associations_[i].kind == Association::Kind::kNew)
      evidence_[i] = associations_[i].landmark_id;
  }
  track_bindings_.record(tracks, evidence_);
}

void GraphSlam::fold_edges_before(int first) {
  std::vector<int> touched;
  for (; folded_poses_ < first; ++folded_poses_) {
    const PoseNode& node = poses_[folded_poses_];
    for (int e : node.edges) {
      const ObservationEdge& edge = edges_[e];
      Landmark& lm = landmarks_[edge.landmark];
      fold_observation(node.pose(), edge.measured, edge.sqrt_information, lm.folded_information,
                       lm.folded_weighted_mean);
      touched.push_back(edge.landmark);
    }
  }
  std::sort(touched.begin(), touched.end());
  touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
  for (int id : touched) {
    Landmark& lm = landmarks_[id];
    lm.folded_prior =
        std::make_unique<LandmarkPriorResidual>(lm.folded_information, lm.folded_weighted_mean);
  }
}

void GraphSlam::unfold_all() {
  for (Landmark& lm : landmarks_) {
    lm.folded_information.setZero();
    lm.folded_weighted_mean.setZero();
    lm.folded_prior.reset();
  }
  folded_poses_ = 0;
}

void GraphSlam::optimise_window() {
  // the window: the last poses free, the one before them fixed; the observations from the
  // poses before the window (fixed until the loop closes) are folded into one prior per landmark
  const int n = static_cast<int>(poses_.size());
  const int first = std::max(1, n - config_.window_poses);
  fold_edges_before(first);
  ceres::Problem problem(problem_options());
  std::vector<int> window_landmarks;
  for (int i = first; i < n; ++i) {
    add_motion_edges(problem, i);
    if (config_.landmark_edges)
      for (int e : poses_[i].edges) window_landmarks.push_back(edges_[e].landmark);
  }
  problem.SetParameterBlockConstant(poses_[first - 1].x.data());
  problem.SetParameterBlockConstant(gyro_bias_rps_.data());
  std::sort(window_landmarks.begin(), window_landmarks.end());
  window_landmarks.erase(std::unique(window_landmarks.begin(), window_landmarks.end()),
                         window_landmarks.end());

  // the window's landmarks: their prior from the older poses, and their observations from the
  // window's poses
  for (int id : window_landmarks) {
    Landmark& lm = landmarks_[id];
    if (lm.removed) continue;
    if (lm.folded_prior) problem.AddResidualBlock(lm.folded_prior.get(), nullptr, lm.x.data());
    for (int e : lm.edges) {
      ObservationEdge& edge = edges_[e];
      if (edge.pose < first) continue;
      problem.AddResidualBlock(edge.cost.get(), huber_.get(), poses_[edge.pose].x.data(),
                               lm.x.data());
    }
    if (lm.fixed) problem.SetParameterBlockConstant(lm.x.data());
  }

  ceres::Solver::Summary summary;
  ceres::Solve(solver_options(config_.window_iterations, false), &problem, &summary);
}

void GraphSlam::localise() {
  // the last poses against the fixed map, tied by the odometry; the one before them fixed
  const int n = static_cast<int>(poses_.size());
  const int first = std::max({1, first_localised_pose_, n - config_.localisation_window_poses});
  ceres::Problem problem(problem_options());
  for (int i = first; i < n; ++i) {
    add_motion_edges(problem, i);
    for (const LocalisationTerm& term : poses_[i].localisation) {
      double* landmark = landmarks_[term.landmark].x.data();
      problem.AddResidualBlock(term.cost.get(), huber_.get(), poses_[i].x.data(), landmark);
      problem.SetParameterBlockConstant(landmark);
    }
  }
  problem.SetParameterBlockConstant(poses_[first - 1].x.data());
  problem.SetParameterBlockConstant(gyro_bias_rps_.data());
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options(config_.localisation_iterations, false), &problem, &summary);

  // the pose leaving the window next time keeps its estimate; its terms are not needed again,
  // nor are the localised poses before it
  if (first - 1 >= first_localised_pose_) poses_[first - 1].localisation.clear();
  forget_localised_poses_before(first - 1);
}

void GraphSlam::forget_localised_poses_before(int keep) {
  if (keep <= first_localised_pose_) return;
  const auto from = poses_.begin() + first_localised_pose_;
  const auto to = poses_.begin() + keep;
  if (config_.keep_trajectory)
    for (auto it = from; it != to; ++it) forgotten_poses_.emplace_back(it->stamp, it->pose());
  poses_.erase(from, to);
}

bool GraphSlam::in_field_of_view(const core::Pose2& pose, const core::Vec2& landmark) const {
  // inside the sensor's range and opening, by the margin
  const core::Vec2 local = pose.inverse_transform(landmark) - core::Vec2(config_.sensor_x_m, 0.0);
  const double range = local.norm();
  if (range < config_.min_range_m + config_.fov_margin_m ||
      range > config_.max_range_m - config_.fov_margin_m) {
    return false;
  }
  const double half_fov = 0.5 * config_.fov_deg * M_PI / 180.0;
  const double bearing = std::atan2(local.y(), local.x());
  return std::abs(bearing) <= half_fov - config_.fov_margin_m / range;
}

void GraphSlam::remove_landmark(Landmark& landmark) {
  // its edges stay in the store but are skipped from now on
  landmark.removed = true;
  landmark.confirmed = false;
}

LoopClosureStats GraphSlam::update_landmark_statistics() {
  const core::Pose2 pose = poses_.back().pose();
  std::unordered_set<int> observed;
  for (const Association& a : associations_) {
    if (a.kind != Association::Kind::kRejected) observed.insert(a.landmark_id);
  }

  // each landmark in reach: missed or seen, its loop state, and the batch's loop statistics
  const double reach = config_.sensor_x_m + config_.max_range_m + 3.0;
  LoopClosureStats stats;
  stats.travel_m = travel_m_;
  const core::Pose2 start = poses_.front().pose();
  const LoopClosureConfig& lc = config_.loop_closure;
  stats.near_start = back_at_start(lc, start, pose, turned_rad_);
  auto count_returned = [&](const Landmark& lm) {
    ++stats.returned;
    if (lm.first_travel_m <= lc.start_window_m) ++stats.start_returned;
  };
  for (Landmark& lm : landmarks_) {
    if (lm.removed) continue;
    if (lm.loop_state == LoopState::kReturned && lm.confirmed) count_returned(lm);
    if ((lm.position() - pose.position()).squaredNorm() > reach * reach) continue;
    const bool seen = observed.count(lm.id) > 0;
    const bool in_view = in_field_of_view(pose, lm.position());

    // a landmark missed more often than seen is clutter, and so is one never confirmed: drop it
    const bool missed_too_often = in_view && !seen && ++lm.misses > lm.sightings;
    const bool stale =
        !lm.confirmed && travel_m_ - lm.first_travel_m > config_.tentative_max_travel_m;
    // (without association every observation stays a landmark: nothing is pruned)
    if ((missed_too_often || stale) && !lm.fixed && !no_association()) {
      remove_landmark(lm);
      continue;
    }

    // the loop state machine
    const double since_first_m = travel_m_ - lm.first_travel_m;
    const double heading_change = core::normalize_angle(pose.yaw - lm.first_heading_rad);
    const LoopState before = lm.loop_state;
    lm.loop_state = next_loop_state(config_.loop_closure, lm.loop_state, in_view, seen,
                                    since_first_m, heading_change);
    if (lm.confirmed && before != LoopState::kReturned && lm.loop_state == LoopState::kReturned)
      count_returned(lm);

    // old landmarks seen now: returned ones, and the big orange cue
    if (!seen || !lm.confirmed || since_first_m < config_.loop_closure.returned_min_travel_m)
      continue;
    ++stats.old_matched;
    if (lm.loop_state == LoopState::kReturned) ++stats.old_matched_returned;
    if (voted_class(lm.class_votes) == core::ConeClass::kOrangeBig &&
        std::abs(heading_change) <= config_.loop_closure.big_orange_heading_rad) {
      stats.big_orange_returned = true;
    }
  }

  return stats;
}

void GraphSlam::close_loop() {
  // the whole graph: every pose but the gauge, every landmark, every edge
  ceres::Problem problem(problem_options());
  for (size_t i = 1; i < poses_.size(); ++i) add_motion_edges(problem, static_cast<int>(i));
  problem.SetParameterBlockConstant(poses_.front().x.data());
  // the lap's heading must close: that calibrates the gyro bias the standstill left
  if (gyro_bias_prior_) {
    problem.AddResidualBlock(gyro_bias_prior_.get(), nullptr, gyro_bias_rps_.data());
  } else {
    problem.SetParameterBlockConstant(gyro_bias_rps_.data());
  }
  for (const int e : closure_edges()) {
    ObservationEdge& edge = edges_[e];
    Landmark& lm = landmarks_[edge.landmark];
    problem.AddResidualBlock(edge.cost.get(), huber_.get(), poses_[edge.pose].x.data(),
                             lm.x.data());
    if (lm.fixed) problem.SetParameterBlockConstant(lm.x.data());
  }
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options(config_.global_iterations, true), &problem, &summary);
  ++loop_closures_;
  // every pose moved: the priors folded at the old poses no longer hold
  unfold_all();
  if (!config_.landmark_edges) place_landmarks_from_poses();

  // the map is final: tentative landmarks go, the rest are fixed, and we localise from now on
  if (!config_.localise_after_loop_closure) return;
  for (Landmark& lm : landmarks_) {
    if (!lm.confirmed) remove_landmark(lm);
    lm.fixed = true;
  }
  phase_ = core::SlamPhase::kLocalisation;
  map_complete_ = true;
  first_localised_pose_ = static_cast<int>(poses_.size());
}

std::vector<int> GraphSlam::closure_edges() const {
  std::vector<int> out;
  if (config_.landmark_edges) {
    for (size_t e = 0; e < edges_.size(); ++e)
      if (!landmarks_[edges_[e].landmark].removed) out.push_back(static_cast<int>(e));
    return out;
  }
  // without landmark edges: the landmarks seen both from the start's poses and from the
  // closing poses, with only those observations (they fix the lap's end against its start)
  const double start_window_m = config_.loop_closure.start_window_m;
  auto at_start = [&](const ObservationEdge& edge) {
    return poses_[edge.pose].travel_m <= start_window_m;
  };
  auto closing = [&](const ObservationEdge& edge) {
    return poses_[edge.pose].travel_m >= closure_seen_travel_m_;
  };
  for (const Landmark& lm : landmarks_) {
    if (lm.removed) continue;
    bool seen_at_start = false, seen_closing = false;
    for (const int e : lm.edges) {
      seen_at_start = seen_at_start || at_start(edges_[e]);
      seen_closing = seen_closing || closing(edges_[e]);
    }
    if (!seen_at_start || !seen_closing) continue;
    for (const int e : lm.edges)
      if (at_start(edges_[e]) || closing(edges_[e])) out.push_back(e);
  }
  std::sort(out.begin(), out.end());
  return out;
}

void GraphSlam::place_landmarks_from_poses() {
  // each landmark at the information-weighted mean of its observations from the optimised poses
  for (Landmark& lm : landmarks_) {
    if (lm.removed || lm.fixed || lm.edges.empty()) continue;
    Eigen::Matrix2d information = Eigen::Matrix2d::Zero();
    Eigen::Vector2d weighted_mean = Eigen::Vector2d::Zero();
    for (const int e : lm.edges) {
      const ObservationEdge& edge = edges_[e];
      fold_observation(poses_[edge.pose].pose(), edge.measured, edge.sqrt_information, information,
                       weighted_mean);
    }
    const Eigen::Vector2d x = information.ldlt().solve(weighted_mean);
    lm.x = {x.x(), x.y()};
  }
}

core::Estimate GraphSlam::estimate() const {
  core::Estimate e;
  e.stamp = poses_.back().stamp;
  e.pose = poses_.back().pose();
  e.speed_mps = speed_mps_;
  e.yaw_rate_rps = yaw_rate_rps_;
  // the confirmed landmarks with their voted class and EKF covariance
  for (const Landmark& lm : landmarks_) {
    if (lm.removed || !lm.confirmed) continue;
    e.map.push_back({lm.id, voted_class(lm.class_votes), lm.position(), lm.covariance});
  }
  e.phase = phase_;
  e.map_complete = map_complete_;
  return e;
}

std::vector<std::pair<core::TimeUs, core::Pose2>> GraphSlam::stamped_trajectory() const {
  // the mapping's poses, the localised ones forgotten, the ones still held
  std::vector<std::pair<core::TimeUs, core::Pose2>> out;
  out.reserve(poses_.size() + forgotten_poses_.size());
  for (size_t i = 0; i < poses_.size(); ++i) {
    if (static_cast<int>(i) == first_localised_pose_)
      out.insert(out.end(), forgotten_poses_.begin(), forgotten_poses_.end());
    out.emplace_back(poses_[i].stamp, poses_[i].pose());
  }
  return out;
}

std::vector<core::Pose2> GraphSlam::trajectory() const {
  std::vector<core::Pose2> out;
  for (const auto& [stamp, pose] : stamped_trajectory()) out.push_back(pose);
  return out;
}

std::vector<core::TimeUs> GraphSlam::trajectory_stamps() const {
  std::vector<core::TimeUs> out;
  for (const auto& [stamp, pose] : stamped_trajectory()) out.push_back(stamp);
  return out;
}

}  // namespace conesim::slam
