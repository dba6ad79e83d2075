#include "slam/loop_closure.hpp"

#include <cmath>
#include <sstream>

namespace conesim::slam {

std::string LoopClosureConfig::validate() const {
  std::ostringstream s;
  if (!(min_travel_m >= 0.0))
    s << "loop_closure.min_travel_m: expected >= 0";
  else if (!(returned_min_travel_m >= 0.0))
    s << "loop_closure.returned_min_travel_m: expected >= 0";
  else if (!(heading_tolerance_rad > 0.0 && heading_tolerance_rad <= M_PI))
    s << "loop_closure.heading_tolerance_rad: expected in (0, pi]";
  else if (min_returned < 1)
    s << "loop_closure.min_returned: expected >= 1";
  else if (!(returned_fraction >= 0.0 && returned_fraction <= 1.0))
    s << "loop_closure.returned_fraction: expected in [0, 1]";
  else if (big_orange_min_returned < 0)
    s << "loop_closure.big_orange_min_returned: expected >= 0";
  else if (!(start_radius_m > 0.0))
    s << "loop_closure.start_radius_m: expected > 0";
  else if (!(start_lateral_m > 0.0))
    s << "loop_closure.start_lateral_m: expected > 0";
  else if (!(start_window_m >= 0.0))
    s << "loop_closure.start_window_m: expected >= 0";
  else if (start_min_returned < 0)
    s << "loop_closure.start_min_returned: expected >= 0";
  else if (!(closure_delay_m >= 0.0))
    s << "loop_closure.closure_delay_m: expected >= 0";
  return s.str();
}

LoopState next_loop_state(const LoopClosureConfig& config, LoopState state, bool in_view,
                          bool observed, double travel_since_first_m, double heading_change_rad) {
  switch (state) {
    case LoopState::kInView:
      // leaves the view when it is neither predicted in it nor seen
      return in_view || observed ? LoopState::kInView : LoopState::kLeftView;
    case LoopState::kLeftView:
      // returns when seen again long after its first sighting, from the same direction
      if (observed && travel_since_first_m >= config.returned_min_travel_m &&
          std::abs(heading_change_rad) <= config.heading_tolerance_rad) {
        return LoopState::kReturned;
      }
      return LoopState::kLeftView;
    case LoopState::kReturned:
      return LoopState::kReturned;
  }
  return state;
}

bool turned_once_around(double turned_rad, double tolerance_rad) {
  return std::abs(std::abs(turned_rad) - 2.0 * M_PI) <= tolerance_rad;
}

bool back_at_start(const LoopClosureConfig& config, const core::Pose2& start,
                   const core::Pose2& pose, double turned_rad) {
  const core::Vec2 offset = start.inverse_transform(pose.position());
  const bool turned_once = turned_once_around(turned_rad, config.heading_tolerance_rad);
  return offset.norm() <= config.start_radius_m && std::abs(offset.y()) <= config.start_lateral_m &&
         std::abs(core::normalize_angle(pose.yaw - start.yaw)) <= config.heading_tolerance_rad &&
         turned_once;
}

bool loop_closed(const LoopClosureConfig& config, const LoopClosureStats& stats) {
  // never before a lap can have been driven
  if (stats.travel_m < config.min_travel_m) return false;
  // a lap ends back at the start: elsewhere (after a hairpin, say) old landmarks return too
  if (!stats.near_start || stats.start_returned < config.start_min_returned) return false;
  // the statistics: enough returned landmarks, and the old ones in view are mostly returned
  const bool consistent = stats.old_matched > 0 && stats.old_matched_returned >=
                                                       config.returned_fraction * stats.old_matched;
  if (stats.returned >= config.min_returned && consistent) return true;
  // the big orange cue, backed by a few returned landmarks
  return stats.big_orange_returned && stats.returned >= config.big_orange_min_returned &&
         consistent;
}

}  // namespace conesim::slam
