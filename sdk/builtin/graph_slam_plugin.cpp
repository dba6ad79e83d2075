// conesim's GraphSLAM back-end (slam::GraphSlam) built as a SLAM plug-in: the same back-end the
// run loop makes built in, loaded through the SDK's entry point and Slam interface. A run with
// `autonomy.slam: plugin:.../libconesim_graph_slam.so` gives the built-in run's metrics to the
// bit, but for the lane's name and what only the built-in interface reports (backend_stats,
// estimate_source, association timing) (tests/app/sdk_test.sh).
//
// config: where the perception sees cones (sensor_x_m, min_range_m, max_range_m, fov_deg: the
// view conesim gives the built-in back-end; the defaults are the cone sensor's) and the graph's
// own keys (default: as a scenario's slam.graph) window_poses, confirm_sightings,
// tentative_max_travel_m, global_only, landmark_edges, icr_sigma_m, localise_after_loop_closure
// (slam.graph: of a scenario).

#include <conesim/sdk.hpp>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "sdk/builtin/slam_bridge.hpp"
#include "slam/backends/graph_slam.hpp"

namespace {

using namespace conesim;

slam::GraphSlamConfig read_config(const sdk::Config& config) {
  static const char* const kKnown[] = {"sensor_x_m",
                                       "min_range_m",
                                       "max_range_m",
                                       "fov_deg",
                                       "window_poses",
                                       "confirm_sightings",
                                       "tentative_max_travel_m",
                                       "global_only",
                                       "landmark_edges",
                                       "icr_sigma_m",
                                       "localise_after_loop_closure",
                                       nullptr};
  config.require_known(kKnown);
  slam::GraphSlamConfig c;
  // as conesim runs it (default_slam_settings, sim/scenario.hpp): the ICR edge allows the
  // MuJoCo car's rear-axle slip
  c.icr_sigma_m = 0.3;
  c.sensor_x_m = config.number("sensor_x_m", c.sensor_x_m);
  c.min_range_m = config.number("min_range_m", c.min_range_m);
  c.max_range_m = config.number("max_range_m", c.max_range_m);
  c.fov_deg = config.number("fov_deg", c.fov_deg);
  c.window_poses = static_cast<int>(config.number("window_poses", c.window_poses));
  c.confirm_sightings = static_cast<int>(config.number("confirm_sightings", c.confirm_sightings));
  c.tentative_max_travel_m = config.number("tentative_max_travel_m", c.tentative_max_travel_m);
  c.global_only = config.boolean("global_only", c.global_only);
  c.landmark_edges = config.boolean("landmark_edges", c.landmark_edges);
  c.icr_sigma_m = config.number("icr_sigma_m", c.icr_sigma_m);
  c.localise_after_loop_closure =
      config.boolean("localise_after_loop_closure", c.localise_after_loop_closure);
  if (const std::string e = c.validate(); !e.empty()) throw std::invalid_argument(e);
  return c;
}

class GraphSlamPlugin final : public sdk_bridge::BackendSlam {
 public:
  GraphSlamPlugin(const sdk::RunInfo&, const sdk::Config& config)
      : BackendSlam(std::make_unique<slam::GraphSlam>(read_config(config))) {}
};

}  // namespace

CONESIM_PLUGIN_SLAM("graph", GraphSlamPlugin)
