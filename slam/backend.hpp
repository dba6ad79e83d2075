#pragma once
// The one interface every SLAM backend implements (docs/architecture.md): odometry and cone
// observations in, an estimate and the associations it made out. Several backends can run side
// by side on the same input stream; one of them drives the car, the others run in shadow.

#include <Eigen/Core>
#include <string>
#include <utility>
#include <vector>

#include "core/autonomy_types.hpp"
#include "core/geometry.hpp"
#include "core/time.hpp"

namespace conesim::slam {

/// The motion of the vehicle between two observation batches, in the frame of the first one.
struct OdometryDelta {
  /// Stamps of the start and the end of the interval.
  core::TimeUs from = 0;
  core::TimeUs to = 0;
  /// Pose at `to` expressed in the vehicle frame at `from`.
  core::Pose2 delta;
  /// Covariance of (x, y, yaw) of the delta, m^2 and rad^2.
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity() * 1e-4;
  /// Distance driven over the interval (arc length), metres.
  double distance_m = 0.0;
  /// Forward speed and yaw rate at `to`, for the estimate.
  double speed_mps = 0.0;
  double yaw_rate_rps = 0.0;
};

/// One step of the input stream: the motion since the previous batch and the cones seen at the
/// end of it (observations in the vehicle frame at odometry.to).
struct SlamInput {
  OdometryDelta odometry;
  core::ConeObservations observations;
  /// The true cone id of each observation (-1: clutter). Empty, except for a back-end given
  /// the ideal association (an ablation: the harness fills it for that lane only, and every
  /// output of that lane says so).
  std::vector<int> true_ids;
};

/// What a backend did with one observation of the last batch.
struct Association {
  enum class Kind {
    /// Matched to an existing landmark (tentative or confirmed).
    kMatched,
    /// Started a new (tentative) landmark.
    kNew,
    /// Rejected: failed the gate or class test near a landmark, or the map is fixed.
    kRejected,
  };
  /// Landmark id for kMatched and kNew, kNoLandmark for kRejected.
  int landmark_id = kNoLandmark;
  Kind kind = Kind::kRejected;

  /// The id of "no landmark".
  static constexpr int kNoLandmark = -2;
  /// The brief's integer code: the landmark id when matched, -1 when new, -2 when rejected.
  int code() const {
    return kind == Kind::kMatched ? landmark_id : kind == Kind::kNew ? -1 : kNoLandmark;
  }
};

/// A SLAM backend. Call `reset` once (and `set_prior_map` for localisation-only runs), then
/// `process` once per observation batch in stamp order; read `estimate` and `last_associations`
/// after each call.
class Backend {
 public:
  virtual ~Backend() = default;

  /// Starts over at the given pose: the map frame is the frame of the start pose's parent (the
  /// track frame when the harness passes the true start pose), and the gauge is fixed there.
  virtual void reset(const core::Pose2& initial_pose, core::TimeUs stamp) = 0;

  /// Gives a known map (skidpad layout): the backend localises on it from the start and adds no
  /// landmarks (phase kLocalisation, map_complete true).
  virtual void set_prior_map(const std::vector<core::MapCone>& map) = 0;

  /// Predicts with the odometry, associates the observations, updates and closes loops.
  virtual void process(const SlamInput& input) = 0;

  /// The current estimate: pose, confirmed map with classes and covariances, phase.
  virtual core::Estimate estimate() const = 0;

  /// One entry per observation of the last processed batch, index by index.
  virtual const std::vector<Association>& last_associations() const = 0;

  /// Number of loop closures detected so far.
  virtual int loop_closures() const = 0;

  /// A short name for metrics (`slam.<name>`).
  virtual std::string name() const = 0;

  /// Microseconds the association of the last batch took, negative when not measured.
  virtual double last_association_us() const { return -1.0; }

  /// Where the estimate comes from, for metrics.json (`estimate_source`): "state" for a
  /// back-end that keeps one estimate; a particle filter names the particle it reports.
  virtual std::string estimate_source() const { return "state"; }

  /// Back-end-specific counters for metrics.json (`backend_stats`), e.g. a particle filter's
  /// resamplings; empty by default.
  virtual std::vector<std::pair<std::string, double>> statistics() const { return {}; }
};

}  // namespace conesim::slam
