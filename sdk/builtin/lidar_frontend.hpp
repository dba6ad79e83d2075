#pragma once
// The LiDAR cone detector's configuration for a LiDAR model, shared by the built-in
// `perception: lidar` (sim/perception_runner.cpp) and its plug-in build
// (sdk/builtin/lidar_perception_plugin.cpp), so that the two detect the same cones.

#include <algorithm>

#include "sensors/lidar_config.hpp"
#include "slam/frontend/lidar_cone_detector.hpp"

namespace conesim::sdk_bridge {

/// The detector knows the beam pattern of the LiDAR model (not the scene).
inline slam::frontend::LidarDetectorConfig lidar_detector_config(
    const sensors::LidarConfig& lidar) {
  slam::frontend::LidarDetectorConfig config;
  config.sweep_period_s = 1.0 / lidar.rate_hz;
  config.ring_elevations_deg = lidar.elevations_deg;
  std::sort(config.ring_elevations_deg.begin(), config.ring_elevations_deg.end());
  config.azimuth_step_deg = 360.0 / lidar.columns;
  config.range_noise_sigma_m = lidar.range_noise_sigma_m;
  config.beam_divergence_mrad = lidar.beam_divergence_mrad;
  return config;
}

}  // namespace conesim::sdk_bridge
