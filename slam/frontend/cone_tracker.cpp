// Frame-to-frame cone tracking: predict every track into the new vehicle frame with the
// odometry, gate observation-track pairs by the Bhattacharyya distance, assign them jointly (the
// least total distance), fuse, vote on the colour, start tracks for the rest, drop the lost.

#include "slam/frontend/cone_tracker.hpp"

#include "core/assignment.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace conesim::slam::frontend {

core::Pose2 motion_over(double speed_mps, double yaw_rate_rps, double dt_s) {
  const double dyaw = yaw_rate_rps * dt_s;
  const double ds = speed_mps * dt_s;
  // the chord of the arc, at half the heading change
  return {ds * std::cos(0.5 * dyaw), ds * std::sin(0.5 * dyaw), dyaw};
}

double bhattacharyya_distance(const core::Vec2& mean_a, const Eigen::Matrix2d& cov_a,
                              const core::Vec2& mean_b, const Eigen::Matrix2d& cov_b) {
  // a degenerate covariance matches nothing
  const double det_ab = cov_a.determinant() * cov_b.determinant();
  if (!(det_ab > 0.0)) return std::numeric_limits<double>::infinity();
  const Eigen::Matrix2d cov = 0.5 * (cov_a + cov_b);
  const core::Vec2 d = mean_a - mean_b;
  const double mahalanobis2 = d.dot(cov.ldlt().solve(d));
  return 0.125 * mahalanobis2 + 0.5 * std::log(cov.determinant() / std::sqrt(det_ab));
}

std::string TrackerConfig::validate() const {
  std::ostringstream e;
  if (!(max_bhattacharyya > 0.0))
    e << "max_bhattacharyya: expected > 0, got " << max_bhattacharyya;
  else if (max_missed_frames < 1)
    e << "max_missed_frames: expected >= 1, got " << max_missed_frames;
  else if (!(motion_noise_m2 >= 0.0))
    e << "motion_noise_m2: expected >= 0, got " << motion_noise_m2;
  return e.str();
}

ConeTracker::ConeTracker(const TrackerConfig& config) : config_(config) {
  const std::string error = config_.validate();
  if (!error.empty()) throw std::invalid_argument("cone tracker: " + error);
}

int ConeTracker::live_tracks() const {
  return static_cast<int>(tracks_.size());
}

core::ConeObservations ConeTracker::update(const core::ConeObservations& frame,
                                           const core::Pose2& motion) {
  // predict: each track into the new vehicle frame, its covariance rotated and grown
  const double c = std::cos(motion.yaw), s = std::sin(motion.yaw);
  Eigen::Matrix2d to_new;  // rotation from the previous frame's axes to the new one's
  to_new << c, s, -s, c;
  for (Track& t : tracks_) {
    t.position = motion.inverse_transform(t.position);
    t.covariance = to_new * t.covariance * to_new.transpose() +
                   Eigen::Matrix2d::Identity() * config_.motion_noise_m2;
  }

  // assign: the least total Bhattacharyya distance over the frame, an observation that starts a
  // new track costing the gate (a pair is made where it beats a new track, never beyond the
  // gate). Pair by pair from the closest, one noisy observation could take its neighbour's
  // track and push the neighbour's observation onto the next one (a swap).
  const size_t n_obs = frame.cones.size(), n_tracks = tracks_.size();
  const double inf = std::numeric_limits<double>::infinity();
  Eigen::MatrixXd cost = Eigen::MatrixXd::Constant(static_cast<Eigen::Index>(n_obs),
                                                   static_cast<Eigen::Index>(n_tracks + n_obs), inf);
  for (size_t o = 0; o < n_obs; ++o) {
    for (size_t k = 0; k < n_tracks; ++k) {
      const double d = bhattacharyya_distance(frame.cones[o].position, frame.cones[o].covariance,
                                              tracks_[k].position, tracks_[k].covariance);
      // a pair costs its distance less the new track it saves (the observation's own column)
      if (d <= config_.max_bhattacharyya)
        cost(static_cast<Eigen::Index>(o), static_cast<Eigen::Index>(k)) =
            d - config_.max_bhattacharyya;
    }
    cost(static_cast<Eigen::Index>(o), static_cast<Eigen::Index>(n_tracks + o)) = 0.0;
  }
  // every observation has its own "new track" column, so the maximal assignment pairs them all
  // and the cheapest of those is the optimum above
  const std::vector<int> column = core::hungarian_assign(cost, inf);
  std::vector<int> track_of(n_obs, -1);
  std::vector<bool> track_taken(n_tracks, false);
  for (size_t o = 0; o < n_obs; ++o)
    if (column[o] >= 0 && column[o] < static_cast<int>(n_tracks)) {
      track_of[o] = column[o];
      track_taken[static_cast<size_t>(column[o])] = true;
    }

  // update the matched tracks (Kalman fusion of the two Gaussians), start new ones
  core::ConeObservations out = frame;
  for (size_t o = 0; o < frame.cones.size(); ++o) {
    const core::ConeObservation& z = frame.cones[o];
    if (track_of[o] < 0) {
      track_of[o] = static_cast<int>(tracks_.size());
      Track t;
      t.id = next_id_++;
      t.position = z.position;
      t.covariance = z.covariance;
      tracks_.push_back(t);
      track_taken.push_back(true);
    } else {
      Track& t = tracks_[static_cast<size_t>(track_of[o])];
      const Eigen::Matrix2d gain = t.covariance * (t.covariance + z.covariance).inverse();
      t.position += gain * (z.position - t.position);
      t.covariance = (Eigen::Matrix2d::Identity() - gain) * t.covariance;
      t.missed = 0;
    }

    // the colour vote: the class with most votes; a tie keeps the class decided before
    Track& t = tracks_[static_cast<size_t>(track_of[o])];
    if (z.cls != core::ConeClass::kUnknown) {
      const int voted = static_cast<int>(z.cls);
      ++t.votes[static_cast<size_t>(voted)];
      const int held = t.cls == core::ConeClass::kUnknown ? -1 : static_cast<int>(t.cls);
      int leader = held >= 0 ? held : voted;
      for (int k = 0; k < 4; ++k)
        if (t.votes[static_cast<size_t>(k)] > t.votes[static_cast<size_t>(leader)]) leader = k;
      t.cls = static_cast<core::ConeClass>(leader);
    }
    out.cones[o].track_id = t.id;
    out.cones[o].cls = t.cls;
  }

  // tracks not seen this frame: count the miss, drop after max_missed_frames
  for (size_t k = 0; k < tracks_.size(); ++k)
    if (!track_taken[k]) ++tracks_[k].missed;
  std::erase_if(tracks_, [this](const Track& t) { return t.missed >= config_.max_missed_frames; });
  return out;
}

}  // namespace conesim::slam::frontend
