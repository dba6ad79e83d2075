#include "sim/slam_runner.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "core/time.hpp"
#include "sim/slam_figures.hpp"
#include "slam/factory.hpp"

namespace conesim::sim {

using core::TimeUs;

namespace {

// how often the true cones in the perception's view are noted, sim microseconds
constexpr TimeUs kInViewEveryUs = 50'000;

// a back-end's settings as the scenario and its perception make them
slam::BackendSettings lane_settings(const Scenario& s, const std::string& lane,
                                    const std::string& backend,
                                    std::optional<slam::AssociationMethod> method,
                                    const std::vector<std::string>& ablations) {
  slam::BackendSettings settings = s.slam_settings;
  // the lane's own ablations (`graph+no_icr`), over the scenario's keys
  for (const std::string& a : ablations) {
    if (a == "global_only") settings.graph.global_only = true;
    if (a == "no_landmark_edges") settings.graph.landmark_edges = false;
    if (a == "no_icr") settings.graph.icr_sigma_m = 0.0;
    if (a == "no_preliminary") settings.ekf.preliminary_list = false;
  }
  // where the perception sees cones: a landmark there that goes unseen counts against it
  const PerceptionView view = perception_view(s);
  settings.graph.sensor_x_m = view.sensor_x_m;
  settings.graph.min_range_m = view.min_range_m;
  settings.graph.max_range_m = view.max_range_m;
  settings.graph.fov_deg = view.fov_deg;
  settings.ekf.sensor_x_m = view.sensor_x_m;
  settings.fastslam.sensor_x_m = view.sensor_x_m;
  settings.fastslam.min_range_m = view.min_range_m;
  settings.fastslam.max_range_m = view.max_range_m;
  settings.fastslam.fov_deg = view.fov_deg;
  // a particle filter's random draws: from the scenario's seed and the lane's name
  settings.fastslam.seed = slam::lane_seed(s.seed, lane);
  if (!method)
    if (const auto it = s.slam_association.find(backend); it != s.slam_association.end())
      method = it->second;
  if (method) {
    settings.ekf.association.method = *method;
    settings.fastslam.association.method = *method;
    settings.odometry.association.method = *method;
    // without association a landmark is one observation: confirmed at once
    if (*method == slam::AssociationMethod::kNone) settings.graph.confirm_sightings = 1;
    // GraphSLAM's built-in association is ML with individual compatibility and the drift
    // consensus on returning, tracking-aided by default; the other methods replace it
    using M = slam::AssociationMethod;
    settings.graph.association.use_track_ids = *method == M::kTrackingAided;
    if (*method != M::kTrackingAided && *method != M::kMaximumLikelihood) {
      slam::AssociationParams params = settings.ekf.association;
      params.method = *method;
      params.gate_chi2 = settings.graph.association.gate_chi2;
      settings.graph.method = params;
    }
  }
  return settings;
}

// the ablations a lane's settings hold, by the names the shadow syntax uses
std::vector<std::string> lane_ablations(const std::string& backend,
                                        const slam::BackendSettings& settings) {
  std::vector<std::string> out;
  if (backend == "graph") {
    if (settings.graph.global_only) out.push_back("global_only");
    if (!settings.graph.landmark_edges) out.push_back("no_landmark_edges");
    if (settings.graph.icr_sigma_m == 0.0) out.push_back("no_icr");
  }
  if (backend == "ekf" && !settings.ekf.preliminary_list) out.push_back("no_preliminary");
  return out;
}

slam::OdometryConfig odometry_config(const Scenario& s) {
  slam::OdometryConfig c;
  c.wheel_radius_m = s.vehicle.wheel_radius_m;
  c.wheelbase_m = s.vehicle.wheelbase_m;
  // the gyro's yaw rate: on the MuJoCo car the anti-Ackermann front tyres fight, and the
  // bicycle model overstates the yaw rate by up to 18 % at large angles (docs/vehicle.md)
  c.model = slam::MotionModel::kUnicycle;
  // the heading random walk it allows: four times the gyro's white noise (the default's margin
  // over the MEMS IMU), at least the default
  c.gyro_sigma_rad_per_sqrt_s =
      std::max(c.gyro_sigma_rad_per_sqrt_s, 4.0 * s.sensors.imu.gyro_noise_density_rps_rthz);
  return c;
}

}  // namespace

// what an update leaves for the harness: the estimate after it and what it did
struct SlamRunner::UpdateResult {
  core::Estimate estimate;
  std::vector<slam::Association> associations;
  int loop_closures = 0;
  double wall_ms = 0.0;
  double cpu_ms = 0.0;
  double association_us = -1.0;
  // a plug-in's failure in this update (it threw or returned NaN): ends the run
  std::string failure;
};

// one back-end with its scorer and the updates in flight
struct SlamRunner::Lane {
  // an update running on the lane's thread (or done), and when its estimate takes effect
  struct Pending {
    TimeUs due_us;
    // the tick that takes the frame; processed ahead of it (process_ahead) or at it
    TimeUs tick_us;
    bool ahead;
    DeliveredDetections frame;
    core::Pose2 odometry_delta;
    // the input, and who runs it: the lane's thread, or the loop itself if the thread has not
    // started it when it is due (whoever sets the flag first)
    slam::SlamInput input;
    std::shared_ptr<std::atomic<bool>> claimed;
    std::future<UpdateResult> result;
  };

  Lane(std::string lane_name, bool drives, std::unique_ptr<slam::Backend> b,
       const tracks::Track& track, const PerceptionView& view)
      : name(std::move(lane_name)), driving(drives), backend(std::move(b)), scorer(track, view) {}

  // one update, timed in wall and in the thread's CPU time
  UpdateResult run(const slam::SlamInput& input) {
    using clock = std::chrono::steady_clock;
    UpdateResult r;
    const auto start = clock::now();
    const double cpu_start = core::thread_cpu_ms();
    try {
      backend->process(input);
      r.cpu_ms = core::thread_cpu_ms() - cpu_start;
      r.wall_ms = std::chrono::duration<double, std::milli>(clock::now() - start).count();
      r.estimate = backend->estimate();
      r.associations = backend->last_associations();
      r.loop_closures = backend->loop_closures();
      r.association_us = backend->last_association_us();
    } catch (const PluginFailure& e) {
      // the estimate before it stands; the run ends at the tick that takes this update in
      r.failure = e.what();
      r.estimate = last_estimate;
      r.associations.clear();
    }
    return r;
  }

  std::string name;
  bool driving;
  // the association method's name, and whether it reads the labels (ideal)
  std::string association;
  bool ideal = false;
  // the ablations it runs with (metrics.json `ablations`)
  std::vector<std::string> ablations;
  std::unique_ptr<slam::Backend> backend;
  SlamScorer scorer;
  std::deque<Pending> pending;
  core::Estimate last_estimate;
  // the scoring posted to the thread (score, note_cones_in_view) and not yet seen done
  std::deque<std::future<void>> scoring;
  // the scoring not yet posted, in order: it goes to the thread in one job after the next
  // update (which wakes the thread anyway), behind the updates
  std::vector<std::function<void()>> unposted;
  void post_scoring() {
    if (unposted.empty()) return;
    forget_scored();
    scoring.push_back(thread->post_later([jobs = std::move(unposted)] {
      for (const auto& job : jobs) job();
    }));
    unposted.clear();
  }
  // lets go of the scoring already done, oldest first (an exception in it surfaces here): a
  // long run keeps only what is still queued
  void forget_scored() {
    while (!scoring.empty() &&
           scoring.front().wait_for(std::chrono::seconds(0)) == std::future_status::ready) {
      scoring.front().get();
      scoring.pop_front();
    }
  }
  // last member: its jobs use the backend and the scorer, so it stops before the members
  // above go
  std::unique_ptr<WorkerThread> thread;
};

SlamRunner::SlamRunner(const Scenario& s, const tracks::Track& track, const VehicleSim& car)
    : track_(track),
      feed_(s.seed, s.sensors.imu, s.sensors.wheel_encoders, s.faults),
      odometry_(odometry_config(s)) {
  if (s.slam == "none") throw std::invalid_argument("slam: no driving back-end");
  start_pose_ = car.truth().pose;
  latency_us_ = core::from_seconds(s.slam_latency_s);
  const PerceptionView view = perception_view(s);

  // the driving lane, then the shadows in the order given
  struct Spec {
    std::string lane, backend;
    std::optional<slam::AssociationMethod> method;
    std::vector<std::string> ablations;
  };
  std::vector<Spec> specs = {{s.slam, s.slam, std::nullopt, {}}};
  for (const SlamShadow& shadow : s.slam_shadows)
    specs.push_back({shadow.lane_name(), shadow.backend, shadow.association, shadow.ablations});
  for (size_t k = 0; k < specs.size(); ++k) {
    // a lane name given twice runs once
    if (std::any_of(lanes_.begin(), lanes_.end(),
                    [&](const auto& l) { return l->name == specs[k].lane; }))
      continue;
    const slam::BackendSettings settings =
        lane_settings(s, specs[k].lane, specs[k].backend, specs[k].method, specs[k].ablations);
    // the driving lane from a plug-in (autonomy.slam), or a built-in back-end
    std::unique_ptr<slam::Backend> backend;
    if (k == 0 && s.slam_plugin) {
      const std::unique_ptr<RunInfoStorage> run =
          make_run_info(s, driver_vehicle(s.vehicle), start_pose_, {});
      backend = std::make_unique<PluginBackend>(*s.slam_plugin,
                                                make_plugin_slam(*s.slam_plugin, run->info));
    } else {
      backend = slam::make_backend(specs[k].backend, settings);
    }
    auto lane = std::make_unique<Lane>(specs[k].lane, k == 0, std::move(backend), track, view);
    lane->ablations = lane_ablations(specs[k].backend, settings);
    // the association it runs: its own, the scenario's for the back-end, or the default
    std::optional<slam::AssociationMethod> method = specs[k].method;
    if (!method)
      if (const auto it = s.slam_association.find(specs[k].backend); it != s.slam_association.end())
        method = it->second;
    // (a plug-in associates as it does itself)
    lane->association = k == 0 && s.slam_plugin          ? std::string("plugin")
                        : method                         ? std::string(slam::to_string(*method))
                        : specs[k].backend == "graph"    ? "tracking"
                        : specs[k].backend == "odometry" ? "nn"
                                                         : "ml";
    if (method == slam::AssociationMethod::kNone) lane->ablations.push_back("no_association");
    lane->ideal = method == slam::AssociationMethod::kIdeal;
    lane->backend->reset(start_pose_, 0);
    if (s.event == core::EventType::kSkidpad) {
      // skidpad localises against its known layout
      std::vector<core::MapCone> prior;
      for (const auto& c : track.cones)
        prior.push_back({c.id, c.cls, c.position, Eigen::Matrix2d::Identity() * 1e-4});
      lane->backend->set_prior_map(prior);
      lane->scorer.set_prior_map_identities();
    }
    lane->last_estimate = lane->backend->estimate();
    // the driving lane's thread runs the updates with a latency and those processed ahead
    lane->thread = std::make_unique<WorkerThread>();
    lanes_.push_back(std::move(lane));
  }
  odometry_.reset(0);
  frame_odometry_.push_back({0, start_pose_});
  last_estimate_ = lanes_.front()->last_estimate;
  last_frame_pose_ = start_pose_;
}

SlamRunner::~SlamRunner() = default;

void SlamRunner::step(TimeUs t, const VehicleSim& car) {
  // the true cones the perception could see from the true pose, every kInViewEveryUs (on the
  // lanes' threads, in order with the scoring of the updates)
  if (t % kInViewEveryUs == 0) {
    const core::Pose2 pose = car.truth().pose;
    for (auto& lane : lanes_)
      lane->unposted.push_back([&lane = *lane, pose] { lane.scorer.note_cones_in_view(pose); });
  }
  feed_.step(t, car);
  forward_.t = -1;
}

slam::SlamInput SlamRunner::next_input(const DeliveredDetections& frame) {
  // the back-ends' input: the odometry up to the frame's stamp and its cones, the same for all
  const TimeUs stamp = frame.observations.stamp;
  feed_.feed(odometry_, stamp);
  slam::SlamInput input{odometry_.take_delta(stamp), frame.observations, {}};
  forward_.t = -1;
  frame_odometry_.push_back({stamp, frame_odometry_.back().second.compose(input.odometry.delta)});
  // only lane_poses() of a shadow reads the older ones: without shadows the last one will do
  if (lanes_.size() == 1) frame_odometry_.pop_front();
  return input;
}

void SlamRunner::post(const DeliveredDetections& frame, const slam::SlamInput& input, TimeUs tick,
                      bool ahead) {
  for (auto& lane_ptr : lanes_) {
    Lane& lane = *lane_ptr;
    // the labels go only to a lane with the ideal association (an ablation)
    slam::SlamInput lane_input = input;
    if (lane.ideal) lane_input.true_ids = frame.labels.cone_id;
    if (!ahead && lane.driving && latency_us_ == 0) {
      // at once; an update processed ahead for an earlier tick was taken in by catch_up()
      if (!lane.pending.empty())
        throw std::logic_error("SLAM: a frame processed while an earlier one is running");
      take_in(lane, frame, lane.run(lane_input));
      lane.post_scoring();
      continue;
    }
    // on the lane's thread (one update at a time, in order)
    auto claimed = std::make_shared<std::atomic<bool>>(false);
    std::future<UpdateResult> result = lane.thread->post([&lane, lane_input, claimed] {
      return claimed->exchange(true) ? UpdateResult{} : lane.run(lane_input);
    });
    lane.pending.push_back({tick + latency_us_, tick, ahead, frame, input.odometry.delta,
                            lane_input, std::move(claimed), std::move(result)});
    lane.post_scoring();
  }
}

bool SlamRunner::out_of_order(const DeliveredDetections& frame) {
  // a frame stamped before the newest one processed: the odometry has moved past its stamp
  if (frame.observations.stamp < last_frame_stamp_) {
    ++frames_out_of_order_;
    return true;
  }
  last_frame_stamp_ = frame.observations.stamp;
  return false;
}

void SlamRunner::process(const DeliveredDetections& frame, TimeUs now) {
  if (out_of_order(frame)) return;
  post(frame, next_input(frame), now, false);
}

bool SlamRunner::input_final(const DeliveredDetections& frame, TimeUs now) const {
  return frame.observations.stamp + feed_.max_latency_us() <= now;
}

void SlamRunner::process_ahead(const DeliveredDetections& frame, TimeUs tick) {
  if (out_of_order(frame)) return;
  post(frame, next_input(frame), tick, true);
}

void SlamRunner::catch_up(TimeUs t) {
  last_tick_us_ = t;
  for (auto& lane_ptr : lanes_) {
    Lane& lane = *lane_ptr;
    while (!lane.pending.empty()) {
      Lane::Pending& update = lane.pending.front();
      // the driving lane waits for its latency; a shadow's finished updates are scored as
      // they come (in order, so the figures do not depend on when)
      const bool ready =
          lane.driving ? update.due_us <= t
                       : update.tick_us <= t && update.result.wait_for(std::chrono::seconds(0)) ==
                                                    std::future_status::ready;
      if (!ready) break;
      // a due update the lane's thread has not started (a busy machine keeps it waiting) runs
      // here; only the last one pending, so that no later update can run beside it
      const bool here = lane.driving && lane.pending.size() == 1 && !update.claimed->exchange(true);
      take_in(lane, std::move(update.frame), here ? lane.run(update.input) : update.result.get());
      lane.pending.pop_front();
    }
  }
}

void SlamRunner::finish() {
  for (auto& lane_ptr : lanes_) {
    Lane& lane = *lane_ptr;
    for (; !lane.pending.empty(); lane.pending.pop_front()) {
      Lane::Pending& update = lane.pending.front();
      UpdateResult result = update.result.get();
      // processed ahead for a tick the run did not reach: the car never had this frame
      if (update.ahead && update.tick_us > last_tick_us_) continue;
      take_in(lane, std::move(update.frame), std::move(result));
    }
    // the scoring done (an exception in it surfaces here)
    lane.post_scoring();
    for (; !lane.scoring.empty(); lane.scoring.pop_front()) lane.scoring.front().get();
  }
}

void SlamRunner::abandon() {
  for (auto& lane : lanes_) {
    lane->unposted.clear();
    lane->thread->drop_queued();
  }
}

void SlamRunner::take_in(Lane& lane, DeliveredDetections frame, UpdateResult update) {
  if (lane.driving && failure_.empty()) failure_ = update.failure;
  lane.last_estimate = update.estimate;
  if (map_observer_) map_observer_(lane.name, frame.observations.stamp, update.estimate);
  if (lane.driving) {
    last_estimate_ = update.estimate;
    last_observations_ = frame.observations;
    last_frame_pose_ = last_estimate_.pose;
  }
  // the scoring on the lane's thread: nothing in the loop reads it
  lane.unposted.push_back([&lane, frame = std::move(frame), update = std::move(update)] {
    SlamScorer::Update u;
    u.stamp = frame.observations.stamp;
    u.true_pose = frame.capture_pose;
    u.observations = &frame.observations;
    u.true_ids = &frame.labels.cone_id;
    u.estimate = &update.estimate;
    u.associations = &update.associations;
    u.loop_closures = update.loop_closures;
    u.wall_ms = update.wall_ms;
    u.cpu_ms = update.cpu_ms;
    u.association_us = update.association_us;
    lane.scorer.score(u);
  });
}

void SlamRunner::wait_for_lanes() const {
  for (const auto& lane : lanes_) {
    lane->post_scoring();
    lane->thread->wait_idle();
  }
}

const SlamRunner::Forward& SlamRunner::forward(TimeUs t) const {
  if (forward_.t == t) return forward_;
  slam::Odometry forward = odometry_;
  feed_.feed_copy(forward, t);
  forward_.delta = forward.take_delta(t);
  forward_.speed_mps = forward.filtered_speed_mps();
  forward_.mean_speed_mps = forward.mean_speed_mps();
  forward_.yaw_rate_rps = forward.yaw_rate_rps();
  forward_.t = t;
  return forward_;
}

core::Estimate SlamRunner::estimate_now(TimeUs t, slam::frontend::SweepMotion* motion) const {
  // carry the last estimate forward with the odometry delivered since its frame
  const Forward& forward = this->forward(t);
  // the updates still running: the estimate before them, moved on by their odometry
  core::Pose2 pose = last_estimate_.pose;
  for (const Lane::Pending& update : lanes_.front()->pending)
    pose = pose.compose(update.odometry_delta);
  core::Estimate e = last_estimate_;
  e.stamp = t;
  e.pose = pose.compose(forward.delta.delta);
  e.speed_mps = forward.speed_mps;
  e.yaw_rate_rps = forward.yaw_rate_rps;
  if (motion) *motion = {forward.mean_speed_mps, e.yaw_rate_rps};
  return e;
}

core::Pose2 SlamRunner::odometry_pose_now(TimeUs t) const {
  return frame_odometry_.back().second.compose(forward(t).delta.delta);
}

core::ConeObservations SlamRunner::observations_at(const core::Pose2& now) const {
  core::ConeObservations obs = last_observations_;
  for (auto& o : obs.cones)
    o.position = now.inverse_transform(last_frame_pose_.transform(o.position));
  return obs;
}

nlohmann::json SlamRunner::metrics() const {
  wait_for_lanes();
  return lanes_.front()->scorer.metrics(lanes_.front()->last_estimate);
}

nlohmann::json SlamRunner::all_metrics() const {
  wait_for_lanes();
  nlohmann::json out = nlohmann::json::object();
  for (const auto& lane : lanes_) {
    nlohmann::json m = lane->scorer.metrics(lane->last_estimate);
    m["role"] = lane->driving ? "drive" : "shadow";
    m["association"] = lane->association;
    // an ablation that read the labels: never a figure a car could reach
    m["ideal_association"] = lane->ideal;
    m["ablations"] = lane->ablations;
    // which estimate is reported: a particle filter's best particle, say
    m["estimate_source"] = lane->backend->estimate_source();
    if (const auto stats = lane->backend->statistics(); !stats.empty()) {
      nlohmann::json b = nlohmann::json::object();
      for (const auto& [key, value] : stats) b[key] = value;
      m["backend_stats"] = std::move(b);
    }
    out[lane->name] = std::move(m);
  }
  return out;
}

std::vector<std::string> SlamRunner::lane_names() const {
  std::vector<std::string> names;
  for (const auto& lane : lanes_) names.push_back(lane->name);
  return names;
}

std::string SlamRunner::name() const {
  return lanes_.front()->name;
}

const SlamScorer& SlamRunner::scorer() const {
  wait_for_lanes();
  return lanes_.front()->scorer;
}

std::vector<core::Pose2> SlamRunner::lane_poses(size_t lane_index, const std::vector<TimeUs>& t,
                                                const std::vector<core::Pose2>& odometry) const {
  wait_for_lanes();
  // frame k of the lane's scorer is frame k + 1 of frame_odometry_ (entry 0 is the start)
  const SlamScorer& scorer = lanes_[lane_index]->scorer;
  const auto& stamps = scorer.stamps();
  const auto& poses = scorer.estimated_path();
  std::vector<core::Pose2> out;
  size_t k = 0;  // updates stamped no later than the time
  for (size_t i = 0; i < t.size(); ++i) {
    while (k < stamps.size() && stamps[k] <= t[i]) ++k;
    const core::Pose2 at_update = k == 0 ? start_pose_ : poses[k - 1];
    const core::Pose2 odometry_then =
        frame_odometry_[std::min(k, frame_odometry_.size() - 1)].second;
    out.push_back(at_update.compose(odometry_then.inverse().compose(odometry[i])));
  }
  return out;
}

void SlamRunner::write_report(const std::filesystem::path& dir) const {
  wait_for_lanes();
  std::vector<LaneFigures> figures;
  for (const auto& lane : lanes_) {
    write_slam_figures(lane->scorer, track_, lane->last_estimate, dir,
                       lane->driving ? "slam_" : "slam_" + lane->name + "_",
                       lane->driving ? "" : "slam_" + lane->name + "_");
    figures.push_back({lane->name, lane->driving, &lane->scorer, &lane->last_estimate});
  }
  if (figures.size() > 1) write_lanes_figures(figures, track_, dir);
}

}  // namespace conesim::sim
