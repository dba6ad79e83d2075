#pragma once
// Every SLAM back-end by name, behind the one Backend interface (docs/architecture.md, "Adding
// a back-end"). The harness builds the driving back-end and the shadow ones here.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "slam/backend.hpp"
#include "slam/backends/dead_reckoning.hpp"
#include "slam/backends/ekf_slam.hpp"
#include "slam/backends/fastslam.hpp"
#include "slam/backends/graph_slam.hpp"

namespace conesim::slam {

/// The parameters of every back-end; each takes its own.
struct BackendSettings {
  GraphSlamConfig graph;
  EkfSlamConfig ekf;
  /// FastSLAM 1.0 and 2.0 share their parameters (`slam.fastslam`); the name sets the version.
  FastSlamConfig fastslam;
  /// The dead-reckoning baseline (`slam.odometry`).
  DeadReckoningConfig odometry;
};

/// The back-ends' names: graph, ekf, fastslam1, fastslam2, odometry (the dead-reckoning
/// baseline).
const std::vector<std::string>& backend_names();

/// "graph, ekf, fastslam1, fastslam2, odometry" for error messages.
std::string backend_list();

/// True for a known back-end name.
bool is_backend(const std::string& name);

/// The seed of a particle filter's random draws in a lane: from the run's seed and the lane's
/// name (FNV-1a), so that two lanes of one run draw differently and a run repeats to the bit.
std::uint64_t lane_seed(std::uint64_t run_seed, const std::string& lane);

/// The back-end of that name with its settings; throws std::invalid_argument for an unknown
/// name.
std::unique_ptr<Backend> make_backend(const std::string& name, const BackendSettings& settings);

}  // namespace conesim::slam
