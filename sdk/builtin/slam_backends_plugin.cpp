// conesim's other SLAM back-ends (EKF SLAM, FastSLAM 1.0 and 2.0, the dead-reckoning baseline;
// GraphSLAM too, with its defaults) built as one SLAM plug-in: the back-end the run loop makes
// built in (slam::make_backend), loaded through the SDK's entry point and Slam interface. A run
// with `autonomy.slam: {plugin: .../libconesim_slam_backends.so, config: {backend: ekf}}`
// gives the built-in `slam: ekf` run's metrics to the bit, but for the lane's name and what
// only the built-in interface reports (backend_stats, estimate_source, association timing)
// (tests/app/sdk_test.sh).
//
// config: backend (ekf, fastslam1, fastslam2, odometry or graph; required); where the
// perception sees cones (sensor_x_m, min_range_m, max_range_m, fov_deg: the view conesim gives
// the built-in back-end; the defaults are the cone sensor's); association (nn, ml, scnn, jcbb,
// tracking or none; default: the back-end's own); seed (FastSLAM's random draws; default: from
// the run's seed and the back-end's name, as the built-in lane of that name draws).

#include <conesim/sdk.hpp>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "sdk/builtin/slam_bridge.hpp"
#include "slam/association/methods.hpp"
#include "slam/factory.hpp"

namespace {

using namespace conesim;

std::unique_ptr<slam::Backend> make(const sdk::RunInfo& run, const sdk::Config& config) {
  static const char* const kKnown[] = {"backend",  "sensor_x_m", "min_range_m", "max_range_m",
                                       "fov_deg",  "association", "seed",        nullptr};
  config.require_known(kKnown);
  const std::string backend = config.text("backend", "");
  if (!slam::is_backend(backend))
    throw std::invalid_argument("backend: expected one of " + slam::backend_list() + ", got '" +
                                backend + "'");

  // the settings as conesim runs them (sim/scenario.hpp, default_slam_settings)
  slam::BackendSettings s;
  s.graph.icr_sigma_m = 0.3;
  const double sensor_x = config.number("sensor_x_m", s.graph.sensor_x_m);
  const double min_range = config.number("min_range_m", s.graph.min_range_m);
  const double max_range = config.number("max_range_m", s.graph.max_range_m);
  const double fov = config.number("fov_deg", s.graph.fov_deg);
  s.graph.sensor_x_m = s.ekf.sensor_x_m = s.fastslam.sensor_x_m = sensor_x;
  s.graph.min_range_m = s.fastslam.min_range_m = min_range;
  s.graph.max_range_m = s.fastslam.max_range_m = max_range;
  s.graph.fov_deg = s.fastslam.fov_deg = fov;
  s.fastslam.seed = slam::lane_seed(run.seed, backend);  // as the built-in lane of that name
  if (config.has("seed")) {
    // a whole number read exactly (a double would round seeds above 2^53)
    const std::string text = config.text("seed", "");
    size_t used = 0;
    unsigned long long value = 0;
    try {
      value = std::stoull(text, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != text.size() || text.front() == '-')
      throw std::invalid_argument("seed: expected a whole number from 0 to 2^64 - 1, got '" +
                                  text + "'");
    s.fastslam.seed = value;
  }

  if (config.has("association")) {
    const std::string name = config.text("association", "");
    const auto method = slam::association_from_string(name);
    if (!method)
      throw std::invalid_argument("association: expected one of " + slam::association_names() +
                                  ", got '" + name + "'");
    s.ekf.association.method = s.fastslam.association.method = *method;
    s.odometry.association.method = *method;
    if (backend == "graph")
      throw std::invalid_argument(
          "association: the graph back-end keeps its own here (slam.association of a scenario "
          "chooses it for the built-in one)");
  }
  return slam::make_backend(backend, s);
}

class BackendsPlugin final : public sdk_bridge::BackendSlam {
 public:
  BackendsPlugin(const sdk::RunInfo& run, const sdk::Config& config)
      : BackendSlam(make(run, config)) {}
};

}  // namespace

CONESIM_PLUGIN_SLAM("backends", BackendsPlugin)
