#pragma once
// The cone tracker as conesim's front-end plug-ins run it (sdk/builtin/*_perception_plugin.cpp):
// each frame's cones get track ids and colour votes, predicted with the motion since the
// previous frame, exactly as the built-in perception tracks them.

#include <conesim/sdk.hpp>
#include <optional>
#include <vector>

#include "core/time.hpp"
#include "sdk/builtin/bridge.hpp"
#include "slam/frontend/cone_tracker.hpp"

namespace conesim::sdk_bridge {

class FrameTracker {
 public:
  /// The frame's cones (in the vehicle frame at `stamp`) tracked, as the SDK's frame; the view
  /// points into this object until the next call.
  sdk::ConeFrame update(const core::ConeObservations& cones, sdk::TimeUs stamp,
                        const sdk::Motion& motion) {
    const double dt_s = stamp_ ? core::to_seconds(stamp - *stamp_) : 0.0;
    stamp_ = stamp;
    core::ConeObservations tracked = tracker_.update(
        cones, slam::frontend::motion_over(motion.speed_mps, motion.yaw_rate_rps, dt_s));
    tracked.stamp = stamp;
    return to_sdk(tracked, buffer_);
  }

 private:
  slam::frontend::ConeTracker tracker_{slam::frontend::TrackerConfig{}};
  std::optional<sdk::TimeUs> stamp_;
  std::vector<sdk::ConeObservation> buffer_;
};

}  // namespace conesim::sdk_bridge
