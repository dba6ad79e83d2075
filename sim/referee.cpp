// The referee judges ground truth after every physics step. All geometry is prepared in the
// constructor (oriented gates, a grid of cones, boundary polygons banded by y, a grid of the
// centre line and cones for "left the track"), so that update() costs a few hundred
// instructions and never allocates. Decisions on gates, timeouts and off-course: referee.hpp.

#include "sim/referee.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>

#include "tracks/fsg_layouts.hpp"
#include "tracks/track_area.hpp"

namespace conesim::sim {

namespace {

using core::Pose2;
using core::Vec2;
using tracks::Track;

constexpr double kPi = std::numbers::pi;
/// A skidpad lap must turn the car at least this much in the expected direction, radians.
constexpr double kSkidpadMinLapTurnRad = 1.5 * kPi;
/// Radius of the skidpad driving circles (half the centre distance), metres.
constexpr double kSkidpadRadiusM = tracks::kSkidpadCentreDistanceM / 2.0;
/// Half width of skidpad's driving lane up to the cone lines: 9.125 - 7.475 = 1.65 m.
constexpr double kSkidpadLaneHalfWidthM = kSkidpadRadiusM - tracks::kSkidpadInnerConeRadiusM;
/// The skidpad exit lane ends this far past the timing line (stop line at 21 m, fssim), metres.
constexpr double kSkidpadExitLengthM = 25.0;
/// Fallback gate: at least this far ahead of the front wing of a car at the start pose, metres.
constexpr double kFallbackGateAheadM = 1.0;
/// Gates shorter than this (posts on top of each other) are ignored, metres.
constexpr double kMinGateLengthM = 0.1;
/// Fallback gate posts stand this far outside the farther of the nearest cones, metres.
constexpr double kFallbackGatePostOutsideM = 1.0;
/// Fallback gate half length when there are no cones to measure the width from, metres.
constexpr double kFallbackGateHalfLengthM = 3.0;
/// Cell size of the cone grid and of the "left the track" grid, metres.
constexpr double kConeCellM = 2.0;
constexpr double kNearCellM = 4.0;

// a segment or, with a == b, a point
struct Segment {
  Vec2 a;
  Vec2 b;
};

// a uniform grid listing, for each cell, the items that come within radius_m of the cell: a
// query returns every item within radius_m of the point (and some a little farther)
class ItemGrid {
 public:
  void build(const std::vector<Segment>& items, double radius_m, double cell_m) {
    cell_m_ = cell_m;
    starts_.clear();
    items_.clear();
    if (items.empty()) return;

    // bounds of the items, grown by the radius
    Vec2 lo = items.front().a, hi = items.front().a;
    for (const Segment& s : items) {
      lo = lo.cwiseMin(s.a).cwiseMin(s.b);
      hi = hi.cwiseMax(s.a).cwiseMax(s.b);
    }
    origin_ = lo - Vec2::Constant(radius_m + cell_m);
    nx_ = static_cast<int>(std::ceil((hi.x() - origin_.x() + radius_m + cell_m) / cell_m));
    ny_ = static_cast<int>(std::ceil((hi.y() - origin_.y() + radius_m + cell_m) / cell_m));

    // two passes over the cells each item touches: count, then fill (compressed rows)
    std::vector<int> counts(static_cast<size_t>(nx_) * ny_ + 1, 0);
    auto for_cells = [&](const Segment& s, auto&& visit) {
      const Vec2 a = s.a.cwiseMin(s.b) - Vec2::Constant(radius_m) - origin_;
      const Vec2 b = s.a.cwiseMax(s.b) + Vec2::Constant(radius_m) - origin_;
      const int x0 = std::max(0, static_cast<int>(a.x() / cell_m));
      const int y0 = std::max(0, static_cast<int>(a.y() / cell_m));
      const int x1 = std::min(nx_ - 1, static_cast<int>(b.x() / cell_m));
      const int y1 = std::min(ny_ - 1, static_cast<int>(b.y() / cell_m));
      for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) {
          // skip cells the item's radius does not reach (long diagonal segments)
          const Vec2 centre = origin_ + cell_m * Vec2(x + 0.5, y + 0.5);
          if (core::distance_to_segment(centre, s.a, s.b) > radius_m + cell_m * std::sqrt(0.5))
            continue;
          visit(static_cast<size_t>(y) * nx_ + x);
        }
    };
    for (const Segment& s : items) for_cells(s, [&](size_t c) { ++counts[c + 1]; });
    for (size_t c = 1; c < counts.size(); ++c) counts[c] += counts[c - 1];
    starts_ = counts;
    items_.resize(static_cast<size_t>(counts.back()));
    for (size_t i = 0; i < items.size(); ++i)
      for_cells(items[i], [&](size_t c) { items_[static_cast<size_t>(counts[c]++)] = int(i); });
  }

  // the items near p (empty outside the grid)
  std::span<const int> near(const Vec2& p) const {
    if (starts_.empty()) return {};
    const Vec2 q = (p - origin_) / cell_m_;
    if (q.x() < 0.0 || q.y() < 0.0 || q.x() >= nx_ || q.y() >= ny_) return {};
    const size_t c = static_cast<size_t>(static_cast<int>(q.y())) * nx_ + static_cast<int>(q.x());
    return {items_.data() + starts_[c], items_.data() + starts_[c + 1]};
  }

  bool empty() const { return items_.empty(); }

 private:
  Vec2 origin_ = Vec2::Zero();
  double cell_m_ = 1.0;
  int nx_ = 0;
  int ny_ = 0;
  std::vector<int> starts_;
  std::vector<int> items_;
};

// a time-keeping gate with its driving direction
struct GateLine {
  Vec2 left = Vec2::Zero();
  Vec2 right = Vec2::Zero();
  /// Unit normal pointing the way the car drives through.
  Vec2 forward = Vec2::UnitX();
  Vec2 mid() const { return 0.5 * (left + right); }
  /// The gate moved along its forward direction.
  GateLine shifted(double along_m) const {
    return {left + along_m * forward, right + along_m * forward, forward};
  }
};

// the gate from the track's posts: the normal of left -> right turned to agree with the hint
GateLine oriented_gate(const tracks::Gate& g, const Vec2& hint) {
  const Vec2 d = g.left - g.right;
  Vec2 n = d.norm() > 0.0 ? Vec2(d.y(), -d.x()).normalized() : hint;
  if (n.dot(hint) < 0.0) n = -n;
  return {g.left, g.right, n};
}

// which way the track runs near p: the centre line's direction there, else the start heading
Vec2 direction_near(const Track& track, const Vec2& p) {
  const std::vector<Vec2>& line = track.centre_line;
  if (line.size() < 2) return track.start.heading();
  size_t best = 0;
  for (size_t i = 1; i < line.size(); ++i)
    if ((line[i] - p).squaredNorm() < (line[best] - p).squaredNorm()) best = i;
  const size_t n = line.size();
  const size_t next = track.closed ? (best + 1) % n : std::min(best + 1, n - 1);
  const size_t prev = track.closed ? (best + n - 1) % n : (best > 0 ? best - 1 : 0);
  const Vec2 d = line[next] - line[prev];
  return d.norm() > 0.0 ? Vec2(d.normalized()) : track.start.heading();
}

// a gate across the track at the centre line's point nearest the start that lies ahead of the
// front wing of a car whose rear axle is at the start pose (front_m ahead), posts just outside
// the nearest cones; skidpad: at the timing line of the FSG layout
GateLine fallback_gate(const Track& track, core::EventType event, double front_m) {
  const Vec2 start = track.start.position();
  const Vec2 heading = track.start.heading();
  if (event == core::EventType::kSkidpad || track.centre_line.empty()) {
    const double ahead = event == core::EventType::kSkidpad ? tracks::kSkidpadStartToTimingLineM
                                                            : front_m + kFallbackGateAheadM;
    const Vec2 mid = start + ahead * heading;
    const Vec2 side(-heading.y(), heading.x());
    return {mid + kFallbackGateHalfLengthM * side, mid - kFallbackGateHalfLengthM * side, heading};
  }

  // nearest centre-line point ahead of the start (any point when none is ahead)
  const std::vector<Vec2>& line = track.centre_line;
  size_t best = 0;
  double best_d2 = std::numeric_limits<double>::infinity();
  for (int pass = 0; pass < 2 && !std::isfinite(best_d2); ++pass)
    for (size_t i = 0; i < line.size(); ++i) {
      if (pass == 0 && (line[i] - start).dot(heading) < front_m + kFallbackGateAheadM) continue;
      const double d2 = (line[i] - start).squaredNorm();
      if (d2 < best_d2) {
        best_d2 = d2;
        best = i;
      }
    }
  const Vec2 mid = line[best];
  const Vec2 forward = direction_near(track, mid);
  const Vec2 side(-forward.y(), forward.x());

  // half length: the farther of the nearest left and right lane cones, plus the post offset
  double half = kFallbackGateHalfLengthM;
  double nearest_left = std::numeric_limits<double>::infinity(), nearest_right = nearest_left;
  for (int id : track.left_lane)
    nearest_left = std::min(nearest_left, (track.cone(id).position - mid).norm());
  for (int id : track.right_lane)
    nearest_right = std::min(nearest_right, (track.cone(id).position - mid).norm());
  if (std::isfinite(nearest_left) && std::isfinite(nearest_right))
    half = std::max(nearest_left, nearest_right) + kFallbackGatePostOutsideM;
  return {mid + half * side, mid - half * side, forward};
}

// the skidpad's driving area, built from the timing gate: two circles of radius 9.125 m whose
// centres lie 9.125 m either side of the timing line's centre, and the straight entry/exit lane
struct SkidpadArea {
  Vec2 mid = Vec2::Zero();
  Vec2 forward = Vec2::UnitX();
  Vec2 right_centre = Vec2::Zero();
  Vec2 left_centre = Vec2::Zero();
  Vec2 lane_begin = Vec2::Zero();
  Vec2 lane_end = Vec2::Zero();

  SkidpadArea() = default;
  SkidpadArea(const GateLine& gate, const Vec2& start) : mid(gate.mid()), forward(gate.forward) {
    const Vec2 left(-forward.y(), forward.x());
    right_centre = mid - kSkidpadRadiusM * left;
    left_centre = mid + kSkidpadRadiusM * left;
    const double start_along = std::min((start - mid).dot(forward), -kSkidpadRadiusM);
    lane_begin = mid + (start_along - 5.0) * forward;
    lane_end = mid + kSkidpadExitLengthM * forward;
  }

  // distance from p to the driving path (the circles and the lane's centre)
  double distance_to_path(const Vec2& p) const {
    const double to_right = std::abs((p - right_centre).norm() - kSkidpadRadiusM);
    const double to_left = std::abs((p - left_centre).norm() - kSkidpadRadiusM);
    const double to_lane = core::distance_to_segment(p, lane_begin, lane_end);
    return std::min({to_right, to_left, to_lane});
  }

  // distance of p past the timing line along the driving direction
  double along(const Vec2& p) const { return (p - mid).dot(forward); }
};

// the car's rear-axle frame with the heading's cosine and sine worked out once per step
struct CarFrame {
  Vec2 origin;
  Vec2 axis;  // unit vector along the heading

  explicit CarFrame(const Pose2& pose)
      : origin(pose.x, pose.y), axis(std::cos(pose.yaw), std::sin(pose.yaw)) {}

  // the point along_m ahead of the rear axle on the car's centre line
  Vec2 ahead(double along_m) const { return origin + along_m * axis; }

  // a track-frame point in the car frame (x forward, y left)
  Vec2 to_local(const Vec2& p) const {
    const Vec2 d = p - origin;
    return {d.dot(axis), core::cross(axis, d)};
  }
};

// how the track's boundaries are judged
enum class Boundary { kNone, kArea, kSkidpad };

// one cone as the referee sees it
struct RefCone {
  int id = 0;
  uint64_t file_id = 0;
  core::ConeClass cls = core::ConeClass::kUnknown;
  Vec2 position = Vec2::Zero();
  double radius_m = 0.0;
};

}  // namespace

// what the referee knows of the run: fixed geometry, then the state that changes every step
struct Referee::Impl {
  // fixed for the run
  core::EventType event;
  RefereeParams params;
  double front_m = 0.0;       // front wing ahead of the rear axle
  double rear_m = 0.0;        // rear end behind the rear axle (positive)
  double half_width_m = 0.0;  // half the car's width
  double cone_penalty_s = 0.0;
  int laps_required = 1;
  std::vector<RefCone> cones;
  std::vector<std::pair<int, int>> index_of_id;  // (id, index in cones), sorted by id
  ItemGrid cone_grid;
  std::vector<GateLine> gates;        // [0] starts the timing
  std::optional<size_t> finish_gate;  // acceleration, open courses: the gate that ends the lap
  Boundary boundary = Boundary::kNone;
  tracks::TrackArea area;
  SkidpadArea skidpad;
  std::vector<Segment> near_items;  // centre-line segments and cones for "left the track"
  ItemGrid near_grid;
  mutable int last_near_item = -1;   // the item found near the car last step, tried first
  double braking_end_along_m = 0.0;  // acceleration: end of the braking zone past gate 0

  // what changes
  RefereeResult result;
  bool finished = false;
  std::vector<char> knocked;
  bool have_previous = false;
  core::TimeUs run_start_us = 0;
  core::TimeUs previous_us = 0;
  Vec2 previous_front = Vec2::Zero();
  double previous_yaw = 0.0;
  double yaw_travel_rad = 0.0;  // heading turned since the run start, unwrapped
  std::vector<int> gate_debt;   // backward crossings not yet cancelled, per gate
  std::optional<double> timing_start_s;
  double last_crossing_s = 0.0;
  double yaw_at_last_crossing_rad = 0.0;
  std::optional<double> laps_done_s;  // when the event's last timed crossing happened
  bool off_course_now = false;
  std::optional<size_t> open_off_course;  // the event of the excursion going on, if any
  double now_s = 0.0;                     // time and true pose of the step being judged
  Pose2 now_pose;
  std::optional<core::TimeUs> slow_since_us;     // below stuck_speed_mps since
  std::optional<core::TimeUs> stopped_since_us;  // below stopped_speed_mps since

  Impl(const Track& track, core::EventType e, const vehicle_models::VehicleParams& vehicle,
       const RefereeParams& p);

  void judge_gates(core::TimeUs t, const Vec2& front);
  void on_forward_crossing(size_t gate, double time_s);
  void judge_cones(const CarFrame& car);
  void judge_off_course(const VehicleTruth& truth, const CarFrame& car);
  RefereeEvent event_now(RefereeEvent::Kind kind, std::string reason, double penalty_s) const;
  void close_off_course();
  bool wheels_off_course(const VehicleTruth& truth) const;
  bool left_the_track(const Vec2& p) const;
  void judge_finish_and_stops(core::TimeUs t, const VehicleTruth& truth, const CarFrame& car);
  void judge_timeouts(core::TimeUs t);
  void dnf(core::TimeUs t, const std::string& reason);
  void complete(core::TimeUs t);
  void update_times(double now_s);
};

Referee::Impl::Impl(const Track& track, core::EventType e,
                    const vehicle_models::VehicleParams& vehicle, const RefereeParams& p)
    : event(e), params(p) {
  using core::EventType;

  // the car's footprint relative to the rear axle
  front_m = vehicle.front_overhang_from_rear_axle_m;
  rear_m = vehicle.length_m - vehicle.front_overhang_from_rear_axle_m;
  half_width_m = 0.5 * vehicle.width_m;
  cone_penalty_s = e == EventType::kSkidpad ? p.cone_penalty_skidpad_s : p.cone_penalty_s;
  laps_required = e == EventType::kSkidpad      ? 4
                  : e == EventType::kTrackdrive ? std::max(1, p.trackdrive_laps)
                                                : 1;

  // cones: base circles, an id index and a grid around the car's footprint centre
  std::vector<Segment> cone_points;
  double max_radius = 0.0;
  for (const tracks::Cone& c : track.cones) {
    const double r = 0.5 * core::cone_size(c.cls).base_m;
    cones.push_back({c.id, track.file_id(c.id), c.cls, c.position, r});
    cone_points.push_back({c.position, c.position});
    index_of_id.emplace_back(c.id, static_cast<int>(cones.size()) - 1);
    max_radius = std::max(max_radius, r);
  }
  std::sort(index_of_id.begin(), index_of_id.end());
  knocked.assign(cones.size(), 0);
  const double footprint_half_diagonal = std::hypot(0.5 * vehicle.length_m, half_width_m);
  cone_grid.build(cone_points, footprint_half_diagonal + max_radius, kConeCellM);

  // gates: the track's, oriented along the track, or a fallback across it ahead of the start
  // (along the centre line where it runs once through a gate: skidpad's crosses its own)
  for (const tracks::Gate& g : track.timing_gates) {
    if ((g.left - g.right).norm() < kMinGateLengthM) continue;
    const Vec2 hint = e != EventType::kSkidpad && track.centre_line.size() >= 2
                          ? direction_near(track, 0.5 * (g.left + g.right))
                          : track.start.heading();
    gates.push_back(oriented_gate(g, hint));
  }
  if (gates.empty()) gates.push_back(fallback_gate(track, e, front_m));
  if (e == EventType::kAcceleration && gates.size() < 2)
    gates.push_back(gates.front().shifted(tracks::kAccelerationLengthM));

  // an open course driven as autocross (a point-to-point layout) finishes across the ends of
  // its lanes, unless the layout has a gate of its own there; one pass is its lap
  const bool open_course =
      !track.closed && (e == EventType::kAutocross || e == EventType::kTrackdrive);
  if (open_course && gates.size() < 2 && !track.left_lane.empty() && !track.right_lane.empty()) {
    const Vec2 left_end = track.cone(track.left_lane.back()).position;
    const Vec2 right_end = track.cone(track.right_lane.back()).position;
    const Vec2 out = (left_end - right_end).normalized();
    const tracks::Gate end{left_end + kFallbackGatePostOutsideM * out,
                           right_end - kFallbackGatePostOutsideM * out};
    gates.push_back(oriented_gate(end, direction_near(track, 0.5 * (left_end + right_end))));
  }
  if (e == EventType::kAcceleration) finish_gate = 1;
  if (open_course && gates.size() >= 2) {
    finish_gate = gates.size() - 1;
    laps_required = 1;
  }
  gate_debt.assign(gates.size(), 0);

  // acceleration: the braking zone ends at the farthest cone past the finish
  if (e == EventType::kAcceleration) {
    const double finish_along = (gates[1].mid() - gates[0].mid()).dot(gates[0].forward);
    braking_end_along_m = finish_along + tracks::kAccelerationBrakingZoneM;
    double farthest = -std::numeric_limits<double>::infinity();
    for (const RefCone& c : cones)
      farthest = std::max(farthest, (c.position - gates[0].mid()).dot(gates[0].forward));
    if (farthest > finish_along + 1.0) braking_end_along_m = farthest;
  }

  // boundaries for off-course
  if (e == EventType::kSkidpad) {
    boundary = Boundary::kSkidpad;
    skidpad = SkidpadArea(gates.front(), track.start.position());
  } else {
    area = tracks::TrackArea::of(track);
    if (!area.empty()) boundary = Boundary::kArea;
  }

  // "left the track": the centre line's segments and every cone
  const std::vector<Vec2>& line = track.centre_line;
  if (e != EventType::kSkidpad) {
    for (size_t i = 0; i + 1 < line.size(); ++i) near_items.push_back({line[i], line[i + 1]});
    if (track.closed && line.size() > 2) near_items.push_back({line.back(), line.front()});
    near_items.insert(near_items.end(), cone_points.begin(), cone_points.end());
    near_grid.build(near_items, p.left_track_distance_m, kNearCellM);
  }
}

void Referee::Impl::judge_gates(core::TimeUs t, const Vec2& front) {
  const double t0 = core::to_seconds(previous_us), t1 = core::to_seconds(t);
  for (size_t g = 0; g < gates.size(); ++g) {
    // which side of the gate line the front wing was and is on
    const GateLine& gate = gates[g];
    const double side0 = gate.forward.dot(previous_front - gate.right);
    const double side1 = gate.forward.dot(front - gate.right);
    const bool forward = side0 < 0.0 && side1 >= 0.0;
    const bool backward = side0 >= 0.0 && side1 < 0.0;
    if (!forward && !backward) continue;

    // the crossing point must lie between the posts
    const double f = side0 / (side0 - side1);
    const Vec2 q = previous_front + f * (front - previous_front);
    const Vec2 along = gate.left - gate.right;
    const double u = (q - gate.right).dot(along) / along.squaredNorm();
    if (u < 0.0 || u > 1.0) continue;

    // backwards crossings are owed and cancel the next forward one
    if (backward) {
      ++gate_debt[g];
      continue;
    }
    if (gate_debt[g] > 0) {
      --gate_debt[g];
      continue;
    }
    on_forward_crossing(g, t0 + f * (t1 - t0));
    if (finished) return;
  }
}

void Referee::Impl::on_forward_crossing(size_t gate, double time_s) {
  using core::EventType;

  // the first crossing of the first gate starts the clock
  if (gate == 0 && !timing_start_s) {
    timing_start_s = time_s;
    last_crossing_s = time_s;
    yaw_at_last_crossing_rad = yaw_travel_rad;
    return;
  }
  if (!timing_start_s || result.laps >= laps_required) return;

  // acceleration and open courses: the finish gate ends the run
  if (finish_gate) {
    if (gate != *finish_gate) return;
  } else if (gate != 0) {
    return;  // sector gates and a skidpad exit gate do not count laps
  }

  // skidpad: two clockwise laps, then two counter-clockwise ones
  if (event == EventType::kSkidpad) {
    const double turned = yaw_travel_rad - yaw_at_last_crossing_rad;
    const double expected_sign = result.laps < 2 ? -1.0 : 1.0;
    if (turned * expected_sign < kSkidpadMinLapTurnRad) {
      dnf(core::from_seconds(time_s), "wrong direction");
      return;
    }
  }

  // a lap
  result.lap_times_s.push_back(time_s - last_crossing_s);
  ++result.laps;
  last_crossing_s = time_s;
  yaw_at_last_crossing_rad = yaw_travel_rad;
  if (result.laps >= laps_required) laps_done_s = time_s;
}

void Referee::Impl::judge_cones(const CarFrame& car) {
  // the footprint in the car frame: x from -rear_m to front_m, y within +-half_width_m
  const Vec2 centre = car.ahead(0.5 * (front_m - rear_m));
  for (int i : cone_grid.near(centre)) {
    const size_t k = static_cast<size_t>(i);
    if (knocked[k]) continue;
    const Vec2 local = car.to_local(cones[k].position);
    const double dx = std::max({-rear_m - local.x(), local.x() - front_m, 0.0});
    const double dy = std::max(std::abs(local.y()) - half_width_m, 0.0);
    if (dx * dx + dy * dy > cones[k].radius_m * cones[k].radius_m) continue;
    knocked[k] = 1;
    result.cones_hit.push_back(cones[k].id);
    RefereeEvent e = event_now(RefereeEvent::Kind::kConeHit,
                               "hit " + std::string(core::to_string(cones[k].cls)) + " cone " +
                                   std::to_string(cones[k].file_id) + " at " +
                                   core::format_place(cones[k].position),
                               cone_penalty_s);
    e.cone_id = cones[k].id;
    e.cone_file_id = cones[k].file_id;
    e.cone_class = cones[k].cls;
    e.cone_position = cones[k].position;
    result.events.push_back(std::move(e));
  }
}

bool Referee::Impl::wheels_off_course(const VehicleTruth& truth) const {
  // off course only when every wheel is outside the boundaries
  auto on_track = [this](const Vec2& w) {
    switch (boundary) {
      case Boundary::kArea:
        return area.contains(w);
      case Boundary::kSkidpad:
        return skidpad.distance_to_path(w) <= kSkidpadLaneHalfWidthM;
      case Boundary::kNone:
        break;
    }
    return true;
  };
  return std::none_of(truth.wheel_positions.begin(), truth.wheel_positions.end(), on_track);
}

bool Referee::Impl::left_the_track(const Vec2& p) const {
  // skidpad: from the analytic path; elsewhere: any centre-line segment or cone near enough
  const double limit = params.left_track_distance_m;
  if (event == core::EventType::kSkidpad) return skidpad.distance_to_path(p) > limit;
  if (near_grid.empty()) return false;
  auto near_enough = [&](int i) {
    const Segment& s = near_items[static_cast<size_t>(i)];
    return core::distance_to_segment(p, s.a, s.b) <= limit;
  };
  if (last_near_item >= 0 && near_enough(last_near_item)) return false;
  for (int i : near_grid.near(p)) {
    if (!near_enough(i)) continue;
    last_near_item = i;
    return false;
  }
  return true;
}

void Referee::Impl::judge_finish_and_stops(core::TimeUs t, const VehicleTruth& truth,
                                           const CarFrame& car) {
  using core::EventType;

  // how long the car has been slow and stopped
  const double speed = std::hypot(truth.vx_mps, truth.vy_mps);
  auto track_below = [&](double limit_mps, std::optional<core::TimeUs>& since_us) {
    if (speed >= limit_mps) {
      since_us.reset();
    } else if (!since_us) {
      since_us = t;
    }
  };
  track_below(params.stuck_speed_mps, slow_since_us);
  track_below(params.stopped_speed_mps, stopped_since_us);
  const bool stopped =
      stopped_since_us && core::to_seconds(t - *stopped_since_us) >= params.stopped_time_s;
  const bool stuck = slow_since_us && core::to_seconds(t - *slow_since_us) >= params.stuck_time_s;

  // before the last lap: too slow for too long is a DNF
  if (!laps_done_s) {
    if (stuck) dnf(t, result.laps >= 1 ? "stopped early" : "stuck");
    return;
  }

  // after it: a stop completes the event, where the event allows it
  bool stop_allowed = true;
  if (event == EventType::kSkidpad) {
    const Vec2 rear_end = car.ahead(-rear_m);
    stop_allowed = skidpad.along(rear_end) > tracks::kSkidpadOuterConeRadiusM;
  }
  if (stopped && stop_allowed) {
    complete(t);
  } else if (stuck) {
    dnf(t, "stopped early");
  } else if (core::to_seconds(t) - *laps_done_s > params.stop_window_s) {
    dnf(t, "did not stop");
  }
}

void Referee::Impl::judge_timeouts(core::TimeUs t) {
  using core::EventType;
  if (laps_done_s) return;

  // from the first gate crossing, or from the run start while the car has not reached it
  const double since_s =
      core::to_seconds(t) - (timing_start_s ? *timing_start_s : core::to_seconds(run_start_us));
  double limit_s = params.timeout_autocross_s;
  switch (event) {
    case EventType::kAcceleration:
      limit_s = params.timeout_acceleration_s;
      break;
    case EventType::kSkidpad:
      limit_s = params.timeout_skidpad_s;
      break;
    case EventType::kAutocross:
      limit_s = params.timeout_autocross_s;
      break;
    case EventType::kTrackdrive:
      if (result.laps == 0 && since_s > params.timeout_trackdrive_first_lap_s) {
        dnf(t, "timeout (first lap)");
        return;
      }
      limit_s = params.timeout_trackdrive_total_s;
      break;
  }
  if (since_s > limit_s) dnf(t, "timeout");
}

void Referee::Impl::dnf(core::TimeUs t, const std::string& reason) {
  if (finished) return;
  finished = true;
  result.completed = false;
  // the reason says where: the middle of the car's footprint
  const CarFrame car(now_pose);
  result.dnf_reason = reason + " at " + core::format_place(car.ahead(0.5 * (front_m - rear_m)));
  close_off_course();
  result.events.push_back(event_now(RefereeEvent::Kind::kDnf, result.dnf_reason, 0.0));
  update_times(core::to_seconds(t));
}

void Referee::Impl::complete(core::TimeUs t) {
  finished = true;
  result.completed = true;
  close_off_course();
  update_times(core::to_seconds(t));
}

RefereeEvent Referee::Impl::event_now(RefereeEvent::Kind kind, std::string reason,
                                      double penalty_s) const {
  RefereeEvent e;
  e.kind = kind;
  e.t_s = now_s;
  e.lap = timing_start_s ? std::min(result.laps + 1, laps_required) : 0;
  e.pose = now_pose;
  e.reason = std::move(reason);
  e.penalty_s = penalty_s;
  return e;
}

void Referee::Impl::judge_off_course(const VehicleTruth& truth, const CarFrame& car) {
  // one penalty per excursion: an event when all four wheels go out, its length when one is back
  const bool off = wheels_off_course(truth);
  if (off && !off_course_now) {
    ++result.off_course;
    const Vec2 centre = car.ahead(0.5 * (front_m - rear_m));
    std::string where = "all four wheels off the track at " + core::format_place(centre);
    if (const auto b = area.nearest_boundary(centre)) {
      char buf[96];
      std::snprintf(buf, sizeof buf, ", %.1f m from the %s boundary", b->distance_m,
                    b->left ? "left (blue)" : "right (yellow)");
      where += buf;
    }
    RefereeEvent e = event_now(RefereeEvent::Kind::kOffCourse, where, params.off_course_penalty_s);
    e.wheels = truth.wheel_positions;
    open_off_course = result.events.size();
    result.events.push_back(std::move(e));
  } else if (!off && off_course_now) {
    close_off_course();
  }
  off_course_now = off;
}

void Referee::Impl::close_off_course() {
  if (!open_off_course) return;
  RefereeEvent& e = result.events[*open_off_course];
  e.duration_s = now_s - e.t_s;
  open_off_course.reset();
}

void Referee::Impl::update_times(double now_s) {
  using core::EventType;

  // raw time: the event's timed laps once they are done, else the clock since the first gate
  const std::vector<double>& laps = result.lap_times_s;
  if (laps_done_s && event == EventType::kSkidpad && laps.size() >= 4) {
    result.raw_time_s = 0.5 * (laps[1] + laps[3]);
  } else if (laps_done_s && timing_start_s) {
    result.raw_time_s = *laps_done_s - *timing_start_s;
  } else {
    result.raw_time_s = timing_start_s ? std::max(0.0, now_s - *timing_start_s) : 0.0;
  }

  // penalties on top
  result.penalty_s = cone_penalty_s * static_cast<double>(result.cones_hit.size()) +
                     params.off_course_penalty_s * result.off_course;
  result.final_time_s = result.raw_time_s + result.penalty_s;
}

std::string RefereeParams::validate() const {
  // every penalty, time and distance must be usable, and at least one lap driven
  const std::pair<const char*, double> non_negative[] = {
      {"cone_penalty_s", cone_penalty_s},
      {"cone_penalty_skidpad_s", cone_penalty_skidpad_s},
      {"off_course_penalty_s", off_course_penalty_s},
      {"stuck_speed_mps", stuck_speed_mps},
      {"stopped_speed_mps", stopped_speed_mps},
      {"stopped_time_s", stopped_time_s}};
  for (const auto& [key, value] : non_negative)
    if (!(value >= 0.0)) return std::string(key) + ": expected a number >= 0";
  const std::pair<const char*, double> positive[] = {
      {"timeout_acceleration_s", timeout_acceleration_s},
      {"timeout_skidpad_s", timeout_skidpad_s},
      {"timeout_autocross_s", timeout_autocross_s},
      {"timeout_trackdrive_first_lap_s", timeout_trackdrive_first_lap_s},
      {"timeout_trackdrive_total_s", timeout_trackdrive_total_s},
      {"stuck_time_s", stuck_time_s},
      {"left_track_distance_m", left_track_distance_m},
      {"stop_window_s", stop_window_s}};
  for (const auto& [key, value] : positive)
    if (!(value > 0.0)) return std::string(key) + ": expected a number > 0";
  if (trackdrive_laps < 1) return "trackdrive_laps: expected at least 1";
  return {};
}

Referee::Referee(const tracks::Track& track, core::EventType event,
                 const vehicle_models::VehicleParams& vehicle, const RefereeParams& params) {
  // bad parameters are a fatal configuration error
  if (const std::string error = params.validate(); !error.empty())
    throw std::invalid_argument("referee: " + error);
  if (const std::string error = vehicle.validate(); !error.empty())
    throw std::invalid_argument("referee: vehicle: " + error);
  impl_ = std::make_unique<Impl>(track, event, vehicle, params);
}

Referee::~Referee() = default;

const char* to_string(RefereeEvent::Kind kind) {
  switch (kind) {
    case RefereeEvent::Kind::kConeHit:
      return "cone_hit";
    case RefereeEvent::Kind::kOffCourse:
      return "off_course";
    case RefereeEvent::Kind::kDnf:
      return "dnf";
  }
  return "unknown";
}

void Referee::update(core::TimeUs t, const VehicleTruth& truth) {
  Impl& s = *impl_;
  if (s.finished) return;
  const Pose2& pose = truth.pose;
  const CarFrame car(pose);
  const Vec2 front = car.ahead(s.front_m);

  // the first call marks the run start; later ones judge the motion since the previous one
  s.now_s = core::to_seconds(t);
  s.now_pose = pose;
  if (!s.have_previous) {
    s.have_previous = true;
    s.run_start_us = t;
  } else {
    s.yaw_travel_rad += core::normalize_angle(pose.yaw - s.previous_yaw);
    s.judge_gates(t, front);
  }
  s.previous_us = t;
  s.previous_front = front;
  s.previous_yaw = pose.yaw;
  if (s.finished) return;

  // cones under the footprint are knocked over
  s.judge_cones(car);

  // off course: one penalty per excursion, judged while the car is timed
  if (s.timing_start_s) s.judge_off_course(truth, car);

  // far from the track, or past the end of the braking zone
  const Vec2 centre = car.ahead(0.5 * (s.front_m - s.rear_m));
  const bool overran = s.event == core::EventType::kAcceleration && s.timing_start_s &&
                       (front - s.gates[0].mid()).dot(s.gates[0].forward) > s.braking_end_along_m;
  if (s.left_the_track(centre)) {
    s.dnf(t, "left the track");
  } else if (overran) {
    s.dnf(t, "overran braking zone");
  }

  // finish rules, stops and time limits
  if (!s.finished) s.judge_finish_and_stops(t, truth, car);
  if (!s.finished) s.judge_timeouts(t);
  if (!s.finished) s.update_times(core::to_seconds(t));
}

bool Referee::finished() const {
  return impl_->finished;
}

const RefereeResult& Referee::result() const {
  return impl_->result;
}

bool Referee::is_knocked(int cone_id) const {
  const auto& index = impl_->index_of_id;
  const auto it = std::lower_bound(index.begin(), index.end(), std::pair(cone_id, -1));
  return it != index.end() && it->first == cone_id &&
         impl_->knocked[static_cast<size_t>(it->second)] != 0;
}

bool Referee::all_wheels_off(const VehicleTruth& truth) const {
  return impl_->wheels_off_course(truth);
}

int Referee::laps() const {
  return impl_->result.laps;
}

}  // namespace conesim::sim
