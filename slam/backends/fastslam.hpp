#pragma once
// FastSLAM 1.0 and 2.0 after the FST Lisboa thesis (docs/architecture.md, "FastSLAM"): a
// particle filter over the path in which every particle carries its own map of independent 2x2
// landmark EKFs. The maps live in a persistent tree shared between particles and copied on
// write, so resampling copies a pointer and an update copies only the paths to the landmarks
// it changes. FastSLAM 2.0 samples each particle's pose from a proposal that folds the matched
// observations into the motion prediction. The weight multiplies the likelihood of the matched
// observations with a factor per new landmark, a penalty per landmark expected in the field of
// view but not seen and one per colour mismatch; low-variance resampling when the effective
// sample size falls below a threshold. Tentative landmarks are confirmed after a number of
// sightings and deleted when missed in view more often than seen. The loop closes on the
// landmarks' returned states; the best particle's map is then given to every particle and the
// filter localises on it (Monte Carlo localisation).
//
// The estimate (pose and map) is the best particle's, the one of highest weight; in
// localisation the pose is the particles' weighted mean.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <random>
#include <string>
#include <unordered_map>
#include <vector>

#include "slam/association/methods.hpp"
#include "slam/backend.hpp"
#include "slam/backends/persistent_map.hpp"
#include "slam/loop_closure.hpp"

namespace conesim::slam {

/// FastSLAM parameters (both versions).
struct FastSlamConfig {
  /// 1 or 2: FastSLAM 1.0 samples the pose from the motion model, 2.0 from the proposal that
  /// includes the matched observations (set by the back-end's name).
  int version = 2;
  /// Particles in the filter.
  int particles = 50;
  /// Resampling when the effective sample size falls below this fraction of the particles.
  double resample_fraction = 0.5;
  AssociationParams association;
  /// The weight factor of an observation that starts a new landmark or is rejected: the
  /// likelihood, per m^2, below which an observation is better explained by a new landmark
  /// (the thesis's "new landmark threshold").
  double new_landmark_likelihood = 0.02;
  /// The factor per landmark predicted inside the field of view but not seen, and per matched
  /// landmark whose voted colour disagrees with the observation's.
  double unseen_penalty = 0.9;
  double colour_mismatch_penalty = 0.5;
  /// An unmatched observation within this distance of a landmark, m, and within this squared
  /// Mahalanobis distance of it, starts nothing (a duplicate or clutter).
  double new_landmark_min_distance_m = 1.0;
  double new_landmark_chi2 = 40.0;
  /// A tentative landmark is confirmed (enters the map) after this many sightings, and is
  /// deleted when not confirmed within this distance driven since its first sighting, m.
  int confirm_sightings = 3;
  double tentative_max_travel_m = 20.0;
  /// A landmark's position relative to the car grows uncertain by this variance per metre
  /// driven since it was last seen, m^2/m, capped (the pose's drift; what lets a particle pair
  /// the old landmarks when it comes back round and FastSLAM 2.0's proposal pull it onto them).
  double drift_variance_m2_per_m = 0.002;
  double max_drift_variance_m2 = 1.0;
  /// A landmark seen again after at least this much driving out of sight, m, keeps the drift
  /// allowance it returned with for another hold_drift_m driven: the pose that drifted away
  /// from it is still off by that much on the next frames, and without the allowance the next
  /// sighting would fail the gate and start a duplicate.
  double return_gap_m = 30.0;
  double hold_drift_m = 30.0;
  /// A landmark's class is trusted in the association once its votes lead by this many.
  int class_vote_margin = 2;
  /// The odometry's covariance is scaled by this, and this is added to its heading variance
  /// per metre driven, rad^2/m (the MuJoCo car's slip is not in the odometry's own figure).
  double odometry_noise_scale = 1.0;
  double yaw_noise_per_m = 0.0;
  /// The sensor's field of view for the unseen penalty and the deletion: its mount ahead of
  /// the rear axle, range limits and opening; a landmark counts as expected only at least
  /// fov_margin_m inside it. The harness fills these from the perception.
  double sensor_x_m = 2.1;
  double min_range_m = 1.0;
  double max_range_m = 15.0;
  double fov_deg = 180.0;
  double fov_margin_m = 2.0;
  /// Loop closure: the returned-landmark statistics (returned_fraction is the thesis's loop
  /// closure factor, 0.8), and the particles' position spread (weighted standard deviation)
  /// must be below this, m.
  LoopClosureConfig loop_closure;
  double closure_max_spread_m = 0.5;
  /// Map the first loop and then localise on it (Monte Carlo localisation); false keeps mapping.
  bool localise_after_loop_closure = true;
  /// The random generator's seed (the harness derives it from the scenario's seed and the lane).
  std::uint64_t seed = 1;

  /// Empty when usable, otherwise "key: what was expected".
  std::string validate() const;
};

/// A landmark in one particle's map: its EKF and its bookkeeping.
struct FastLandmark {
  core::Vec2 mean = core::Vec2::Zero();
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Identity();
  std::array<int, 5> class_votes{};
  int sightings = 0;
  int misses = 0;
  bool confirmed = false;
  int track_id = -1;
  int label = -1;
  double first_travel_m = 0.0;
  double first_heading_rad = 0.0;
  double last_seen_travel_m = 0.0;
  /// The drift allowance held after a return (m^2), until this much has been driven (m).
  double held_drift_m2 = 0.0;
  double held_until_travel_m = -1.0;
  LoopState loop_state = LoopState::kInView;
};

class FastSlam : public Backend {
 public:
  explicit FastSlam(const FastSlamConfig& config = {});

  void reset(const core::Pose2& initial_pose, core::TimeUs stamp) override;
  void set_prior_map(const std::vector<core::MapCone>& map) override;
  void process(const SlamInput& input) override;
  core::Estimate estimate() const override;
  const std::vector<Association>& last_associations() const override;
  int loop_closures() const override { return loop_closures_; }
  std::string name() const override { return config_.version == 1 ? "fastslam1" : "fastslam2"; }
  double last_association_us() const override { return association_us_; }
  std::string estimate_source() const override {
    return phase_ == core::SlamPhase::kLocalisation ? "particles' weighted mean pose on the "
                                                      "best particle's map"
                                                    : "best particle";
  }
  /// particles, resamplings, effective_sample_size (after the last update), map_nodes (distinct
  /// landmark-tree nodes over all particles) and landmarks (in the best particle's tree).
  std::vector<std::pair<std::string, double>> statistics() const override;

  /// One particle: its pose, log weight and map, and what it did with the last frame.
  struct Particle {
    core::Pose2 pose;
    double log_weight = 0.0;
    PersistentMap<FastLandmark> map;
    std::vector<Association> associations;
    // tracking-aided association: each observation's own evidence of the last frame, as a
    // landmark id (-1: none)
    std::vector<int> evidence;
    // confirmed landmarks in the returned loop state, and those of them first seen near the
    // start (the loop closure statistics, kept as counts so that no update scans the map)
    int returned = 0;
    int start_returned = 0;
  };

  const std::vector<Particle>& particles() const { return particles_; }
  /// The particle of highest weight (the lowest index among equals).
  int best_particle() const;
  /// Each particle's log weight factor of the last frame, before normalisation and resampling.
  const std::vector<double>& last_log_factors() const { return last_log_factors_; }
  /// Resamplings so far and the effective sample size after the last update.
  int resamplings() const { return resamplings_; }
  double effective_sample_size() const { return ess_; }
  /// Distinct landmark-tree nodes over all particles (how much the maps share).
  size_t distinct_map_nodes() const;

  /// The weight factors of one frame for a particle, as logs (for tests): every matched
  /// observation's likelihood, the new-landmark factor per new or rejected observation, the
  /// unseen penalty per landmark expected in view and not seen, the colour penalty per
  /// mismatch.
  struct WeightTerms {
    double matched = 0.0;
    int new_or_rejected = 0;
    int unseen = 0;
    int colour_mismatches = 0;
  };
  double log_weight_factor(const WeightTerms& t) const;

  /// Low-variance (systematic) resampling: the indices of the particles drawn for normalised
  /// weights w with one uniform offset u in [0, 1/M).
  static std::vector<int> low_variance_resample(const std::vector<double>& weights, double u);

  /// Whether a landmark lies in the view (by the margin) from a pose.
  bool in_field_of_view(const core::Pose2& pose, const core::Vec2& landmark) const;

  /// FastSLAM 2.0's proposal after one matched observation: the pose mean and covariance
  /// (map frame) updated with observation z (covariance r) of a landmark (mean, covariance),
  /// and the log-likelihood of z under the proposal before the update.
  static double fold_observation(core::Pose2& mean, Eigen::Matrix3d& covariance,
                                 const core::Vec2& z, const Eigen::Matrix2d& r,
                                 const core::Vec2& landmark, const Eigen::Matrix2d& landmark_cov);

 private:
  // the landmark ids near a position (from the shared spatial index; a particle may lack some)
  std::vector<int> ids_near(const core::Vec2& p, double radius) const;
  void index_landmark(int id, const core::Vec2& p);
  // one particle's update; returns its frame's log weight factor
  double update_particle(Particle& particle, const SlamInput& input,
                         const std::vector<char>& usable, double reach, int id_base,
                         LoopClosureStats* stats);
  void resample();
  void normalise_weights();
  void close_loop();
  // the weighted mean and the position spread of the particles
  core::Pose2 mean_pose(double* spread_m = nullptr) const;

  FastSlamConfig config_;
  std::mt19937_64 rng_;
  std::vector<Particle> particles_;
  // landmark ids by grid cell of where they were made (shared by all particles)
  std::unordered_map<std::int64_t, std::vector<int>> index_;
  std::vector<char> indexed_;
  int next_id_ = 0;
  core::SlamPhase phase_ = core::SlamPhase::kMapping;
  bool map_complete_ = false;
  double closure_due_travel_m_ = -1.0;
  int loop_closures_ = 0;
  int resamplings_ = 0;
  double ess_ = 0.0;
  double travel_m_ = 0.0;
  /// The heading change summed since the start (not wrapped): one full turn a lap, rad.
  double turned_rad_ = 0.0;
  double speed_mps_ = 0.0;
  double yaw_rate_rps_ = 0.0;
  core::TimeUs stamp_ = 0;
  core::Pose2 start_;
  int frames_ = 0;
  double association_us_ = 0.0;
  std::vector<int> labels_;
  std::vector<double> last_log_factors_;
  // tracking-aided association's memory of the perception's tracks
  TrackBindings track_bindings_;
};

}  // namespace conesim::slam
