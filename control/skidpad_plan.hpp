#pragma once
// The skidpad from its known layout: the two circle centres are fitted to the prior map's
// cones, and the figure-eight path (entry, two right laps, two left laps, exit) is built on
// them.

#include <optional>
#include <vector>

#include "control/path.hpp"
#include "core/autonomy_types.hpp"

namespace conesim::control {

/// The skidpad as fitted from its cones (map frame).
struct SkidpadGeometry {
  /// Centres of the right (driven first, clockwise) and left circles.
  Vec2 right_centre = Vec2::Zero();
  Vec2 left_centre = Vec2::Zero();
  /// Where the circles touch: the middle of the timing line.
  Vec2 timing_point = Vec2::Zero();
  /// Unit vector of the driving direction through the timing line.
  Vec2 forward = Vec2::UnitX();
  /// Radius of the driving line: half the distance between the centres, metres.
  double radius_m = 0.0;
};

/// Fits the skidpad geometry to the prior map: the timing point from the big orange cones (or
/// the centroid of the circle cones), and each centre by a circle fit to its inner ring of cones.
/// `start` gives the driving direction. nullopt when the map holds too few cones.
std::optional<SkidpadGeometry> fit_skidpad(const std::vector<core::MapCone>& prior_map,
                                           const core::Pose2& start);

/// The driving path over the fitted skidpad and where along it each lap ends.
struct SkidpadPlan {
  Path path;
  /// Arc length at the end of each of the four laps, metres.
  std::vector<double> lap_end_s;
  /// Arc length where the car is to stand still (the end of the path), metres.
  double stop_s = 0.0;
};

/// Entry from `start` to the timing line, two clockwise laps of the right circle, two
/// counter-clockwise laps of the left one, and the exit straight to stop_after_m past the
/// timing line; points every spacing_m.
SkidpadPlan plan_skidpad(const SkidpadGeometry& geometry, const core::Pose2& start,
                         double stop_after_m, double spacing_m = 0.5);

}  // namespace conesim::control
