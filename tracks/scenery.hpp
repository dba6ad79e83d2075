#pragma once
// Scenery and clutter around a layout (issue 17): static objects beside the track that the
// sensors see and the physics does not (barriers, fences, tyre stacks, tents, people, spare
// cones standing or lying off the track), each made of a few boxes, cylinders and cone
// frustums. They are placed from the scenario seed on a stream of their own, never within
// `margin_m` of a lane, a cone or the driving line, so that a run without clutter draws exactly
// the numbers it drew before.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "core/clutter.hpp"
#include "tracks/ground.hpp"
#include "tracks/track.hpp"

namespace conesim::tracks {

/// One solid of a scenery object, in the object's frame (x along the object, z up, the ground
/// at z = 0).
struct ScenePrimitive {
  enum class Shape {
    kBox,       // half extents in `size`
    kCylinder,  // size: radius, (unused), half length along the local z axis
    kFrustum,   // size: bottom radius, top radius, half length along the local z axis
  };
  Shape shape = Shape::kBox;
  /// Centre in the object's frame, metres.
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  /// The solid's axes in the object's frame (columns).
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d size = Eigen::Vector3d::Zero();
  /// Colour in the camera, 0..1.
  std::array<float, 4> rgba = {0.5f, 0.5f, 0.5f, 1.f};
  /// Diffuse reflectivity for the LiDAR, 0..1.
  double reflectivity = 0.3;
};

/// A static object beside the track.
struct SceneryObject {
  core::ClutterClass cls = core::ClutterClass::kBarrier;
  /// Where it stands: the object frame's origin on the ground and its heading.
  Pose2 pose;
  std::vector<ScenePrimitive> parts;
  /// Every point of the object lies within this horizontal distance of the pose's position.
  double radius_m = 0.0;
  /// ... and below this height.
  double height_m = 0.0;
  /// The ground's slope under the object, applied after its heading (identity: level; set by
  /// lay_on_ground for what lies flat on the ground).
  Eigen::Matrix3d tilt = Eigen::Matrix3d::Identity();
};

/// Tilts what lies flat on the ground (the grass edge's strips) to the slope of the ground under
/// it, so that a strip on a grade or a crown stays a 6 cm step all along instead of standing
/// out of the slope at one end. Objects that stand (barriers, tents, people) stay level.
void lay_on_ground(std::vector<SceneryObject>& objects, const GroundModel& ground);

/// The scenario's `world.clutter` block.
struct ClutterConfig {
  /// Objects per 100 m of driving line (0: none, today's world).
  double objects_per_100m = 0.0;
  /// No part of an object comes nearer than this to a lane's polyline, a cone or the driving
  /// line, metres.
  double margin_m = 3.0;
  /// Objects stand at most this much farther out than the margin, metres.
  double spread_m = 12.0;
  /// Added to the scenario seed: another arrangement on the same layout and run.
  uint64_t seed_offset = 0;
  /// Lays a grass edge: 4 m strips of grass 6 cm above the asphalt along both sides of the
  /// driving line, each as near as the margin lets it (independent of the density).
  bool grass_edge = false;

  /// Empty when valid, else "key: expected ...".
  std::string validate() const;
};

/// The object of a class at a pose; `variant` picks among a class's looks (a spare cone's
/// colour), any value is valid.
SceneryObject make_scenery_object(core::ClutterClass cls, const Pose2& pose, int variant = 0);

/// The objects for a layout: round(objects_per_100m x length / 100) of them, fewer where no
/// clear place is found, then the grass edge's strips if asked. Deterministic for (track,
/// config, seed); empty for a density of 0 without the grass edge.
/// Throws std::invalid_argument for a config that fails validate().
std::vector<SceneryObject> place_scenery(const Track& track, const ClutterConfig& config,
                                         uint64_t scenario_seed);

/// Points on the outline of an object's footprint in the track frame (the corners of its boxes,
/// points round its cylinders), for tests of where it stands.
std::vector<Vec2> footprint_points(const SceneryObject& object);

}  // namespace conesim::tracks
