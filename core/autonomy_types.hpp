#pragma once
// What the system under test (perception, SLAM, driver) exchanges with the harness. Nothing
// here carries ground truth: labels travel separately (core/labels.hpp).

#include <Eigen/Core>
#include <vector>

#include "core/cone.hpp"
#include "core/geometry.hpp"
#include "core/time.hpp"

namespace conesim::core {

/// One cone seen by perception, in the vehicle frame at the observation's stamp.
struct ConeObservation {
  /// Position in the vehicle frame (x forward, y left), metres.
  Vec2 position = Vec2::Zero();
  /// Class as perceived (may be kUnknown or wrong).
  ConeClass cls = ConeClass::kUnknown;
  /// Position covariance in the vehicle frame, m^2.
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Identity() * 0.01;
  /// Perception's frame-to-frame track id, -1 when not tracked.
  int track_id = -1;
};

/// All cones perceived from one sensor frame.
struct ConeObservations {
  TimeUs stamp = 0;
  std::vector<ConeObservation> cones;
};

/// A cone of an estimated (or given) map, in the map frame.
struct MapCone {
  int id = 0;
  ConeClass cls = ConeClass::kUnknown;
  Vec2 position = Vec2::Zero();
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Identity() * 0.01;
};

/// Whether SLAM is still building the map or localising on a fixed one.
enum class SlamPhase { kMapping, kLocalisation };

/// The state estimate the driver plans from.
struct Estimate {
  TimeUs stamp = 0;
  /// Pose of the vehicle reference point (rear axle centre) in the map frame.
  Pose2 pose;
  /// Forward speed, m/s.
  double speed_mps = 0.0;
  /// Yaw rate, rad/s.
  double yaw_rate_rps = 0.0;
  /// The map so far (or the whole known map in localisation).
  std::vector<MapCone> map;
  SlamPhase phase = SlamPhase::kMapping;
  /// True once the map is known to be complete (a loop has closed).
  bool map_complete = false;
};

/// What the driver asks of the car: a single-track steering angle and a longitudinal
/// acceleration, which the vehicle turns into wheel angles and torques within its limits.
struct VehicleCommand {
  /// Equivalent single-track (bicycle) steering angle, radians, positive left.
  double steer_rad = 0.0;
  /// Requested longitudinal acceleration, m/s^2 (negative brakes).
  double accel_mps2 = 0.0;
  /// True once the driver has finished and wants the car held still.
  bool hold_stopped = false;
};

}  // namespace conesim::core
