#include "slam/factory.hpp"

#include <algorithm>
#include <stdexcept>

namespace conesim::slam {

const std::vector<std::string>& backend_names() {
  static const std::vector<std::string> names = {"graph", "ekf", "fastslam1", "fastslam2",
                                                 "odometry"};
  return names;
}

std::string backend_list() {
  std::string out;
  for (const std::string& n : backend_names()) out += (out.empty() ? "" : ", ") + n;
  return out;
}

bool is_backend(const std::string& name) {
  const auto& names = backend_names();
  return std::find(names.begin(), names.end(), name) != names.end();
}

std::unique_ptr<Backend> make_backend(const std::string& name, const BackendSettings& settings) {
  if (name == "graph") return std::make_unique<GraphSlam>(settings.graph);
  if (name == "ekf") return std::make_unique<EkfSlam>(settings.ekf);
  if (name == "odometry") return std::make_unique<DeadReckoning>(settings.odometry);
  if (name == "fastslam1" || name == "fastslam2") {
    FastSlamConfig config = settings.fastslam;
    config.version = name == "fastslam1" ? 1 : 2;
    return std::make_unique<FastSlam>(config);
  }
  throw std::invalid_argument("unknown SLAM back-end '" + name + "'; expected one of " +
                              backend_list());
}

std::uint64_t lane_seed(std::uint64_t run_seed, const std::string& lane) {
  std::uint64_t seed = 1469598103934665603ULL ^ run_seed;
  for (const char c : lane) seed = (seed ^ static_cast<unsigned char>(c)) * 1099511628211ULL;
  return seed;
}

}  // namespace conesim::slam
