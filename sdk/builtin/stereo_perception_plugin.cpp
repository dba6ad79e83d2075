// conesim's stereo front-end (the `perception: stereo` of a scenario: the stereo cone detector
// and the cone tracker of slam/frontend) built as a perception plug-in given the camera. A run
// with `autonomy.perception: {plugin: .../libconesim_stereo_perception.so, sensors: [camera]}`
// gives the built-in run's metrics to the bit, but for the perception's mode and the camera's
// own score beside the delivered one (tests/app/sdk_test.sh).
//
// config: none.

#include <conesim/sdk.hpp>
#include <optional>
#include <vector>

#include "core/time.hpp"
#include "sdk/builtin/bridge.hpp"
#include "slam/frontend/cone_tracker.hpp"
#include "slam/frontend/stereo_cone_detector.hpp"

namespace {

using namespace conesim;

class StereoPerceptionPlugin final : public sdk::Perception {
 public:
  StereoPerceptionPlugin(const sdk::RunInfo&, const sdk::Config& config)
      : detector_(slam::frontend::StereoDetectorConfig{}),
        tracker_(slam::frontend::TrackerConfig{}) {
    static const char* const kKnown[] = {nullptr};
    config.require_known(kKnown);
  }

  // given the camera only
  sdk::ConeFrame on_lidar(const sdk::LidarSweep&, const sdk::Motion&) override { return {}; }

  sdk::ConeFrame on_stereo(const sdk::StereoFrame& pair, const sdk::Motion& motion) override {
    // the cones of the pair, at its stamp
    slam::frontend::StereoDetections detections = detector_.detect(sdk_bridge::from_sdk(pair));
    detections.stamp = pair.stamp_us;
    // tracked ids and colour votes, predicted with the motion since the previous pair
    const double dt_s = stamp_us_ ? core::to_seconds(pair.stamp_us - *stamp_us_) : 0.0;
    stamp_us_ = pair.stamp_us;
    core::ConeObservations tracked =
        tracker_.update(detections.observations(),
                        slam::frontend::motion_over(motion.speed_mps, motion.yaw_rate_rps, dt_s));
    tracked.stamp = pair.stamp_us;
    return sdk_bridge::to_sdk(tracked, cones_);
  }

 private:
  slam::frontend::StereoConeDetector detector_;
  slam::frontend::ConeTracker tracker_;
  std::optional<sdk::TimeUs> stamp_us_;
  std::vector<sdk::ConeObservation> cones_;
};

}  // namespace

CONESIM_PLUGIN_PERCEPTION("stereo", StereoPerceptionPlugin)
