#pragma once
// GraphSLAM on Ceres after the FST Lisboa and RaceUp theses: a pose node per observation batch,
// odometry and ICR edges between consecutive poses, landmark nodes with observation edges, the
// gauge fixed at the start pose; landmarks refined by a per-landmark EKF between optimisations;
// a sliding window optimised every batch and the whole graph once the loop closes, after which
// the map is fixed and the backend localises only.

#include <array>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "slam/association/ml_association.hpp"
#include "slam/association/track_bindings.hpp"
#include "slam/backend.hpp"
#include "slam/loop_closure.hpp"

namespace ceres {
class CostFunction;
class LossFunction;
class Problem;
}  // namespace ceres

namespace conesim::slam {

/// GraphSLAM parameters.
struct GraphSlamConfig {
  AssociationConfig association;
  /// One of the injectable methods (nn, scnn, jcbb) instead of the built-in ML+IC with the
  /// drift consensus (tracking-aided when association.use_track_ids and the observations carry
  /// track ids); unset: the built-in.
  std::optional<AssociationParams> method;
  LoopClosureConfig loop_closure;

  /// The cone sensor's field of view (for the landmark statistics): its mount ahead of the rear
  /// axle, range limits and opening angle. A landmark counts as missed only when predicted at
  /// least fov_margin_m inside this view.
  double sensor_x_m = 2.1;
  double min_range_m = 1.0;
  double max_range_m = 15.0;
  double fov_deg = 180.0;
  double fov_margin_m = 2.0;

  /// A tentative landmark joins the map after this many sightings, and is dropped when it has
  /// not by this distance driven since its first sighting, m.
  int confirm_sightings = 3;
  double tentative_max_travel_m = 20.0;
  /// Poses optimised every batch (older ones are held fixed).
  int window_poses = 8;
  /// Solver iterations for the window, the global optimisation and localisation.
  int window_iterations = 4;
  int global_iterations = 30;
  int localisation_iterations = 4;
  /// Poses optimised together against the fixed map in localisation (the oldest one before
  /// them held fixed): the heading the map gives is averaged over them instead of resting on
  /// the last pose alone, whose heading the gyro then carries with its bias.
  int localisation_window_poses = 10;
  /// Sigma of the gyro bias left after the standstill calibration, rad/s: the loop closure
  /// estimates that bias with the whole lap (the heading must close), and from then on the
  /// odometry is corrected by it. 0 (the default) holds the bias at zero: with 5e-4 the bias
  /// came out within about 2e-4 rad/s of the truth, and that error made the fixed map worse on
  /// about half of the 20 generated circuits (seed 1: map RMSE 0.045 -> 0.158 m).
  double gyro_bias_sigma_rps = 0.0;
  /// Sigma of the ICR edge's lateral residual, m (0 disables the edge).
  double icr_sigma_m = 0.05;
  /// Ablation (RaceUp's simulator set-up): no sliding-window optimisation while mapping, the
  /// poses follow the odometry and only the loop closure optimises, once, the whole graph.
  bool global_only = false;
  /// Ablation (RaceUp, Fig. 7.12): false keeps the observation edges out of the optimisation,
  /// an odometry-only graph, except for the loop closure: the edges from the start's poses and
  /// from the closing poses to the landmarks both saw tie the lap's end to its start. After the
  /// closure every landmark is placed again from its observations on the optimised poses.
  bool landmark_edges = true;
  /// Huber threshold of observation edges, in whitened units (sigmas).
  double observation_huber = 3.0;
  /// Variance growth of a landmark's position relative to the car per metre driven since it was
  /// last seen (the drift the association allows for on returning), m^2 per m, and its cap.
  double drift_variance_m2_per_m = 0.002;
  double max_drift_variance_m2 = 1.0;
  /// Map the first loop and then localise on it (trackdrive); false keeps mapping.
  bool localise_after_loop_closure = true;
  /// Keep the estimate of every localised pose for trajectory() (32 bytes a batch). Off, the
  /// localised poses older than the window are forgotten: memory and update time stay flat
  /// however many laps the car drives on the fixed map.
  bool keep_trajectory = false;

  /// Empty when usable, otherwise "graph_slam.key: what was expected".
  std::string validate() const;
};

/// The GraphSLAM backend.
class GraphSlam : public Backend {
 public:
  explicit GraphSlam(const GraphSlamConfig& config = {});
  ~GraphSlam() override;

  void reset(const core::Pose2& initial_pose, core::TimeUs stamp) override;
  void set_prior_map(const std::vector<core::MapCone>& map) override;
  void process(const SlamInput& input) override;
  core::Estimate estimate() const override;
  const std::vector<Association>& last_associations() const override { return associations_; }
  int loop_closures() const override { return loop_closures_; }
  std::string name() const override { return "graph"; }
  double last_association_us() const override { return association_us_; }

  /// The estimated trajectory, one pose per processed batch (the poses of the pose nodes,
  /// smoothed by the optimisations): the whole of it with keep_trajectory, otherwise the
  /// mapping's poses and the last localisation window's.
  std::vector<core::Pose2> trajectory() const;
  /// Stamps of the trajectory's poses.
  std::vector<core::TimeUs> trajectory_stamps() const;
  /// The gyro bias estimated at the loop closure (zero before), rad/s.
  double gyro_bias_rps() const { return gyro_bias_rps_[0]; }
  /// Landmarks ever created, tentative and removed ones included (ids are 0..count-1).
  int landmark_count() const { return static_cast<int>(landmarks_.size()); }

 private:
  // an observation of the fixed map in localisation
  struct LocalisationTerm {
    std::unique_ptr<ceres::CostFunction> cost;
    int landmark = 0;
  };

  // a pose node with the edges that lead into it from the previous pose
  struct PoseNode {
    core::TimeUs stamp = 0;
    std::array<double, 3> x{};
    double travel_m = 0.0;
    std::unique_ptr<ceres::CostFunction> odometry;
    std::unique_ptr<ceres::CostFunction> icr;
    /// Observation edges from this pose.
    std::vector<int> edges;
    /// Observations of the fixed map from this pose (localisation), kept while in the window.
    std::vector<LocalisationTerm> localisation;

    core::Pose2 pose() const { return {x[0], x[1], x[2]}; }
  };

  // a landmark node with its EKF covariance, class votes, statistics and loop state
  struct Landmark {
    int id = 0;
    std::array<double, 2> x{};
    Eigen::Matrix2d covariance = Eigen::Matrix2d::Identity();
    std::array<int, 5> class_votes{};
    /// The true cone it was made from (ideal association only).
    int label = -1;
    int sightings = 0;
    int misses = 0;
    bool confirmed = false;
    bool removed = false;
    bool fixed = false;
    LoopState loop_state = LoopState::kInView;
    double first_travel_m = 0.0;
    double first_heading_rad = 0.0;
    double last_seen_travel_m = 0.0;
    /// Observation edges to this landmark.
    std::vector<int> edges;
    /// The edges from poses that have left the window, folded into one prior (those poses
    /// stay fixed until the loop closes): their summed information and weighted mean.
    Eigen::Matrix2d folded_information = Eigen::Matrix2d::Zero();
    Eigen::Vector2d folded_weighted_mean = Eigen::Vector2d::Zero();
    std::unique_ptr<ceres::CostFunction> folded_prior;

    core::Vec2 position() const { return {x[0], x[1]}; }
  };

  // a landmark seen from a pose
  struct ObservationEdge {
    int pose = 0;
    int landmark = 0;
    std::unique_ptr<ceres::CostFunction> cost;
    /// The observation in the vehicle frame and its whitening factor (for folding).
    core::Vec2 measured = core::Vec2::Zero();
    Eigen::Matrix2d sqrt_information = Eigen::Matrix2d::Identity();
  };

  // the recipe's steps
  void predict(const OdometryDelta& odometry);
  void associate_batch(const core::ConeObservations& observations);
  void update(const core::ConeObservations& observations);
  void record_tracks(const core::ConeObservations& observations);
  void optimise_window();
  void localise();
  LoopClosureStats update_landmark_statistics();
  void close_loop();
  std::vector<LandmarkCandidate> candidates(double farthest_observation_m) const;

  // helpers
  bool in_field_of_view(const core::Pose2& pose, const core::Vec2& landmark) const;
  void add_observation_edge(int pose, int landmark, const core::ConeObservation& observation);
  void add_motion_edges(ceres::Problem& problem, int pose);
  void remove_landmark(Landmark& landmark);
  // folds the observation edges of the poses before `first` (fixed from now on) into their
  // landmarks' priors
  void fold_edges_before(int first);
  // forgets the folded priors (the poses they were folded at have moved)
  void unfold_all();
  // the observation edges the loop closure optimises: all of them, or without landmark edges
  // those that tie the lap's end to its start
  std::vector<int> closure_edges() const;
  // places every landmark that is not fixed at the mean of its observations from the poses
  void place_landmarks_from_poses();
  // trajectory() with its stamps
  std::vector<std::pair<core::TimeUs, core::Pose2>> stamped_trajectory() const;
  // forgets the localised poses before `keep` (nothing uses them again), keeping their
  // estimates with keep_trajectory
  void forget_localised_poses_before(int keep);
  // true when no association runs (every observation a landmark of its own)
  bool no_association() const {
    return config_.method && config_.method->method == AssociationMethod::kNone;
  }

  GraphSlamConfig config_;
  std::deque<PoseNode> poses_;
  std::deque<Landmark> landmarks_;
  std::deque<ObservationEdge> edges_;
  std::unique_ptr<ceres::LossFunction> huber_;
  std::unique_ptr<ceres::CostFunction> gyro_bias_prior_;
  /// The gyro bias the odometry's heading changes are corrected by, rad/s (a parameter block).
  std::array<double, 1> gyro_bias_rps_{};
  /// The first pose localised on the fixed map (poses before it belong to the mapping).
  int first_localised_pose_ = 1;
  /// The localised poses forgotten so far, stamped (kept with keep_trajectory only): they came
  /// between poses_[first_localised_pose_ - 1] and poses_[first_localised_pose_].
  std::vector<std::pair<core::TimeUs, core::Pose2>> forgotten_poses_;
  std::vector<Association> associations_;
  /// Tracking-aided association: the perception tracks' evidence, and the batch's own (the
  /// landmark id each observation paired with without the tracks, -1: none).
  TrackBindings track_bindings_;
  std::vector<int> evidence_;
  /// The labels of the batch being processed (ideal association only, else empty).
  std::vector<int> labels_;
  core::SlamPhase phase_ = core::SlamPhase::kMapping;
  bool map_complete_ = false;
  int loop_closures_ = 0;
  // the loop was seen to close and the global optimisation runs at this distance driven
  std::optional<double> closure_due_travel_m_;
  /// The distance driven when the loop was seen to close (the closing poses start there).
  double closure_seen_travel_m_ = 0.0;
  /// Covariance of the newest pose, for the association gate: grown by the odometry, shrunk by
  /// the matched observations.
  Eigen::Matrix3d pose_covariance_ = Eigen::Matrix3d::Zero();
  /// Poses [0, folded_poses_) have their observation edges folded into landmark priors.
  int folded_poses_ = 0;
  double travel_m_ = 0.0;
  /// The heading change summed since the start (not wrapped): one full turn a lap, rad.
  double turned_rad_ = 0.0;
  double association_us_ = 0.0;
  double speed_mps_ = 0.0;
  double yaw_rate_rps_ = 0.0;
};

}  // namespace conesim::slam
