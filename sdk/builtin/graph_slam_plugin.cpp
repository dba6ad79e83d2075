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
#include <stdexcept>
#include <string>
#include <vector>

#include "sdk/builtin/slam_bridge.hpp"
#include "slam/backends/graph_slam.hpp"

namespace {

using namespace conesim;

using sdk_bridge::from_sdk;
using sdk_bridge::to_sdk;

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

class GraphSlamPlugin final : public sdk::Slam {
 public:
  GraphSlamPlugin(const sdk::RunInfo&, const sdk::Config& config) : graph_(read_config(config)) {}

  void reset(const sdk::Pose2& start, sdk::TimeUs stamp_us,
             sdk::Span<sdk::MapCone> prior_map) override {
    graph_.reset(from_sdk(start), stamp_us);
    if (prior_map.empty()) return;
    std::vector<core::MapCone> map;
    for (const sdk::MapCone& c : prior_map) map.push_back(from_sdk(c));
    graph_.set_prior_map(map);
  }

  void process(const sdk::SlamInput& in) override {
    graph_.process({from_sdk(in.odometry), from_sdk(in.observations), {}});
    // what it did with each observation, and the landmarks the new ones started
    codes_.clear();
    started_.clear();
    for (const slam::Association& a : graph_.last_associations()) {
      codes_.push_back(a.code());
      started_.push_back(a.kind == slam::Association::Kind::kNew ? a.landmark_id : -1);
    }
  }

  sdk::Estimate estimate() const override { return to_sdk(graph_.estimate(), map_); }
  sdk::Span<int32_t> associations() const override { return {codes_.data(), codes_.size()}; }
  sdk::Span<int32_t> new_landmark_ids() const override {
    return {started_.data(), started_.size()};
  }
  int32_t loop_closures() const override { return graph_.loop_closures(); }

 private:
  slam::GraphSlam graph_;
  std::vector<int32_t> codes_;
  std::vector<int32_t> started_;
  mutable std::vector<sdk::MapCone> map_;
};

}  // namespace

CONESIM_PLUGIN_SLAM("graph", GraphSlamPlugin)
