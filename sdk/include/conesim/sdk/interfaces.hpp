#pragma once
// The three interfaces a team implements to put its own stack in the loop, and what each is
// told about the run. conesim's built-in front-ends, back-ends and reference driver are run
// through the same interfaces (docs/sdk.md).
//
// Calls on one object come from one thread at a time, in stamp order. Views a method returns
// (Span, const char*) stay valid until the next non-const call on the same object. A method
// may throw a std::exception: the run ends with a DNF whose reason names the plug-in and the
// message. A NaN or infinite number in an output does the same.

#include "conesim/sdk/types.hpp"

namespace conesim::sdk {

/// What a plug-in is told about the run when it is made.
struct RunInfo {
  Event event = Event::kTrackdrive;
  /// The scenario's seed (a plug-in that draws random numbers should seed from it, so that
  /// the same seed gives the same run).
  uint64_t seed = 1;
  /// The car's geometry and envelope.
  Vehicle vehicle;
  /// Laps of trackdrive.
  int32_t trackdrive_laps = 10;
  /// How often Driver::update runs (and SLAM's estimate is read), Hz.
  double driver_rate_hz = 20.0;
  /// The true start pose of the rear axle: the map frame is its parent frame (the track frame).
  Pose2 start_pose;
  /// The layout known before the run (skidpad), in the map frame; empty otherwise.
  Span<MapCone> prior_map;
  /// The scenario file's path, for messages.
  const char* scenario_file = "";
};

/// Raw sensor frames in, cone observations out.
class Perception {
 public:
  virtual ~Perception() = default;

  /// One LiDAR sweep (when the scenario gives the plug-in the LiDAR). `motion` is the
  /// autonomy's estimate of the car's motion now, for de-skewing. Returns the cones in the
  /// vehicle frame at sweep.end_us, or a frame with stamp -1 for none.
  virtual ConeFrame on_lidar(const LidarSweep& sweep, const Motion& motion) = 0;

  /// One stereo pair (when the scenario gives the plug-in the camera). Returns the cones in
  /// the vehicle frame at frame.stamp_us, or a frame with stamp -1 for none (the default).
  virtual ConeFrame on_stereo(const StereoFrame& frame, const Motion& motion) {
    (void)frame;
    (void)motion;
    return {};
  }
};

/// Odometry and cone observations in, a pose and map estimate out.
class Slam {
 public:
  virtual ~Slam() = default;

  /// Starts over at `start` (the map frame is its parent) at `stamp_us`; `prior_map` is the
  /// known layout for a localisation-only run (skidpad), empty otherwise.
  virtual void reset(const Pose2& start, TimeUs stamp_us, Span<MapCone> prior_map) = 0;

  /// One cone frame with the odometry since the previous one.
  virtual void process(const SlamInput& input) = 0;

  /// The estimate after the last process(): pose at the last frame's stamp, map, phase.
  /// conesim carries the pose forward to the driver's tick with its odometry.
  virtual Estimate estimate() const = 0;

  /// What the last process() did with each observation, index by index: the landmark id it
  /// was matched to, -1 for a new landmark, -2 for rejected. Scored against the truth (the
  /// association figures of metrics.json); empty when not reported (then not scored).
  virtual Span<int32_t> associations() const { return {}; }

  /// Loop closures detected so far.
  virtual int32_t loop_closures() const { return 0; }

  /// For each observation of the last process() that started a landmark (-1 in
  /// associations()), that landmark's id, index by index (any value elsewhere); empty when not
  /// reported. With it the scorer counts a landmark's first sighting towards the cone it stands
  /// for, as it does for conesim's own back-ends; without it a landmark's first match is scored
  /// against its later sightings only. Added in ABI 2.
  virtual Span<int32_t> new_landmark_ids() const { return {}; }
};

/// What a Driver reports about its mission (the progress line, DNF reasons).
struct DriverStatus {
  /// Laps the car has counted itself.
  int32_t laps_counted = 0;
  /// 1 once the mission is done and the car is held at a stop.
  int32_t finished = 0;
  /// Short state name ("explore", "fast", "stopped"); may be empty.
  const char* state = "";
  /// Why the driver cannot go on as planned; empty while all is well. Appended to a DNF reason.
  const char* problem = "";
};

/// Everything a Driver gets each time it runs.
struct DriverInput {
  /// Sim time of this tick.
  TimeUs now_us = 0;
  /// The state estimate: SLAM's carried forward to now, or the truth without SLAM.
  Estimate estimate;
  /// The latest perceived cones, in the vehicle frame now.
  ConeFrame observations;
};

/// An estimate and observations in, a steering and acceleration command out.
class Driver {
 public:
  virtual ~Driver() = default;

  /// Plans and returns the command to hold until the next call (driver_rate_hz).
  virtual Command update(const DriverInput& input) = 0;

  /// The mission's status after the last update.
  virtual DriverStatus status() const { return {}; }
};

}  // namespace conesim::sdk
