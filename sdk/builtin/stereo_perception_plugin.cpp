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
#include "sdk/builtin/frame_tracker.hpp"
#include "slam/frontend/stereo_cone_detector.hpp"

namespace {

using namespace conesim;

class StereoPerceptionPlugin final : public sdk::Perception {
 public:
  StereoPerceptionPlugin(const sdk::RunInfo&, const sdk::Config& config)
      : detector_(slam::frontend::StereoDetectorConfig{}) {
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
    return tracker_.update(detections.observations(), pair.stamp_us, motion);
  }

 private:
  slam::frontend::StereoConeDetector detector_;
  sdk_bridge::FrameTracker tracker_;
};

}  // namespace

CONESIM_PLUGIN_PERCEPTION("stereo", StereoPerceptionPlugin)
