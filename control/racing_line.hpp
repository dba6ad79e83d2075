#pragma once
// A racing line inside the lanes that keeps the car's whole footprint clear of the cones: the
// corridor between the two boundaries along a reference line, the path of least curvature
// (least squared second differences) within the corridor shrunk by half the car's width plus a
// margin, and a check of the rectangle of the car (front and rear overhang included) along it,
// which narrows the corridor where a corner of the car would come too close to a cone and
// plans again.

#include <string>
#include <vector>

#include "control/path.hpp"
#include "core/autonomy_types.hpp"

namespace conesim::control {

/// The car's footprint about the rear axle (the reference point the path is for).
struct Footprint {
  /// Front wing ahead of the rear axle, rear end behind it, half the width, metres.
  double front_m = 2.25;
  double rear_m = 0.65;
  double half_width_m = 0.7;
  /// Clearance planned between the footprint and a cone's base, metres.
  double margin_m = 0.3;
  /// Where the line turns tighter than `tight_curvature` (1/m; 0: nowhere) the clearance is
  /// `tight_margin_m` instead (when larger), from `tight_before_m` before such a turn to
  /// `tight_after_m` past it: the car takes those turns near full lock with no steering left to
  /// correct, and leaves them off the line, accelerating at the tyres' limit.
  double tight_margin_m = 0.0;
  double tight_curvature = 0.0;
  double tight_before_m = 10.0;
  double tight_after_m = 25.0;
};

/// The free space either side of a reference line.
struct Corridor {
  /// Reference line points (evenly spaced) and the unit left normal at each.
  std::vector<Vec2> centre;
  std::vector<Vec2> normal;
  /// Distance from each reference point to the left and right boundary, metres (> 0).
  std::vector<double> left_m;
  std::vector<double> right_m;
  bool closed = false;
};

/// The corridor along `centre` between the boundary polylines `left` and `right` (cone
/// centres; closed polylines join their last point to the first). A side further than
/// max_side_m (a missing boundary) counts as max_side_m away.
Corridor make_corridor(const std::vector<Vec2>& centre, bool closed, const std::vector<Vec2>& left,
                       const std::vector<Vec2>& right, bool boundaries_closed,
                       double max_side_m = 3.0);

/// The line through the corridor and what it took.
struct RacingLine {
  /// The rear-axle path (points one per corridor point).
  Path path;
  /// Lateral offset of each point from the reference line, metres, positive left.
  std::vector<double> offset_m;
  /// Smallest clearance of the footprint to a cone along the path, metres, and where.
  double min_clearance_m = 0.0;
  Vec2 min_clearance_at = Vec2::Zero();
  /// Largest absolute curvature of the path, 1/m, and where.
  double max_curvature = 0.0;
  Vec2 max_curvature_at = Vec2::Zero();
  /// Narrowest corridor (boundary to boundary through the reference point), metres, and where.
  double min_width_m = 0.0;
  Vec2 min_width_at = Vec2::Zero();
};

/// The least-curvature line through the corridor with the footprint kept `footprint.margin_m`
/// clear of `cones` (their base radius is taken from their class). Where the corridor is
/// narrower than the car plus margins the line keeps to the middle of it.
///
/// With a `curvature_target` (1/m; 0: none) the line is planned again where it is tighter than
/// that, with its curvature there weighing more: the turn spreads over more of its corner at a
/// larger radius where the corridor leaves room (least squared curvature alone takes a hairpin
/// on a short arc tighter than it needs to be).
RacingLine plan_racing_line(const Corridor& corridor, const std::vector<core::MapCone>& cones,
                            const Footprint& footprint, double curvature_target = 0.0);

/// The least-curvature line between the boundaries, planned `passes` times, each pass on the
/// corridor along the previous line (resampled every spacing_m): the offsets along fixed
/// normals bunch up on the inside of a tight turn, which a single pass takes for less
/// curvature, so the line is straightened on its own normals again. An open line starts at
/// the reference line's first point. `min_width_m` is the first corridor's.
RacingLine plan_racing_line(const std::vector<Vec2>& reference, bool closed,
                            const std::vector<Vec2>& left, const std::vector<Vec2>& right,
                            const std::vector<core::MapCone>& cones, const Footprint& footprint,
                            int passes = 3, double spacing_m = 1.0, double curvature_target = 0.0);

/// Smallest clearance between the footprint and the cones with the rear axle on `pose`, metres
/// (negative: a cone inside the footprint); `at` gets the nearest cone's position.
double footprint_clearance(const core::Pose2& pose, const std::vector<core::MapCone>& cones,
                           const Footprint& footprint, Vec2* at = nullptr);

}  // namespace conesim::control
