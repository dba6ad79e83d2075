#pragma once
// The one scorer of a SLAM back-end against ground truth (docs/metrics.md): the closed-loop
// runner and the offline test drives both feed it, so map error, trajectory error, association
// accuracy and loop closures have one definition. It never changes what it scores: it only
// reads the estimates and associations a back-end gives and the labels of the frames.

#include <array>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/autonomy_types.hpp"
#include "core/geometry.hpp"
#include "core/time.hpp"
#include "sim/perception_runner.hpp"
#include "slam/backend.hpp"
#include "tracks/track.hpp"

namespace conesim::sim {

/// Scores one back-end over a run.
class SlamScorer {
 public:
  /// A map cone farther than this from every true cone is spurious, m.
  static constexpr double kMatchCutoffM = 1.0;
  /// A loop closure is real when the car is this close to a place it passed at least
  /// kLoopTruthMinTravelM of driving earlier.
  static constexpr double kLoopTruthRadiusM = 15.0;
  static constexpr double kLoopTruthMinTravelM = 60.0;
  /// How often the map error over distance is taken, in distance driven.
  static constexpr double kMapSnapshotEveryM = 10.0;

  /// `track` must outlive the scorer; `view` is the perception's range and field of view
  /// (map_missed counts the true cones that were in it at some moment).
  SlamScorer(const tracks::Track& track, const PerceptionView& view);

  /// The back-end was given the layout as its map (skidpad): landmark k is track cone k, and no
  /// vote of the run outweighs that.
  void set_prior_map_identities();

  /// Marks the true cones within the perception's range and field of view of a true pose.
  void note_cones_in_view(const core::Pose2& true_pose);

  /// What one update of the back-end is scored on.
  struct Update {
    core::TimeUs stamp = 0;
    /// The true pose at the frame's capture.
    core::Pose2 true_pose;
    const core::ConeObservations* observations = nullptr;
    /// The true cone id of each observation (-1: clutter).
    const std::vector<int>* true_ids = nullptr;
    /// The estimate after the update and what the back-end did with each observation.
    const core::Estimate* estimate = nullptr;
    const std::vector<slam::Association>* associations = nullptr;
    /// Loop closures so far (the back-end's count after the update).
    int loop_closures = 0;
    /// Time the update took: wall and the thread's CPU time, ms.
    double wall_ms = 0.0;
    double cpu_ms = 0.0;
    /// Time the association took, microseconds (negative: the back-end does not say).
    double association_us = -1.0;
  };

  /// Scores one update. Associations: a match is right when the landmark's majority true cone
  /// so far (its votes before this frame) is the observation's true cone; a new landmark or a
  /// match adds a vote. Trajectory: the estimated pose against the true one, no alignment.
  void score(const Update& update);

  /// An estimated map cone and the true cone it stands for (-1: spurious).
  struct MapMatch {
    core::MapCone estimate;
    int true_cone_id = -1;
    double error_m = 0.0;
  };

  /// A map matched one to one to the true cones within kMatchCutoffM, no alignment: the most
  /// pairs, then the least total distance.
  std::vector<MapMatch> match_map(const std::vector<core::MapCone>& map) const;

  /// The figures of metrics.json's slam.<name> for the back-end's final estimate
  /// (docs/metrics.md lists them). A figure with nothing to measure is null, not 0.
  nlohmann::json metrics(const core::Estimate& final_estimate) const;

  /// The map error at one moment: RMSE overall and per class of the true cone (blue, yellow,
  /// orange_small, orange_big) over the true cones observed so far; NaN where none matched.
  struct MapErrorSnapshot {
    double distance_m = 0.0;
    int matched = 0;
    std::array<double, 5> rmse_m{};
  };
  const std::vector<MapErrorSnapshot>& map_error_over_distance() const {
    return map_error_over_distance_;
  }

  /// The scored updates' true and estimated poses, stamps and true distance driven.
  const std::vector<core::Pose2>& true_path() const { return true_path_; }
  const std::vector<core::Pose2>& estimated_path() const { return estimated_path_; }
  const std::vector<core::TimeUs>& stamps() const { return stamps_; }
  const std::vector<double>& true_odometer() const { return true_odometer_; }
  /// Each scored update's CPU time, ms, index by index with stamps().
  const std::vector<double>& update_cpu_ms() const { return update_cpu_ms_; }
  /// Where (true map frame) each wrong association's observation was.
  const std::vector<core::Vec2>& wrong_association_places() const {
    return wrong_association_places_;
  }
  int da_correct() const { return da_correct_; }
  int da_wrong() const { return da_wrong_; }
  /// Observations of a true cone that the association left unpaired and started no landmark
  /// with (a duplicate, a wrong colour, or held back as ambiguous).
  int da_rejected() const { return da_rejected_; }
  int false_loop_closures() const { return false_loop_closures_; }
  int loop_closures() const { return loop_closures_; }

 private:
  void snapshot_map_error(double distance_m, const core::Estimate& estimate);
  const tracks::Cone& true_cone(int id) const { return track_.cones[cone_index_[id]]; }

  const tracks::Track& track_;
  PerceptionView view_;
  std::vector<int> cone_index_;
  std::vector<char> cone_observed_;
  std::vector<char> cone_in_view_;
  // true cone ids seen by each landmark (by landmark id), for its majority identity
  std::map<int, std::map<int, int>> landmark_votes_;
  std::vector<double> update_ms_;
  std::vector<double> update_cpu_ms_;
  std::vector<double> association_us_;
  std::vector<double> position_error2_;
  std::vector<double> yaw_error2_;
  std::vector<core::Pose2> true_path_;
  std::vector<core::Pose2> estimated_path_;
  std::vector<core::TimeUs> stamps_;
  std::vector<double> true_odometer_;
  std::vector<core::Vec2> wrong_association_places_;
  int da_correct_ = 0;
  int da_wrong_ = 0;
  int da_rejected_ = 0;
  int loop_closures_ = 0;
  int false_loop_closures_ = 0;
  nlohmann::json loop_closure_events_ = nlohmann::json::array();
  double next_map_snapshot_m_ = kMapSnapshotEveryM;
  std::vector<MapErrorSnapshot> map_error_over_distance_;
};

/// The q-quantile (0..1) of a sample by the nearest rank, 0 for an empty one.
double nearest_rank_percentile(std::vector<double> v, double q);

}  // namespace conesim::sim
