#pragma once
// Data association: maximum likelihood with an individual-compatibility chi-square gate, one
// landmark per observation, class compatibility, and the tracking-aided variant after the FST
// Lisboa thesis (the perception's tracks as a prior, slam/association/track_bindings.hpp).

#include <Eigen/Core>
#include <array>
#include <vector>

#include "core/autonomy_types.hpp"
#include "core/cone.hpp"
#include "core/geometry.hpp"
#include "slam/association/ambiguity.hpp"
#include "slam/association/methods.hpp"
#include "slam/backend.hpp"

namespace conesim::slam {

/// Association parameters.
struct AssociationConfig {
  /// Individual-compatibility gate on the squared Mahalanobis distance (chi-square, 2 dof):
  /// 9.21 is the 99 % quantile.
  double gate_chi2 = 9.21;
  /// An unmatched observation within this squared Mahalanobis distance of some landmark is
  /// rejected (a duplicate, a wrong colour or clutter); farther from all, it starts a new one.
  double new_landmark_chi2 = 40.0;
  /// And it must be at least this far (Euclidean) from every landmark to start a new one, m.
  double new_landmark_min_distance_m = 1.0;
  /// Use perception's track ids: the landmarks an observation's track pointed at in earlier
  /// frames are likelier for it (TrackBindings), over this many frames of memory.
  bool use_track_ids = true;
  double track_memory_frames = 10.0;
  /// Tracking-aided only: an observation of a track waits for a later frame unless its
  /// likeliest landmark (the track's prior counted) beats every other one in its gate by this
  /// much in cost, 2 ln of the likelihood ratio (slam/association/ambiguity.hpp); 0 pairs
  /// every observation. Observations without a track are never held back.
  double ambiguity_margin = kDefaultAmbiguityMargin;
  /// A landmark's class is trusted for the class test once its votes lead by this many.
  int class_vote_margin = 2;
  /// Returning to old landmarks (drift variance above old_drift_variance_m2), the loose gate
  /// alone would pair a never-seen cone with its neighbour. Old pairings must instead agree on
  /// one drift offset: the offset most observations share within consensus_tolerance_m, backed
  /// by at least consensus_min_support observations; otherwise only the tight gate (no drift
  /// allowance) is used.
  double old_drift_variance_m2 = 0.01;
  double consensus_tolerance_m = 0.3;
  int consensus_min_support = 2;
};

/// A landmark as the association sees it: position and covariance in the map frame.
struct LandmarkCandidate {
  int id = 0;
  core::Vec2 position = core::Vec2::Zero();
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Identity();
  /// Class votes per core::ConeClass (kUnknown's entry unused).
  std::array<int, 5> class_votes{};
  /// The true cone it was made from (ideal association only), -1 otherwise.
  int label = -1;
  /// Extra isotropic position variance for drift since it was last seen (loop closure), m^2.
  double drift_variance_m2 = 0.0;
};

/// The landmark's class from its votes: the most voted, kUnknown with no votes.
core::ConeClass voted_class(const std::array<int, 5>& votes);

/// True when an observation of class `observed` may be of a landmark with these votes: unknown
/// matches anything, and a class that leads by the margin must agree.
bool class_compatible(core::ConeClass observed, const std::array<int, 5>& votes, int margin);

/// The predicted observation of a landmark from a pose (vehicle frame), with the Jacobians by
/// the pose (2x3) and by the landmark (2x2) when asked for.
core::Vec2 predict_observation(const core::Pose2& pose, const core::Vec2& landmark,
                               Eigen::Matrix<double, 2, 3>* h_pose = nullptr,
                               Eigen::Matrix2d* h_landmark = nullptr);

/// Squared Mahalanobis distance of an observation to a landmark with the innovation covariance
/// S = H_l P_l H_l^T + H_p P_p H_p^T + R (pose covariance optional, may be null).
double mahalanobis2(const core::Pose2& pose, const Eigen::Matrix3d* pose_covariance,
                    const LandmarkCandidate& landmark, const core::ConeObservation& observation);

/// Associates every observation of a batch with at most one candidate and every candidate with
/// at most one observation: greedy by likelihood (smallest Mahalanobis plus log-determinant,
/// less the track's prior when `tracks` is given and config.use_track_ids), old landmarks only
/// along the consensus drift offset. Unmatched observations are new when far from every
/// candidate, else rejected; when `allow_new` is false they are all rejected. `evidence`, when
/// given, gets the landmark id each observation pairs with without the tracks (-1: none).
std::vector<Association> associate(const AssociationConfig& config, const core::Pose2& pose,
                                   const Eigen::Matrix3d* pose_covariance,
                                   const std::vector<LandmarkCandidate>& candidates,
                                   const core::ConeObservations& observations, bool allow_new,
                                   const TrackBindings* tracks = nullptr,
                                   std::vector<int>* evidence = nullptr);

/// The same with one of the injectable methods (slam/association/methods.hpp) on the
/// candidates' marginal covariances (drift allowance included): the pairings of two
/// observations are correlated through the shared pose covariance, and through the landmark's
/// covariance when they pair with the same landmark. Unmatched observations are new or rejected
/// as in associate().
std::vector<Association> associate_with_method(
    const AssociationParams& params, const AssociationConfig& config, const core::Pose2& pose,
    const Eigen::Matrix3d* pose_covariance, const std::vector<LandmarkCandidate>& candidates,
    const core::ConeObservations& observations, bool allow_new,
    const std::vector<int>* labels = nullptr, const TrackBindings* tracks = nullptr,
    std::vector<int>* evidence = nullptr);

}  // namespace conesim::slam
