#include "control/manoeuvre.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "vehicle_models/kinematics.hpp"

namespace conesim::control {

namespace {

using core::MapCone;
using core::Pose2;

// clearance is compared in steps of this, metres; a manoeuvre replaces following the path (or
// the manoeuvre under way) only when it keeps this much more clearance
constexpr double kClearanceStepM = 0.02;
constexpr double kClearanceGainM = 0.04;
// the end of the horizon: distance from the path and heading error cost this per metre, radian
constexpr double kLateralWeight = 0.5;
constexpr double kHeadingWeight = 1.0;
// straying further than this from the path is leaving the lane (a hairpin's island has gaps
// between its cones a roll-out could slip through), metres
constexpr double kMaxDeviationM = 2.5;
// the path is where the cones are known to leave room: straying from it by more than the free
// band costs this much per metre (what lies beyond may not have been seen yet)
constexpr double kFreeDeviationM = 0.5;
constexpr double kDeviationWeight = 10.0;
// cones are taken this much further than the horizon's distance and the footprint reach, metres
constexpr double kConeReachExtraM = 2.0;
// full lock the other way than the tight turn ahead is tried when the steering is already
// turned that way by this share of full lock
constexpr double kOtherSideSteerShare = 0.3;
// steering past this share of full lock towards a side is a turn under way: no candidate
// straightens it before turning that way
constexpr double kCommittedSteerShare = 0.5;
// the roll-outs' motion is integrated in sub-steps of at most this, seconds (a quarter of the
// default car's steering lag)
constexpr double kSubstepS = 0.01;
// cones further than this from the rear axle cannot touch the footprint, metres
constexpr double kFootprintReachM = 4.0;

// where the roll-out is on the path, as arc length
double arc_at(const std::vector<double>& s, const PathProjection& on) {
  return s[on.segment] + on.t * (s[on.segment + 1] - s[on.segment]);
}

struct Rollout {
  double clearance = std::numeric_limits<double>::infinity();
  double max_deviation = 0.0;
  Pose2 end;
  PathProjection end_on_path;
};

struct Context {
  const ManoeuvreParams& p;
  const Path& path;
  const std::vector<double>& s;
  const std::vector<double>& k;
  const SpeedCommand& speed_command;
  const std::vector<MapCone>& cones;
};

// rolls the manoeuvre out; gives up (clearance -infinity) once the footprint comes closer than
// `give_up_below` to a cone
Rollout roll(const Context& c, const Pose2& start, double speed, double steer_now,
             const PathProjection& here, const Manoeuvre& m, double* first_command,
             double give_up_below = -std::numeric_limits<double>::infinity()) {
  const ManoeuvreParams& p = c.p;
  Rollout r;
  RolloutCar car{start, steer_now, steer_now};
  PathProjection on = here;
  for (double t = 0.0; t < p.horizon_s - 1e-9;) {
    // fine steps while the manoeuvre's timing matters, coarser ones for the tail
    const double dt = t < p.fine_s ? p.step_s : p.coarse_step_s;
    const bool first_step = t == 0.0;
    t += dt;
    double wanted = 0.0;
    if (m.wait_s >= 0.0 && t >= m.wait_s && t < m.wait_s + m.hold_s)
      wanted = m.side * p.max_steer_rad;
    else if (m.straight && t < m.wait_s)
      wanted = 0.0;
    else
      wanted = track_path(p.tracker, car.pose, speed, c.path, on,
                          curvature_near(c.path, c.s, c.k, arc_at(c.s, on) + p.preview_s * speed,
                                         p.curvature_span_m));
    if (first_step) *first_command = wanted;
    car.step(p, wanted, speed, dt);
    const Pose2& pose = car.pose;
    r.clearance = std::min(r.clearance, signed_footprint_clearance(pose, c.cones, p.footprint));
    if (r.clearance < give_up_below) {
      r.clearance = -std::numeric_limits<double>::infinity();
      return r;
    }
    // the projection follows the roll-out a few segments at a time
    const size_t window = static_cast<size_t>(std::ceil(speed * dt)) + 3;
    on = project_onto(c.path, pose.position(), on.segment, window);
    r.max_deviation = std::max(r.max_deviation, on.distance_m);
    // the speed as the driver commands it, within what the car does
    const double accel =
        std::clamp(c.speed_command(speed, arc_at(c.s, on)), -p.max_decel_mps2, p.max_accel_mps2);
    speed = std::max(0.5, speed + accel * dt);
  }
  r.end = car.pose;
  r.end_on_path = on;
  return r;
}

}  // namespace

void RolloutCar::step(const ManoeuvreParams& p, double command, double speed_mps, double dt_s) {
  // sub-steps short against the lag: with one update per driver step (as long as the lag) the
  // lag vanished and the wheels took the step's end angle at its start, so the roll-outs turned
  // in 0.05-0.08 s before the car (hard autocross 7074 with GraphSLAM: a turn-in from straight to
  // full lock at 3 m/s ran 0.13 m wider than its roll-out, into an outer cone)
  const int substeps = std::max(1, static_cast<int>(std::ceil(dt_s / kSubstepS - 1e-9)));
  const double h = dt_s / substeps;
  const double max_change = p.max_steer_rate_rps * dt_s / substeps;
  const double follow = 1.0 - std::exp(-h / std::max(p.steer_lag_s, 1e-9));
  for (int i = 0; i < substeps; ++i) {
    steer += std::clamp(command - steer, -max_change, max_change);
    wheels += (steer - wheels) * follow;
    const double effective = std::atan(std::tan(wheels) * yaw_gain_at(p.yaw_gain, wheels));
    pose = vehicle_models::bicycle_step(pose, speed_mps, effective, p.wheelbase_m, h);
  }
}

Manoeuvre Manoeuvre::advanced(double dt_s) const {
  Manoeuvre m = *this;
  if (m.wait_s < 0.0) return m;
  m.wait_s -= dt_s;
  if (m.wait_s < 0.0) {
    m.hold_s = std::max(0.0, m.hold_s + m.wait_s);
    m.wait_s = 0.0;
  }
  return m;
}

double signed_footprint_clearance(const Pose2& pose, const std::vector<MapCone>& cones,
                                  const Footprint& f) {
  double best = std::numeric_limits<double>::infinity();
  const double c = std::cos(pose.yaw), s = std::sin(pose.yaw);
  for (const MapCone& cone : cones) {
    const Vec2 rel = cone.position - pose.position();
    if (rel.squaredNorm() > kFootprintReachM * kFootprintReachM) continue;
    // the cone in the car's frame
    const Vec2 q(c * rel.x() + s * rel.y(), -s * rel.x() + c * rel.y());
    const double dx = std::max(-f.rear_m - q.x(), q.x() - f.front_m);
    const double dy = std::abs(q.y()) - f.half_width_m;
    // outside: Euclidean distance to the box; inside: minus the distance to its nearest edge
    const double outside = std::hypot(std::max(dx, 0.0), std::max(dy, 0.0));
    const double d = outside > 0.0 ? outside : std::max(dx, dy);
    best = std::min(best, d - 0.5 * core::cone_size(cone.cls).base_m);
  }
  return best;
}

ManoeuvreChoice choose_manoeuvre(const ManoeuvreParams& p, const Pose2& pose, double speed_mps,
                                 double steer_now_rad, const Path& path, const PathProjection& here,
                                 const SpeedCommand& speed_command,
                                 const std::vector<MapCone>& cones, double nominal_steer_rad,
                                 const Manoeuvre* previous) {
  ManoeuvreChoice best{{}, nominal_steer_rad, 0.0, true};
  if (path.segment_count() == 0) return best;
  const double speed = std::max(0.5, speed_mps);
  std::vector<MapCone> near;
  const double reach = speed * p.horizon_s + kFootprintReachM + kConeReachExtraM;
  for (const MapCone& c : cones)
    if ((c.position - pose.position()).norm() <= reach) near.push_back(c);
  const std::vector<double> s = path.arc_lengths();
  const std::vector<double> k = curvatures(path.points, path.closed);
  const Context context{p, path, s, k, speed_command, near};
  const double s_here = arc_at(s, here);
  const double lap = path.closed ? s.back() : 0.0;

  // candidates are ranked by clearance first (up to the enough level, in steps, leaving the
  // lane counting as a hit), then by how far they get along the path and how well they end
  auto clearance_of = [&](const Rollout& r) {
    if (r.max_deviation > kMaxDeviationM) return -1.0;
    return std::floor(std::min(r.clearance, p.enough_clearance_m) / kClearanceStepM) *
           kClearanceStepM;
  };
  auto progress_of = [&](const Rollout& r) {
    double s_end = arc_at(s, r.end_on_path);
    if (lap > 0.0 && s_end < s_here - 0.5 * lap) s_end += lap;
    const Vec2 a = path.points[r.end_on_path.segment];
    const Vec2 b = path.segment_end(r.end_on_path.segment);
    const double heading =
        std::abs(core::normalize_angle(r.end.yaw - std::atan2(b.y() - a.y(), b.x() - a.x())));
    return (s_end - s_here) - kLateralWeight * r.end_on_path.distance_m - kHeadingWeight * heading -
           kDeviationWeight * std::max(0.0, r.max_deviation - kFreeDeviationM);
  };

  double first = 0.0;
  const Rollout nominal = roll(context, pose, speed, steer_now_rad, here, {}, &first);
  best.clearance_m = nominal.clearance;
  // following the path keeps clear enough: nothing to search for
  double best_clearance = clearance_of(nominal);
  if (best_clearance >= p.enough_clearance_m - 1e-9) return best;
  // a manoeuvre has to gain this much clearance over the incumbent to replace it
  double best_progress = progress_of(nominal);
  double needed_gain = kClearanceGainM;
  auto consider = [&](const Manoeuvre& m) {
    // a candidate that comes closer to a cone than the incumbent cannot win
    const Rollout r = roll(context, pose, speed, steer_now_rad, here, m, &first,
                           best_clearance + needed_gain - kClearanceStepM);
    if (!std::isfinite(r.clearance)) return;
    const double clearance = clearance_of(r), progress = progress_of(r);
    if (clearance < best_clearance + needed_gain - 1e-9) return;
    if (clearance < best_clearance + 1e-9 && needed_gain <= 0.0 && progress <= best_progress)
      return;
    best_clearance = clearance;
    best_progress = progress;
    needed_gain = 0.0;  // among manoeuvres, equal clearance is decided by progress
    // waiting on the path is the tracker's command for now
    const bool on_path = m.wait_s > 0.0 && !m.straight;
    best = {m, on_path ? nominal_steer_rad : first, r.clearance, on_path};
  };
  if (previous && previous->wait_s >= 0.0 && previous->wait_s + previous->hold_s > 0.0) {
    consider(*previous);
    // the manoeuvre under way stays unless another one is clearly better
    if (!best.nominal || best.manoeuvre.wait_s >= 0.0) needed_gain = kClearanceGainM;
    // its turn-in as planned with the other holds, which must gain as much: the wait grid may
    // not hold the wait left, and a hold chosen at the approach can turn out too long at the exit
    // (hard trackdrive 7159 with GraphSLAM, lap 1: straight for 0.25 s more, then 2.5 s at full
    // lock, fell from 0.27 to -0.07 m at the exit in one tick; the grid's straight waits, 0.2
    // and 0.35 s, were too early and too late)
    if (previous->wait_s > 0.0)
      for (const double hold : p.hold_s)
        if (hold != previous->hold_s)
          consider({previous->wait_s, hold, previous->side, previous->straight});
  }
  // full lock towards the tight turn ahead, and towards the side the steering is on
  double tightest = 0.0;
  for (size_t i = 0; i < k.size(); ++i) {
    double d = s[i] - s_here;
    if (lap > 0.0 && d < 0.0) d += lap;
    if (d >= 0.0 && d <= speed * p.horizon_s + 1.0 && std::abs(k[i]) > std::abs(tightest))
      tightest = k[i];
  }
  std::vector<double> sides;
  if (tightest != 0.0) sides.push_back(tightest > 0.0 ? 1.0 : -1.0);
  const double steer_side = steer_now_rad > 0.0 ? 1.0 : -1.0;
  if (std::abs(steer_now_rad) > kOtherSideSteerShare * p.max_steer_rad &&
      (sides.empty() || sides.front() != steer_side))
    sides.push_back(steer_side);
  for (const double side : sides)
    for (const double wait : p.wait_s)
      for (const bool straight : {false, true}) {
        if (straight && wait <= 0.0) continue;
        // once the steering is well into a turn, holding it straight first would unwind it
        // mid-turn: re-chosen tick after tick (a wait looked as good as turning now to the
        // roll-outs while they turned in a step before the car, see RolloutCar::step), the
        // steering flipped between lock and straight and the car turned in late (generated hard
        // trackdrive 7177, lap 1)
        if (straight && side == steer_side &&
            std::abs(steer_now_rad) >= kCommittedSteerShare * p.max_steer_rad)
          continue;
        // a lock at full lock promised after following the path is not put off: re-chosen
        // tick after tick with the same wait, the lock never came while the tracker turned in
        // early and gently, and the car cut inside to the apex cone (hard trackdrive 7159 with
        // GraphSLAM, lap 1; hard autocross 7110)
        if (!straight && wait > 0.0 && previous && previous->wait_s > 0.0 && !previous->straight &&
            previous->side == side && wait > previous->wait_s + 1e-9)
          continue;
        for (const double hold : p.hold_s) consider({wait, hold, side, straight});
      }
  // nothing keeps clear (a cone seen late, a path through cones): the roll-outs know no better
  // than the tracker, so it steers
  if (best.clearance_m < 0.0 && !best.nominal)
    best = {{}, nominal_steer_rad, nominal.clearance, true};
  return best;
}

}  // namespace conesim::control
