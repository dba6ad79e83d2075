#pragma once
// Scenery and clutter beside the track (issue 17): the classes of the static objects placed
// around the lanes, and how a LiDAR point on one is labelled. A clutter label is never a cone
// id: cone ids are >= 0, the ground is -1, clutter is -2 and below.

#include <array>
#include <optional>
#include <string_view>

namespace conesim::core {

/// What a scenery object is.
enum class ClutterClass {
  kBarrier,    // a water-filled road barrier
  kFence,      // a construction fence: panels on feet
  kTyreStack,  // stacked tyres
  kTent,       // a 3 x 3 m gazebo: four legs and a roof
  kPerson,     // a standing person
  kSpareCone,  // a cone standing off the track (PacSim's `unknown`)
  kLyingCone,  // a cone lying on its side off the track
  kGrassEdge,  // a strip of grass 6 cm above the asphalt: the step where the paved area ends
};

inline constexpr int kClutterClassCount = 8;

/// All classes, in enum order.
inline constexpr std::array<ClutterClass, kClutterClassCount> kClutterClasses = {
    ClutterClass::kBarrier,   ClutterClass::kFence,    ClutterClass::kTyreStack,
    ClutterClass::kTent,      ClutterClass::kPerson,   ClutterClass::kSpareCone,
    ClutterClass::kLyingCone, ClutterClass::kGrassEdge};

/// The class's name in files and metrics: barrier, fence, tyre_stack, tent, person, spare_cone,
/// lying_cone, grass_edge.
std::string_view to_string(ClutterClass c);

/// The label of a LiDAR point on an object of this class (-2, -3, ...).
constexpr int clutter_label(ClutterClass c) {
  return -2 - static_cast<int>(c);
}

/// The class a point label stands for; nullopt for a cone id, the ground or anything else.
constexpr std::optional<ClutterClass> clutter_of_label(int label) {
  const int k = -2 - label;
  if (k < 0 || k >= kClutterClassCount) return std::nullopt;
  return static_cast<ClutterClass>(k);
}

}  // namespace conesim::core
