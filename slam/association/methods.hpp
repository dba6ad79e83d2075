#pragma once
// The data association methods a back-end can be given (docs/architecture.md, "Association"):
// each pairs the observations of one frame with the back-end's landmarks, one landmark per
// observation at most. They work on a joint Gaussian of the pose and the candidate landmarks,
// so a filter gives them its covariance blocks and a graph its marginals.

#include <Eigen/Core>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/autonomy_types.hpp"
#include "core/cone.hpp"
#include "core/geometry.hpp"
#include "slam/association/ambiguity.hpp"
#include "slam/association/track_bindings.hpp"

namespace conesim::slam {

enum class AssociationMethod {
  /// Euclidean nearest neighbour in the map frame within a fixed radius (Monash, RaceUp).
  kNearestNeighbour,
  /// Maximum likelihood with the individual-compatibility chi-square gate, greedy by
  /// likelihood with mutual exclusion.
  kMaximumLikelihood,
  /// Sequential compatibility nearest neighbour: observation by observation, the likeliest
  /// landmark that keeps the pairings so far jointly compatible.
  kScnn,
  /// Joint compatibility branch and bound over the joint innovation covariance.
  kJcbb,
  /// Maximum likelihood with the perception's tracks as a prior (the FST thesis's idea): an
  /// observation's track makes the landmarks the track's earlier frames pointed at likelier
  /// (TrackBindings), within the same individual-compatibility gate.
  kTrackingAided,
  /// From the ground-truth labels: an observation pairs with the landmark first made from the
  /// same true cone. For ablation only (what the others lose to wrong pairings); flagged in
  /// every output that uses it.
  kIdeal,
  /// No association (an ablation, RaceUp's first real-world map): every observation starts a
  /// landmark of its own, so the map holds every detection where the pose put it.
  kNone,
};

/// The method's name as scenarios and metrics spell it: nn, ml, scnn, jcbb, tracking, ideal,
/// none.
std::string_view to_string(AssociationMethod method);
/// The method of a name, nullopt for an unknown one.
std::optional<AssociationMethod> association_from_string(std::string_view name);
/// "nn, ml, scnn, jcbb, tracking, ideal, none" for error messages.
std::string association_names();

/// Parameters shared by the methods.
struct AssociationParams {
  AssociationMethod method = AssociationMethod::kMaximumLikelihood;
  /// Individual compatibility gate on the squared Mahalanobis distance (2 dof, 99 %).
  double gate_chi2 = 9.21;
  /// Joint compatibility: the pairings' joint squared Mahalanobis distance must stay below the
  /// chi-square quantile of this probability for 2k degrees of freedom.
  double joint_probability = 0.99;
  /// Nearest neighbour's radius, m.
  double nn_radius_m = 1.0;
  /// Tracking-aided: frames over which a track's evidence fades (TrackBindings).
  double track_memory_frames = 10.0;
  /// Tracking-aided: the margin an observation of a track needs to be paired in this frame
  /// (slam/association/ambiguity.hpp); 0 pairs every observation.
  double ambiguity_margin = kDefaultAmbiguityMargin;
  /// JCBB stops after this many nodes of the interpretation tree (the best found so far wins).
  int jcbb_max_nodes = 20000;
};

/// The joint Gaussian the association works on: the predicted observation of each candidate
/// landmark and the Jacobians and covariances that give the innovation covariance of any set
/// of pairings, cross terms included.
class AssociationProblem {
 public:
  virtual ~AssociationProblem() = default;
  /// Number of observations and candidate landmarks.
  virtual int observations() const = 0;
  virtual int candidates() const = 0;
  /// The innovation z_i - h(x, l_j).
  virtual Eigen::Vector2d innovation(int observation, int candidate) const = 0;
  /// The covariance of the innovations of pairings a and b (2x2; a == b gives S_a, with R).
  virtual Eigen::Matrix2d innovation_covariance(int obs_a, int cand_a, int obs_b,
                                                int cand_b) const = 0;
  /// The observation's and candidate's places in the map frame (nearest neighbour).
  virtual core::Vec2 observation_in_map(int observation) const = 0;
  virtual core::Vec2 candidate_position(int candidate) const = 0;
  /// False when the pairing is ruled out (class, already excluded).
  virtual bool allowed(int observation, int candidate) const = 0;
  /// Perception's track id of an observation (-1: none) and a candidate's landmark id.
  virtual int observation_track(int observation) const = 0;
  virtual int candidate_landmark(int candidate) const = 0;
  /// The true cone of an observation and of a candidate landmark (ideal association only;
  /// -1: unknown or clutter).
  virtual int observation_label(int) const { return -1; }
  virtual int candidate_label(int) const { return -1; }
};

/// The pairing of each observation: a candidate index, or -1. Tracking-aided association takes
/// the tracks' memory (none: plain maximum likelihood) and writes the frame's own evidence for
/// it to `evidence` (the maximum-likelihood pairing without the tracks, a candidate index or -1
/// per observation) when given; the back-end records it once it knows its new landmarks.
std::vector<int> associate(const AssociationParams& params, const AssociationProblem& problem,
                           const TrackBindings* tracks = nullptr,
                           std::vector<int>* evidence = nullptr);

/// The chi-square quantile of probability p for k degrees of freedom (Wilson-Hilferty, within
/// 1 % of the exact value for k >= 2 at p = 0.99).
double chi2_quantile(double p, int dof);

/// The joint squared Mahalanobis distance of a set of pairings (observation, candidate).
double joint_mahalanobis2(const AssociationProblem& problem,
                          const std::vector<std::pair<int, int>>& pairings);

}  // namespace conesim::slam
