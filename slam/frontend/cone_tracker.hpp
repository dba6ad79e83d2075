#pragma once
// Frame-to-frame tracking of cone observations (FST thesis, section 3.6): each observation is
// predicted into the next frame with the odometry, matched by the Bhattacharyya distance
// between the two Gaussians, given a stable track id, and its class decided by the colour votes
// of the whole track. The tracking-aided association in SLAM uses the ids.

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
  struct Track;
  TrackerConfig config_;
  std::vector<Track> tracks_;
  int next_id_ = 0;
};

}  // namespace conesim::slam::frontend
