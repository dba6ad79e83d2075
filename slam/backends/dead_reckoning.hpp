#pragma once
// The dead-reckoning "back-end" (lane `odometry`): the baseline every SLAM figure is read
// against. The pose is the odometry composed from the start pose and never corrected; each
// observation is placed on that pose, and a simple association (Euclidean nearest neighbour by
// default) gathers the placements of one cone into a landmark, so that its map can be scored
// like the others'. No loop closure, no localisation.

#include <array>
#include <string>
#include <vector>

#include "slam/association/methods.hpp"
#include "slam/association/ml_association.hpp"
#include "slam/backend.hpp"

namespace conesim::slam {

/// Dead-reckoning parameters.
struct DeadReckoningConfig {
  /// The association (nn by default; ml, scnn, jcbb on the odometry's growing pose covariance,
  /// ideal on the labels, none for every observation a landmark).
  AssociationParams association{.method = AssociationMethod::kNearestNeighbour};
  /// A landmark joins the map after this many sightings (1 with no association), and a
  /// tentative one is forgotten when not confirmed by this distance driven since it was first
  /// seen, m (clutter).
  int confirm_sightings = 3;
  double tentative_max_travel_m = 20.0;
  /// Landmarks farther than this from the car take no part in the association, m.
  double reach_m = 25.0;

  /// Empty when usable, otherwise "key: what was expected".
  std::string validate() const;
};

/// Odometry only: the baseline back-end.
class DeadReckoning : public Backend {
 public:
  explicit DeadReckoning(const DeadReckoningConfig& config = {});

  void reset(const core::Pose2& initial_pose, core::TimeUs stamp) override;
  void set_prior_map(const std::vector<core::MapCone>& map) override;
  void process(const SlamInput& input) override;
  core::Estimate estimate() const override;
  const std::vector<Association>& last_associations() const override { return associations_; }
  int loop_closures() const override { return 0; }
  std::string name() const override { return "odometry"; }
  double last_association_us() const override { return association_us_; }
  /// `landmarks` (in the map: confirmed and not forgotten) and `landmarks_made` (every one
  /// started, tentative and forgotten ones included).
  std::vector<std::pair<std::string, double>> statistics() const override;

 private:
  // a cone's placements: their mean and covariance, class votes, the true cone (ideal only)
  struct Landmark {
    int id = 0;
    core::Vec2 sum = core::Vec2::Zero();
    Eigen::Matrix2d covariance_sum = Eigen::Matrix2d::Zero();
    std::array<int, 5> class_votes{};
    int label = -1;
    int sightings = 0;
    double first_travel_m = 0.0;
    bool forgotten = false;
    bool fixed = false;

    core::Vec2 position() const { return sum / static_cast<double>(sightings); }
    bool confirmed(int needed) const { return fixed || sightings >= needed; }
  };

  // the recipe's steps
  void predict(const OdometryDelta& odometry);
  void associate(const SlamInput& input);
  void update(const core::ConeObservations& observations);
  // sightings that confirm a landmark (1 without association)
  int confirm_sightings() const {
    return config_.association.method == AssociationMethod::kNone ? 1 : config_.confirm_sightings;
  }

  DeadReckoningConfig config_;
  core::Pose2 pose_;
  Eigen::Matrix3d pose_covariance_ = Eigen::Matrix3d::Zero();
  std::vector<Landmark> landmarks_;
  std::vector<Association> associations_;
  core::TimeUs stamp_ = 0;
  bool localising_ = false;
  double travel_m_ = 0.0;
  double speed_mps_ = 0.0;
  double yaw_rate_rps_ = 0.0;
  double association_us_ = 0.0;
};

}  // namespace conesim::slam
