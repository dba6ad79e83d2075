#pragma once
// Path planning from cones: each boundary is chained cone to cone (blue left, yellow right)
// from the car forward, and the centre line is walked between the two chains, offsetting the
// one visible side by an assumed half width where the other is missing.

#include <optional>
#include <vector>

#include "control/path.hpp"
#include "core/autonomy_types.hpp"

namespace conesim::control {

/// Planner settings.
struct PlannerParams {
  /// Half track width assumed when only one boundary is known, metres.
  double assumed_half_width_m = 1.6;
  /// Longest link between consecutive cones of a chain: one missing cone on a 5 m spacing.
  double max_link_m = 10.5;
  /// Largest turn between consecutive links of a chain, radians.
  double max_link_turn_rad = 1.3;
  /// ... and for a link up to short_link_m long of the chains ahead of the car: round the inner
  /// cones of a minimum hairpin (1.5 m inner radius, cones 2 m apart) the boundary turns by
  /// 1.4 rad a link, and a chain that may not follow it jumps to a cone of another part of the
  /// track. Not for a whole circuit's chains, whose cones the lap driven orders where a chain
  /// cannot follow (boundaries_along): the racing line keeps the boundaries it had.
  double max_short_link_turn_rad = 1.75;
  double short_link_m = 2.5;
  /// A link costs its length times (1 + turn_weight * turn^2): straight-on links win. With 2,
  /// the off-class penalty of a start's big orange cone outweighed a 0.7 rad turn to a yellow
  /// cone of the lane beyond (EUFS Jellybean), and the boundary left the start gate.
  double turn_weight = 3.0;
  /// Extra cost of an orange or unknown cone in a chain, metres (a coloured cone is preferred).
  double off_class_penalty_m = 3.0;
  /// A cone of one chain closer than this to the other boundary is taken for a wrong colour or
  /// a spurious cone and dropped (tracks are 3 m wide or more; separate parts of a circuit keep
  /// 2 m between their boundaries), metres.
  double min_boundary_gap_m = 1.5;
  /// A cone of one chain further than this from the other boundary, where that boundary runs
  /// beside it, belongs to another part of the track and is dropped, metres.
  double max_boundary_gap_m = 6.0;
  /// Step of the centre-line walk, metres.
  double step_m = 1.0;
  /// A boundary further than this from the walk point is ignored there, metres.
  double max_side_distance_m = 4.0;
  /// Moving-average half window applied to the walked centre line, points.
  int smooth_half_window = 1;
};

/// The two boundaries as ordered chains of cone positions (map frame).
struct Boundaries {
  std::vector<Vec2> left;
  std::vector<Vec2> right;
  /// True when a chain came back to its first cone (a whole circuit).
  bool left_closed = false;
  bool right_closed = false;
};

/// Chains the boundaries from the cones near `from` forward, each up to max_length_m long.
/// With `whole_circuit` a chain runs until it returns to its first cone.
Boundaries chain_boundaries(const std::vector<core::MapCone>& cones, const core::Pose2& from,
                            const PlannerParams& params, double max_length_m, bool whole_circuit);

/// The boundaries of a whole circuit ordered along a closed reference line round it (the car's
/// own lap, say), in the order of each cone's nearest point along the line: blue cones within
/// max_side_distance_m of it to the left, yellow ones to the right, orange ones to the side they
/// lie on; a blue or yellow cone of a wrong colour for its place is left out: more than 0.75 m
/// on the wrong side of the line, or nearer, across the lane, to the cones of the other colour
/// within 6 m along the line than to those of its own. Where a whole circuit's chains cannot follow
/// a turn (the inner cones of a minimum hairpin turn by more than its links may) the line the car
/// drove still orders the cones. A side is closed when it has cones all round: no stretch of the
/// line longer than 2 max_link_m without one.
Boundaries boundaries_along(const Path& reference, const std::vector<core::MapCone>& cones,
                            const PlannerParams& params);

/// Closed boundaries with points added in their gaps, where a link is much longer than both its
/// neighbours (cones missing from an even spacing): on a smooth curve through the cones either
/// side, where the missing cones would stand. The added points are appended to `cones` as
/// cones of the side's colour (id -1), so that a footprint check keeps clear of them too.
Boundaries with_gaps_filled(const Boundaries& boundaries, std::vector<core::MapCone>& cones);

/// The cones with those of a wrong colour for their place beside a closed reference line (within
/// max_side_distance_m of it, a blue cone more than 0.75 m right of it or a yellow one left, or
/// nearer across the lane to the other colour's cones beside it than to its own's, as in
/// boundaries_along) made unknown: still obstacles, no longer a side the line must keep.
std::vector<core::MapCone> with_sides_kept(const Path& reference, std::vector<core::MapCone> cones,
                                           const PlannerParams& params);

/// Walks the centre line between the boundaries from `from`, one step at a time, up to
/// max_length_m. With `whole_circuit` the chains are closed loops and the walk stops when it
/// comes back across the start; the result then excludes the start point's duplicate.
std::vector<Vec2> walk_centre_line(const Boundaries& boundaries, const core::Pose2& from,
                                   const PlannerParams& params, double max_length_m,
                                   bool whole_circuit);

/// The local path ahead of the car from the cones near it: chained, walked and smoothed. The
/// first point is the car's position. Empty when no boundary is in sight.
Path plan_local_path(const std::vector<core::MapCone>& cones, const core::Pose2& pose,
                     const PlannerParams& params, double horizon_m);

/// The closed centre line of a whole circuit from its map, starting at the start pose and
/// resampled every spacing_m; nullopt when the boundaries do not close into one loop.
std::optional<Path> plan_circuit(const std::vector<core::MapCone>& map, const core::Pose2& start,
                                 const PlannerParams& params, double spacing_m = 1.0);

}  // namespace conesim::control
