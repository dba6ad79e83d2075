#include "control/lap_line.hpp"

#include <cmath>
#include <optional>

namespace conesim::control {

namespace {
// the line reaches this far beyond the big orange cones, metres
constexpr double kLineExtensionM = 1.0;
}  // namespace

std::optional<LapLine> lap_line_from_cones(const std::vector<core::MapCone>& map,
                                           const core::Pose2& start, double search_m) {
  // centroids of the big orange cones left and right of the start heading
  core::Vec2 sum_l = core::Vec2::Zero(), sum_r = core::Vec2::Zero();
  int n_l = 0, n_r = 0;
  for (const core::MapCone& c : map) {
    if (c.cls != core::ConeClass::kOrangeBig) continue;
    if ((c.position - start.position()).norm() > search_m) continue;
    if (start.inverse_transform(c.position).y() > 0.0) {
      sum_l += c.position;
      ++n_l;
    } else {
      sum_r += c.position;
      ++n_r;
    }
  }
  if (n_l == 0 || n_r == 0) return std::nullopt;

  // the segment between them, a little longer at both ends
  const core::Vec2 l = sum_l / n_l, r = sum_r / n_r;
  const core::Vec2 u = (l - r).normalized();
  return LapLine{l + kLineExtensionM * u, r - kLineExtensionM * u};
}

LapLine lap_line_at(const core::Vec2& point, const core::Pose2& start, double half_width_m) {
  const core::Vec2 left(-std::sin(start.yaw), std::cos(start.yaw));
  return {point + half_width_m * left, point - half_width_m * left};
}

bool crosses_forward(const LapLine& line, const core::Vec2& from, const core::Vec2& to) {
  // the segments cross, and the move goes the way the line's left end is on its left
  if (!core::segments_intersect(from, to, line.left, line.right)) return false;
  return core::cross(line.right - line.left, to - from) > 0.0;
}

}  // namespace conesim::control
