#pragma once
// Frame-to-frame tracking of cone observations (FST thesis, section 3.6): each observation is
// predicted into the next frame with the odometry, matched by the Bhattacharyya distance
// between the two Gaussians, given a stable track id, and its class decided by the colour votes
// of the whole track. The tracking-aided association in SLAM uses the ids.

#include <array>
#include <string>
#include <vector>

#include "core/autonomy_types.hpp"
#include "core/geometry.hpp"

namespace conesim::slam::frontend {

/// Parameters of the tracker.
struct TrackerConfig {
  /// Largest Bhattacharyya distance of a match.
  double max_bhattacharyya = 3.0;
  /// A track not matched for this many frames is dropped.
  int max_missed_frames = 3;
  /// Process noise added to a track's covariance per frame (odometry error), m^2.
  double motion_noise_m2 = 0.01;

  /// Empty when valid, else a message naming the key and what was expected.
  std::string validate() const;
};

/// Bhattacharyya distance between two Gaussians in the plane:
/// D = 1/8 d' S^-1 d + 1/2 ln(det S / sqrt(det A det B)), with d the difference of the means
/// and S = (A + B) / 2. Zero for identical Gaussians; the second term grows when the shapes
/// differ even at the same mean.
double bhattacharyya_distance(const core::Vec2& mean_a, const Eigen::Matrix2d& cov_a,
                              const core::Vec2& mean_b, const Eigen::Matrix2d& cov_b);

/// Where the vehicle frame dt_s seconds later lies in the vehicle frame now, moving at a
/// constant speed and yaw rate (the chord of the arc): the motion a tracker predicts by.
core::Pose2 motion_over(double speed_mps, double yaw_rate_rps, double dt_s);

/// The tracker's state: live tracks with their colour votes. Deterministic; not thread-safe.
class ConeTracker {
 public:
  /// Throws std::invalid_argument when config.validate() fails.
  explicit ConeTracker(const TrackerConfig& config);

  /// Tracks one frame. motion is the vehicle frame of this frame in the previous frame's
  /// vehicle frame (from the odometry). Returns the observations with track_id set and the
  /// class replaced by the track's colour vote (kUnknown until a colour has been seen).
  core::ConeObservations update(const core::ConeObservations& frame, const core::Pose2& motion);

  /// Tracks alive now.
  int live_tracks() const;

 private:
  // One tracked cone, in the vehicle frame of the last frame (defined here, not in the .cpp:
  // std::vector needs the complete type wherever the tracker is destroyed).
  struct Track {
    int id = 0;
    core::Vec2 position = core::Vec2::Zero();
    Eigen::Matrix2d covariance = Eigen::Matrix2d::Identity();
    // colour votes by class (blue, yellow, orange small, orange big); kUnknown is not counted
    std::array<int, 4> votes{};
    // the class decided so far (a tie keeps it)
    core::ConeClass cls = core::ConeClass::kUnknown;
    // frames in a row without a match
    int missed = 0;
  };
  TrackerConfig config_;
  std::vector<Track> tracks_;
  int next_id_ = 0;
};

}  // namespace conesim::slam::frontend
