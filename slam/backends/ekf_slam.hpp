#pragma once
// EKF SLAM after the Monash Motorsport thesis (docs/architecture.md, "EKF SLAM"): one Gaussian
// over the pose and every landmark; a block-form prediction that touches only the pose rows and
// the pose-landmark cross terms; a batched update of all matched cones of a frame with an LDLT
// solve of the innovation covariance and the Joseph form of the covariance update; a preliminary
// landmark list; a controlled loop closure on the start's big orange cones; and localisation on
// the finished map.

#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "slam/association/methods.hpp"
#include "slam/backend.hpp"

namespace conesim::slam {

/// EKF SLAM parameters.
struct EkfSlamConfig {
  AssociationParams association;
  /// A cone enters the filter after this many sightings in the preliminary list, and the list
  /// forgets a candidate not confirmed within this distance driven since its first sighting.
  int confirm_sightings = 3;
  double preliminary_max_travel_m = 15.0;
  /// Monash's preliminary landmark list (the ablation switches it off): false puts every new
  /// cone into the filter at its first sighting, clutter included.
  bool preliminary_list = true;
  /// Preliminary sightings are merged within this distance (map frame), m.
  double preliminary_radius_m = 1.0;
  /// An unmatched observation within this distance of a landmark in the map frame, m, and
  /// within this squared Mahalanobis distance of it, starts nothing: a duplicate or clutter.
  double new_landmark_min_distance_m = 1.0;
  double new_landmark_chi2 = 40.0;
  /// Before the loop closes, a landmark not seen for this distance driven takes no part in the
  /// association (a drifted pose would pair it with the wrong cone), m.
  double unseen_exclusion_m = 25.0;
  /// The loop may close once the car has driven this far and a big orange cone is paired with
  /// one of the big orange landmarks mapped within start_radius_m of the start pose.
  double loop_min_travel_m = 60.0;
  double start_radius_m = 12.0;
  /// A layout without big orange cones at the start closes the loop when this many of the
  /// start's landmarks (mapped within start_radius_m in the first loop_min_travel_m / 2) pair
  /// with cones of one frame.
  int closure_min_pairs = 3;
  /// And only while the car heads within this angle of the start pose's heading, no farther
  /// than 2 x start_radius_m from it, rad.
  double closure_max_heading_rad = 1.0;
  /// Mapping goes on this far after the closure before the map is fixed (localise after).
  double closure_delay_m = 20.0;
  bool localise_after_loop_closure = true;
  /// The odometry's covariance is scaled by this (the MuJoCo car's slip is not in it).
  double odometry_noise_scale = 1.0;
  /// Added to the odometry's heading variance per metre driven, rad^2/m.
  double yaw_noise_per_m = 0.0;
  /// Observations farther than this from the sensor are not used, m (0: no limit).
  double max_range_m = 0.0;
  /// Where the sensor sits ahead of the rear axle (for max_range_m), m.
  double sensor_x_m = 0.0;
  /// A landmark's class is trusted in the association once its votes lead by this many.
  int class_vote_margin = 2;

  /// Empty when usable, otherwise "key: what was expected".
  std::string validate() const;
};

class EkfSlam : public Backend {
 public:
  explicit EkfSlam(const EkfSlamConfig& config = {});

  void reset(const core::Pose2& initial_pose, core::TimeUs stamp) override;
  void set_prior_map(const std::vector<core::MapCone>& map) override;
  void process(const SlamInput& input) override;
  core::Estimate estimate() const override;
  const std::vector<Association>& last_associations() const override { return associations_; }
  int loop_closures() const override { return loop_closures_; }
  std::string name() const override { return "ekf"; }

  /// The joint covariance (pose first, then two rows per landmark in the filter).
  const Eigen::MatrixXd& covariance() const { return p_; }
  /// Landmarks in the filter.
  int landmarks() const { return static_cast<int>(landmarks_.size()); }
  /// Microseconds the last association took.
  double last_association_us() const override { return association_us_; }
  /// `landmarks` (in the filter, ever: the joint state's size over two) and
  /// `preliminary_dropped` (candidates the preliminary list forgot before they were confirmed:
  /// the landmarks it kept out of the filter).
  std::vector<std::pair<std::string, double>> statistics() const override;

  /// The motion model x' = x (+) delta and its Jacobians by the pose (3x3) and the delta (3x3).
  static core::Pose2 motion(const core::Pose2& pose, const core::Pose2& delta,
                            Eigen::Matrix3d* f_pose = nullptr, Eigen::Matrix3d* f_delta = nullptr);
  /// A landmark from the pose and an observation z (vehicle frame): l = p + R(yaw) z, with the
  /// Jacobians by the pose (2x3) and by z (2x2).
  static core::Vec2 landmark_from(const core::Pose2& pose, const core::Vec2& z,
                                  Eigen::Matrix<double, 2, 3>* l_pose = nullptr,
                                  Eigen::Matrix2d* l_z = nullptr);

 private:
  struct Landmark {
    int id = 0;
    int index = 0;  // first row of the landmark in the state
    std::array<int, 5> class_votes{};
    int label = -1;  // the true cone it was made from (ideal association only)
    double first_travel_m = 0.0;
    double last_seen_travel_m = 0.0;
    bool at_start = false;
  };
  struct Preliminary {
    int id = 0;
    core::Vec2 position = core::Vec2::Zero();
    std::array<int, 5> class_votes{};
    int sightings = 0;
    double first_travel_m = 0.0;
    int label = -1;
  };

  void predict(const OdometryDelta& odometry);
  // pairs the observations with the landmarks that may take part; fills associations_
  std::vector<int> associate_frame(const core::ConeObservations& observations,
                                   std::vector<int>* candidate_landmarks);
  // the Kalman update with the paired observations (observation index, landmark index)
  void update(const core::ConeObservations& observations,
              const std::vector<std::pair<int, int>>& pairs, bool pose_only);
  void add_landmark(const core::ConeObservation& observation, int id, int label);
  void handle_unmatched(const core::ConeObservations& observations);
  // the true cone of observation i (ideal association), -1 otherwise
  int label_of(size_t i) const { return i < labels_.size() ? labels_[i] : -1; }
  void enter_localisation();
  core::Pose2 pose() const { return {x_(0), x_(1), x_(2)}; }
  // sightings that put a cone into the filter (1 without the preliminary list)
  int confirm_sightings() const { return config_.preliminary_list ? config_.confirm_sightings : 1; }
  core::Vec2 landmark_position(const Landmark& lm) const {
    return {x_(lm.index), x_(lm.index + 1)};
  }

  EkfSlamConfig config_;
  Eigen::VectorXd x_;
  Eigen::MatrixXd p_;
  std::vector<Landmark> landmarks_;
  std::vector<Preliminary> preliminary_;
  // landmarks fixed in localisation: their marginal covariance (the state holds the pose only)
  std::vector<Eigen::Matrix2d> fixed_covariance_;
  std::vector<core::Vec2> fixed_position_;
  std::vector<Association> associations_;
  // tracking-aided association: the perception tracks' evidence
  TrackBindings track_bindings_;
  std::vector<int> labels_;
  int next_id_ = 0;
  /// Candidates the preliminary list forgot unconfirmed: landmarks kept out of the filter.
  int preliminary_dropped_ = 0;
  core::SlamPhase phase_ = core::SlamPhase::kMapping;
  bool map_complete_ = false;
  bool loop_open_ = false;  // old landmarks may be associated again
  double closure_travel_m_ = -1.0;
  int loop_closures_ = 0;
  double travel_m_ = 0.0;
  /// The heading change summed since the start (not wrapped): one full turn a lap, rad.
  double turned_rad_ = 0.0;
  double speed_mps_ = 0.0;
  double yaw_rate_rps_ = 0.0;
  core::TimeUs stamp_ = 0;
  core::Pose2 start_;
  double association_us_ = 0.0;
};

}  // namespace conesim::slam
