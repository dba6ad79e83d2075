// A follow-the-gap driver: steers for the middle of the gap between the blue (left) and yellow
// (right) cones it sees ahead, with pure pursuit, at a speed its curvature allows; brakes to a
// stop once it has driven a lap (back past the start line) or the straight of acceleration.
// It uses only what a driver gets each tick: the estimate and the cones in the vehicle frame.
//
// config: {max_speed_mps: 6, lateral_accel_mps2: 5, lookahead_gain_s: 0.5, lookahead_min_m: 3.5,
//          half_width_m: 1.5}

#include <algorithm>
#include <cmath>
#include <conesim/sdk.hpp>
#include <string>
#include <vector>

namespace {

using namespace conesim::sdk;

struct Point {
  double x = 0.0;
  double y = 0.0;
};

class FollowGapDriver final : public Driver {
 public:
  FollowGapDriver(const RunInfo& run, const Config& config)
      : event_(run.event), vehicle_(run.vehicle), start_(run.start_pose) {
    // (the RunInfo's views are conesim's until the factory returns: keep values, not views)
    vehicle_.yaw_gain = {};
    static const char* const kKnown[] = {"max_speed_mps",    "lateral_accel_mps2",
                                         "lookahead_gain_s", "lookahead_min_m",
                                         "half_width_m",     nullptr};
    config.require_known(kKnown);
    max_speed_mps_ = config.number("max_speed_mps", 6.0);
    lateral_accel_mps2_ = config.number("lateral_accel_mps2", 5.0);
    lookahead_gain_s_ = config.number("lookahead_gain_s", 0.5);
    lookahead_min_m_ = config.number("lookahead_min_m", 3.5);
    half_width_m_ = config.number("half_width_m", 1.5);
    if (!(max_speed_mps_ > 0.0)) throw std::invalid_argument("max_speed_mps: expected > 0");
    if (run.event == Event::kSkidpad)
      throw std::invalid_argument("this example driver drives no skidpad (no figure of eight)");
  }

  Command update(const DriverInput& in) override {
    const double dt = last_us_ < 0 ? 0.0 : 1e-6 * static_cast<double>(in.now_us - last_us_);
    last_us_ = in.now_us;
    const double v = in.estimate.speed_mps;
    odometer_m_ += std::abs(v) * dt;

    // done: a lap back past the start line (acceleration: 75 m down the straight)
    const Pose2 from_start = compose(inverse(start_), in.estimate.pose);
    const double ax = from_start.x_m, ay = from_start.y_m;
    const bool lap_done = event_ == Event::kAcceleration
                              ? ax > 75.0 + vehicle_.rear_axle_to_front_m + 1.0
                              : odometer_m_ > 60.0 && ax > vehicle_.rear_axle_to_front_m + 1.0 &&
                                    ax < 15.0 && std::abs(ay) < 5.0;
    if (lap_done && !finished_) laps_ = 1;
    finished_ = finished_ || lap_done;
    if (finished_) {
      state_ = "stopping";
      if (std::abs(v) < 0.3) {
        state_ = "stopped";
        return {0.0, 0.0, 1};
      }
      return {0.0, -6.0, 0};
    }

    // the gap: midpoints of each left cone and its nearest right cone ahead
    std::vector<Point> left, right;
    for (const ConeObservation& c : in.observations.cones) {
      if (c.x_m < -0.5 || std::hypot(c.x_m, c.y_m) > 14.0) continue;
      const bool is_left =
          c.cls == ConeClass::kBlue ||
          (c.cls != ConeClass::kYellow && c.cls != ConeClass::kUnknown && c.y_m > 0.0);
      const bool is_right =
          c.cls == ConeClass::kYellow ||
          (c.cls != ConeClass::kBlue && c.cls != ConeClass::kUnknown && c.y_m < 0.0);
      if (is_left) left.push_back({c.x_m, c.y_m});
      if (is_right) right.push_back({c.x_m, c.y_m});
    }
    std::vector<Point> targets;
    for (const Point& l : left) {
      const Point* best = nullptr;
      double best_d = 6.5;
      for (const Point& r : right) {
        const double d = std::hypot(l.x - r.x, l.y - r.y);
        if (d < best_d) best_d = d, best = &r;
      }
      if (best) targets.push_back({0.5 * (l.x + best->x), 0.5 * (l.y + best->y)});
    }
    // one side only: keep half a track width from it
    if (targets.empty()) {
      for (const Point& l : left) targets.push_back({l.x, l.y - half_width_m_});
      for (const Point& r : right) targets.push_back({r.x, r.y + half_width_m_});
    }

    // pure pursuit on the target nearest the look-ahead distance
    const double lookahead = std::max(lookahead_min_m_, lookahead_gain_s_ * v);
    Point target{lookahead, 0.0};
    double best = 1e9;
    for (const Point& p : targets) {
      if (p.x < 1.0) continue;
      const double miss = std::abs(std::hypot(p.x, p.y) - lookahead);
      if (miss < best) best = miss, target = p;
    }
    const double ld = std::max(1.0, std::hypot(target.x, target.y));
    const double alpha = std::atan2(target.y, target.x);
    const double curvature = 2.0 * std::sin(alpha) / ld;
    const double steer = std::clamp(std::atan(vehicle_.wheelbase_m * curvature),
                                    -vehicle_.max_steer_rad, vehicle_.max_steer_rad);

    // speed: what the curvature allows at the lateral limit, and no more than the cap
    const double v_target = std::min(
        max_speed_mps_, std::sqrt(lateral_accel_mps2_ / std::max(std::abs(curvature), 1e-3)));
    const double accel = std::clamp(2.0 * (v_target - v), -6.0, 4.0);
    state_ = targets.empty() ? "blind" : "gap";
    return {steer, accel, 0};
  }

  DriverStatus status() const override { return {laps_, finished_ ? 1 : 0, state_.c_str(), ""}; }

 private:
  Event event_;
  Vehicle vehicle_;
  Pose2 start_;
  double max_speed_mps_ = 6.0;
  double lateral_accel_mps2_ = 5.0;
  double lookahead_gain_s_ = 0.5;
  double lookahead_min_m_ = 3.5;
  double half_width_m_ = 1.5;
  TimeUs last_us_ = -1;
  double odometer_m_ = 0.0;
  bool finished_ = false;
  int32_t laps_ = 0;
  std::string state_ = "start";
};

}  // namespace

CONESIM_PLUGIN_DRIVER("follow_gap", FollowGapDriver)
