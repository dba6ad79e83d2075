#pragma once
// The start/finish line as the car knows it, and the test of a forward crossing.

#include <optional>
#include <vector>

#include "core/autonomy_types.hpp"

namespace conesim::control {

/// A line segment the car crosses, from its left end to its right end (seen driving forward).
struct LapLine {
  core::Vec2 left = core::Vec2::Zero();
  core::Vec2 right = core::Vec2::Zero();
};

/// The start/finish line from the big orange cones of the map that lie within search_m of the
/// start pose, one group each side of its heading; nullopt when a side has none.
std::optional<LapLine> lap_line_from_cones(const std::vector<core::MapCone>& map,
                                           const core::Pose2& start, double search_m = 25.0);

/// A line across the start heading through `point`, half_width_m to each side.
LapLine lap_line_at(const core::Vec2& point, const core::Pose2& start, double half_width_m);

/// True when the move from `from` to `to` crosses the line in the forward direction (from its
/// back side to its front side).
bool crosses_forward(const LapLine& line, const core::Vec2& from, const core::Vec2& to);

}  // namespace conesim::control
