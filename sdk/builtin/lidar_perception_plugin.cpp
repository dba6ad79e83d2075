// conesim's LiDAR front-end (the `perception: lidar` of a scenario: the LiDAR cone detector and
// the cone tracker of slam/frontend) built as a perception plug-in given the LiDAR. A run with
// `autonomy.perception: {plugin: .../libconesim_lidar_perception.so, sensors: [lidar]}` gives
// the built-in run's metrics to the bit, but for the perception's mode and the LiDAR's own
// scores beside the delivered one (tests/app/sdk_test.sh).
//
// config: `model`, the LiDAR model whose beam pattern the detector expects (the scenario's
// `sensors.lidar.model`; default vlp16).

#include <conesim/sdk.hpp>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/time.hpp"
#include "sdk/builtin/bridge.hpp"
#include "sdk/builtin/frame_tracker.hpp"
#include "sdk/builtin/lidar_frontend.hpp"
#include "sensors/lidar_config.hpp"
#include "slam/frontend/lidar_cone_detector.hpp"

namespace {

using namespace conesim;

slam::frontend::LidarDetectorConfig detector_config(const std::string& model) {
  const std::optional<sensors::LidarConfig> lidar = sensors::lidar_preset(model);
  if (!lidar) {
    std::string known;
    for (const std::string& name : sensors::lidar_preset_names())
      known += (known.empty() ? "" : ", ") + name;
    throw std::invalid_argument("model: unknown LiDAR model '" + model + "' (known: " + known +
                                ")");
  }
  return sdk_bridge::lidar_detector_config(*lidar);
}

class LidarPerceptionPlugin final : public sdk::Perception {
 public:
  LidarPerceptionPlugin(const sdk::RunInfo&, const sdk::Config& config)
      : model_(config.text("model", "vlp16")), config_(detector_config(model_)) {
    static const char* const kKnown[] = {"model", nullptr};
    config.require_known(kKnown);
  }

  sdk::ConeFrame on_lidar(const sdk::LidarSweep& sweep, const sdk::Motion& motion) override {
    // the detector knows where the sensor sits from the first sweep, and that sweep tells
    // whether the LiDAR has more rings than the configured model (another model)
    if (!detector_) {
      const size_t rings = config_.ring_elevations_deg.size();
      for (const sdk::LidarPoint& p : sweep.points)
        if (p.ring >= rings)
          throw std::runtime_error("a point of ring " + std::to_string(p.ring) + ", but model " +
                                   model_ + " has " + std::to_string(rings) +
                                   " rings: set the plug-in's `model` to the scenario's "
                                   "sensors.lidar.model");
      detector_ = std::make_unique<slam::frontend::LidarConeDetector>(
          config_, sdk_bridge::from_sdk(sweep.sensor_in_vehicle));
    }
    // the cones of the sweep, de-skewed to its last column
    const slam::frontend::SweepMotion sweep_motion{motion.speed_mps, motion.yaw_rate_rps};
    const slam::frontend::LidarDetections detections =
        detector_->detect(sdk_bridge::from_sdk(sweep), sweep_motion, sweep.end_us);
    // tracked ids and colour votes, predicted with the motion since the previous sweep
    return tracker_.update(detections.observations(), sweep.end_us, motion);
  }

 private:
  std::string model_;
  slam::frontend::LidarDetectorConfig config_;
  std::unique_ptr<slam::frontend::LidarConeDetector> detector_;
  sdk_bridge::FrameTracker tracker_;
};

}  // namespace

CONESIM_PLUGIN_PERCEPTION("lidar", LidarPerceptionPlugin)
