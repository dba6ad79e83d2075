#include "sim/slam_score.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "sim/evaluation.hpp"

namespace conesim::sim {

namespace {

nlohmann::json pose_json(const core::Pose2& p) {
  return nlohmann::json{{"x_m", p.x}, {"y_m", p.y}, {"yaw_rad", p.yaw}};
}

// the root mean square, NaN (null in the JSON) when there is nothing to average
double rms(const std::vector<double>& squares) {
  if (squares.empty()) return NAN;
  double sum = 0.0;
  for (double s : squares) sum += s;
  return std::sqrt(sum / squares.size());
}

// the classes scored one by one, in the order of the per-class figures
constexpr std::array<core::ConeClass, 4> kScoredClasses = {
    core::ConeClass::kBlue, core::ConeClass::kYellow, core::ConeClass::kOrangeSmall,
    core::ConeClass::kOrangeBig};

// position of a class in kScoredClasses, -1 for unknown
int class_slot(core::ConeClass c) {
  for (size_t k = 0; k < kScoredClasses.size(); ++k)
    if (kScoredClasses[k] == c) return static_cast<int>(k);
  return -1;
}

// a JSON number, or null where nothing was measured
nlohmann::json number_or_null(double v) {
  return std::isnan(v) ? nlohmann::json() : nlohmann::json(v);
}

}  // namespace

double nearest_rank_percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[static_cast<size_t>(q * (v.size() - 1) + 0.5)];
}

SlamScorer::SlamScorer(const tracks::Track& track, const PerceptionView& view)
    : track_(track), view_(view) {
  cone_observed_.assign(static_cast<size_t>(track.next_id()), 0);
  cone_in_view_.assign(static_cast<size_t>(track.next_id()), 0);
  cone_index_.assign(static_cast<size_t>(track.next_id()), -1);
  for (size_t k = 0; k < track.cones.size(); ++k)
    cone_index_[track.cones[k].id] = static_cast<int>(k);
}

void SlamScorer::set_prior_map_identities() {
  for (size_t k = 0; k < track_.cones.size(); ++k)
    landmark_votes_[static_cast<int>(k)][track_.cones[k].id] = std::numeric_limits<int>::max() / 2;
}

void SlamScorer::note_cones_in_view(const core::Pose2& pose) {
  // within [min_range_m, max_range_m] of the sensor and within half the field of view of the
  // sensor's heading, the sensor sensor_x_m ahead of the rear axle
  const double half_fov_rad = 0.5 * view_.fov_deg * std::numbers::pi / 180.0;
  for (const tracks::Cone& c : track_.cones) {
    const core::Vec2 local = pose.inverse_transform(c.position) - core::Vec2(view_.sensor_x_m, 0.0);
    const double range_m = local.norm();
    if (range_m < view_.min_range_m || range_m > view_.max_range_m) continue;
    if (std::abs(std::atan2(local.y(), local.x())) > half_fov_rad) continue;
    cone_in_view_[c.id] = 1;
  }
}

void SlamScorer::score(const Update& u) {
  update_cpu_ms_.push_back(u.cpu_ms);
  update_ms_.push_back(u.wall_ms);
  if (u.association_us >= 0.0) association_us_.push_back(u.association_us);

  // trajectory error at the capture time, no alignment
  const core::Pose2& truth = u.true_pose;
  const core::Pose2& est = u.estimate->pose;
  position_error2_.push_back((est.position() - truth.position()).squaredNorm());
  yaw_error2_.push_back(std::pow(core::normalize_angle(est.yaw - truth.yaw), 2));
  const double travelled =
      true_path_.empty()
          ? 0.0
          : true_odometer_.back() + (truth.position() - true_path_.back().position()).norm();
  true_path_.push_back(truth);
  estimated_path_.push_back(est);
  stamps_.push_back(u.stamp);
  true_odometer_.push_back(travelled);

  // associations against the labels: a match is right when the landmark's majority cone is
  // the observation's true cone (a track cone, or a spare cone standing off the track)
  const auto& associations = *u.associations;
  const auto& true_ids = *u.true_ids;
  for (size_t i = 0; i < associations.size() && i < true_ids.size(); ++i) {
    const int true_id = true_ids[i];
    if (true_id >= 0 && true_id < static_cast<int>(cone_observed_.size()))
      cone_observed_[true_id] = 1;
    const auto& a = associations[i];
    if (a.kind == slam::Association::Kind::kRejected) {
      if (true_id >= 0) ++da_rejected_;
      continue;
    }
    auto& votes = landmark_votes_[a.landmark_id];
    if (a.kind == slam::Association::Kind::kMatched) {
      int majority = -3, best = 0;
      for (const auto& [id, n] : votes)
        if (n > best) best = n, majority = id;
      if (majority == true_id &&
          (true_id >= 0 || core::ObservationLabels::is_off_track_cone(true_id))) {
        ++da_correct_;
      } else {
        ++da_wrong_;
        if (u.observations && i < u.observations->cones.size())
          wrong_association_places_.push_back(truth.transform(u.observations->cones[i].position));
      }
    }
    ++votes[true_id];
  }

  // a loop closure is false unless the car really is back near where it was long before
  for (; loop_closures_ < u.loop_closures; ++loop_closures_) {
    bool real = false;
    for (size_t j = 0; j < true_path_.size(); ++j) {
      if (travelled - true_odometer_[j] < kLoopTruthMinTravelM) break;
      if ((true_path_[j].position() - truth.position()).norm() < kLoopTruthRadiusM) real = true;
    }
    if (!real) ++false_loop_closures_;
    loop_closure_events_.push_back({{"t_s", core::to_seconds(u.stamp)},
                                    {"travel_m", travelled},
                                    {"true_pose", pose_json(truth)},
                                    {"estimated_pose", pose_json(est)},
                                    {"false", !real}});
  }

  // the map error every few metres driven
  if (travelled >= next_map_snapshot_m_) {
    snapshot_map_error(travelled, *u.estimate);
    while (next_map_snapshot_m_ <= travelled) next_map_snapshot_m_ += kMapSnapshotEveryM;
  }
}

void SlamScorer::snapshot_map_error(double distance_m, const core::Estimate& e) {
  // the map now against the true cones observed so far, no alignment
  std::vector<core::Vec2> estimated, truth;
  std::vector<int> truth_slot;
  for (const core::MapCone& c : e.map) estimated.push_back(c.position);
  for (const tracks::Cone& c : track_.cones) {
    if (!cone_observed_[c.id]) continue;
    truth.push_back(c.position);
    truth_slot.push_back(class_slot(c.cls));
  }
  const std::vector<int> match = match_points(estimated, truth, kMatchCutoffM);

  // rmse overall (slot 0) and by the true cone's class (slots 1..4)
  std::array<double, 5> sum2{}, n{};
  for (size_t i = 0; i < match.size(); ++i) {
    if (match[i] < 0) continue;
    const double err2 = (estimated[i] - truth[match[i]]).squaredNorm();
    sum2[0] += err2, n[0] += 1;
    if (const int k = truth_slot[match[i]]; k >= 0) sum2[k + 1] += err2, n[k + 1] += 1;
  }
  MapErrorSnapshot snapshot;
  snapshot.distance_m = distance_m;
  snapshot.matched = static_cast<int>(n[0]);
  for (size_t k = 0; k < sum2.size(); ++k)
    snapshot.rmse_m[k] = n[k] > 0 ? std::sqrt(sum2[k] / n[k]) : NAN;
  map_error_over_distance_.push_back(snapshot);
}

std::vector<SlamScorer::MapMatch> SlamScorer::match_map(
    const std::vector<core::MapCone>& map) const {
  std::vector<core::Vec2> estimated, truth;
  for (const core::MapCone& c : map) estimated.push_back(c.position);
  for (const tracks::Cone& c : track_.cones) truth.push_back(c.position);
  const std::vector<int> match = match_points(estimated, truth, kMatchCutoffM);
  std::vector<MapMatch> matches;
  for (size_t i = 0; i < map.size(); ++i) {
    MapMatch m{map[i], -1, 0.0};
    if (match[i] >= 0) {
      m.true_cone_id = track_.cones[match[i]].id;
      m.error_m = (estimated[i] - truth[match[i]]).norm();
    }
    matches.push_back(m);
  }
  return matches;
}

nlohmann::json SlamScorer::metrics(const core::Estimate& e) const {
  // map: matched one to one to the true cones, no alignment
  const std::vector<MapMatch> matches = match_map(e.map);
  std::vector<double> err2;
  std::vector<char> true_used(static_cast<size_t>(track_.next_id()), 0);
  int class_wrong = 0;
  for (const MapMatch& m : matches) {
    if (m.true_cone_id < 0) continue;
    err2.push_back(m.error_m * m.error_m);
    true_used[m.true_cone_id] = 1;
    if (m.estimate.cls != true_cone(m.true_cone_id).cls) ++class_wrong;
  }
  // missed: a true cone that was in the perception's view at some moment of the run and that
  // no map landmark was matched to, whether or not the perception reported it; observed:
  // reported by the perception at least once (its labels)
  int observed = 0, in_view = 0, missed = 0;
  for (const tracks::Cone& c : track_.cones) {
    observed += cone_observed_[c.id];
    if (!cone_in_view_[c.id]) continue;
    ++in_view;
    if (!true_used[c.id]) ++missed;
  }
  const int matched = static_cast<int>(err2.size());

  // per class: matched, missed and error by the true cone's class, spurious by the estimate's
  struct ClassTally {
    int matched = 0, missed = 0, spurious = 0;
    std::vector<double> err2;
  };
  std::array<ClassTally, kScoredClasses.size()> tally;
  for (const MapMatch& m : matches) {
    if (m.true_cone_id < 0) {
      if (const int k = class_slot(m.estimate.cls); k >= 0) ++tally[k].spurious;
    } else if (const int k = class_slot(true_cone(m.true_cone_id).cls); k >= 0) {
      ++tally[k].matched;
      tally[k].err2.push_back(m.error_m * m.error_m);
    }
  }
  for (const tracks::Cone& c : track_.cones)
    if (cone_in_view_[c.id] && !true_used[c.id])
      if (const int k = class_slot(c.cls); k >= 0) ++tally[k].missed;
  nlohmann::json by_class = nlohmann::json::object();
  for (size_t k = 0; k < kScoredClasses.size(); ++k)
    by_class[std::string(core::to_string(kScoredClasses[k]))] = {
        {"matched", tally[k].matched},
        {"missed", tally[k].missed},
        {"spurious", tally[k].spurious},
        {"rmse_m", number_or_null(rms(tally[k].err2))}};

  // the map aligned: the rigid transform that best lays the matched estimates on their true
  // cones, then matched again
  std::vector<core::Vec2> from, to;
  for (const MapMatch& m : matches) {
    if (m.true_cone_id < 0) continue;
    from.push_back(m.estimate.position);
    to.push_back(true_cone(m.true_cone_id).position);
  }
  const core::Pose2 map_alignment = align_se2(from, to);
  std::vector<core::Vec2> aligned, truth;
  for (const core::MapCone& c : e.map) aligned.push_back(map_alignment.transform(c.position));
  for (const tracks::Cone& c : track_.cones) truth.push_back(c.position);
  const std::vector<int> aligned_match = match_points(aligned, truth, kMatchCutoffM);
  std::vector<double> aligned_err2;
  for (size_t i = 0; i < aligned.size(); ++i)
    if (aligned_match[i] >= 0)
      aligned_err2.push_back((aligned[i] - truth[aligned_match[i]]).squaredNorm());

  // the trajectory aligned: the estimated path laid on the true one
  std::vector<core::Vec2> est_positions, true_positions;
  for (size_t i = 0; i < true_path_.size(); ++i) {
    est_positions.push_back(estimated_path_[i].position());
    true_positions.push_back(true_path_[i].position());
  }
  const core::Pose2 path_alignment = align_se2(est_positions, true_positions);
  std::vector<double> ate_aligned2, yaw_aligned2;
  for (size_t i = 0; i < true_path_.size(); ++i) {
    const core::Pose2 est = path_alignment.compose(estimated_path_[i]);
    ate_aligned2.push_back((est.position() - true_path_[i].position()).squaredNorm());
    yaw_aligned2.push_back(std::pow(core::normalize_angle(est.yaw - true_path_[i].yaw), 2));
  }
  const int total_da = da_correct_ + da_wrong_;
  nlohmann::json m = {
      {"map_rmse_m", number_or_null(rms(err2))},
      {"map_matched", matched},
      {"map_missed", missed},
      {"map_spurious", static_cast<int>(e.map.size()) - matched},
      {"map_cones_in_view", in_view},
      {"map_missed_fraction",
       in_view ? nlohmann::json(static_cast<double>(missed) / in_view) : nlohmann::json()},
      {"map_cones_observed", observed},
      {"map_class_wrong", class_wrong},
      {"map_rmse_aligned_m", number_or_null(rms(aligned_err2))},
      {"map_matched_aligned", aligned_err2.size()},
      {"map_alignment", pose_json(map_alignment)},
      {"by_class", by_class},
      {"ate_rmse_m", number_or_null(rms(position_error2_))},
      {"yaw_rmse_rad", number_or_null(rms(yaw_error2_))},
      {"ate_rmse_aligned_m", number_or_null(rms(ate_aligned2))},
      {"yaw_rmse_aligned_rad", number_or_null(rms(yaw_aligned2))},
      {"trajectory_alignment", pose_json(path_alignment)},
      {"da_correct", da_correct_},
      {"da_wrong", da_wrong_},
      {"da_rejected", da_rejected_},
      {"da_correct_fraction",
       total_da ? nlohmann::json(static_cast<double>(da_correct_) / total_da) : nlohmann::json()},
      {"loop_closures", loop_closures_},
      {"false_loop_closures", false_loop_closures_},
      {"loop_closure_events", loop_closure_events_},
      {"phase", e.phase == core::SlamPhase::kLocalisation ? "localisation" : "mapping"},
      {"updates", update_ms_.size()},
      {"update_ms_median", nearest_rank_percentile(update_ms_, 0.5)},
      {"update_ms_p99", nearest_rank_percentile(update_ms_, 0.99)},
      {"update_cpu_ms_median", nearest_rank_percentile(update_cpu_ms_, 0.5)},
      {"update_cpu_ms_p99", nearest_rank_percentile(update_cpu_ms_, 0.99)},
  };
  // the map error every 10 m driven, all classes and per class (FST Figs 4.6-4.8)
  nlohmann::json over_distance = nlohmann::json::array();
  for (const MapErrorSnapshot& row : map_error_over_distance_) {
    nlohmann::json r = {{"distance_m", row.distance_m},
                        {"matched", row.matched},
                        {"rmse_m", number_or_null(row.rmse_m[0])}};
    for (size_t k = 0; k < kScoredClasses.size(); ++k)
      r[std::string(core::to_string(kScoredClasses[k])) + "_m"] = number_or_null(row.rmse_m[k + 1]);
    over_distance.push_back(r);
  }
  m["map_error_over_distance"] = over_distance;
  if (!association_us_.empty()) {
    m["association_us_median"] = nearest_rank_percentile(association_us_, 0.5);
    m["association_us_p99"] = nearest_rank_percentile(association_us_, 0.99);
  } else {
    m["association_us_median"] = nullptr;
    m["association_us_p99"] = nullptr;
  }
  return m;
}

}  // namespace conesim::sim
