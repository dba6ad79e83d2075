#include "laptime/lap_time.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "tracks/fsg_layouts.hpp"
#include "tracks/rules.hpp"

namespace conesim::laptime {

namespace {

using tracks::EventType;
using tracks::Track;

// a small cone's base radius (228 mm base), metres
constexpr double kConeBaseRadiusM = 0.114;

// where timing starts: the middle of the first gate, else the start pose
Vec2 timing_point(const Track& track) {
  if (!track.timing_gates.empty())
    return 0.5 * (track.timing_gates.front().left + track.timing_gates.front().right);
  return track.start.position();
}

// index of the point of a line nearest p
size_t nearest_index(const std::vector<Vec2>& pts, const Vec2& p) {
  size_t best = 0;
  for (size_t i = 1; i < pts.size(); ++i)
    if ((pts[i] - p).squaredNorm() < (pts[best] - p).squaredNorm()) best = i;
  return best;
}

// curvature at arc length s of a line (linear between its points, wrapping on a loop)
double curvature_at(const RacingLine& line, double s) {
  const size_t n = line.s_m.size();
  if (line.closed) {
    s = std::fmod(s, line.length_m);
    if (s < 0.0) s += line.length_m;
  }
  const size_t i =
      static_cast<size_t>(std::upper_bound(line.s_m.begin(), line.s_m.end(), s) - line.s_m.begin());
  if (i == 0) return line.curvature.front();
  if (i >= n && !line.closed) return line.curvature.back();
  const double s1 = i < n ? line.s_m[i] : line.length_m;
  const double k1 = line.curvature[i % n];
  const double f = (s - line.s_m[i - 1]) / std::max(1e-12, s1 - line.s_m[i - 1]);
  return line.curvature[i - 1] + f * (k1 - line.curvature[i - 1]);
}

// the point at arc length s of a line
Vec2 point_at(const RacingLine& line, double s) {
  const size_t n = line.points.size();
  if (line.closed) {
    s = std::fmod(s, line.length_m);
    if (s < 0.0) s += line.length_m;
  }
  const size_t i =
      static_cast<size_t>(std::upper_bound(line.s_m.begin(), line.s_m.end(), s) - line.s_m.begin());
  if (i == 0) return line.points.front();
  if (i >= n && !line.closed) return line.points.back();
  const double s1 = i < n ? line.s_m[i] : line.length_m;
  const double f = (s - line.s_m[i - 1]) / std::max(1e-12, s1 - line.s_m[i - 1]);
  return line.points[i - 1] + f * (line.points[i % n] - line.points[i - 1]);
}

// fills the figures of a bound from its speed profile
void summarise(LapTimeBound& b) {
  b.usable = !b.speed_mps.empty();
  if (!b.usable) return;
  b.top_speed_mps = *std::max_element(b.speed_mps.begin(), b.speed_mps.end());
  b.min_speed_mps = *std::min_element(b.speed_mps.begin(), b.speed_mps.end());
}

// trackdrive and autocross: the minimum-curvature lap from the timing line, flying or from
// standstill at the start pose
LapTimeBound circuit_bound(const Track& track, const PerformanceEnvelope& envelope,
                           const RacingLineParams& line_params, double step_m, bool standing) {
  LapTimeBound b;
  const RacingLine line = minimum_curvature_line(track, line_params);
  if (line.points.size() < 10) {
    b.message = "the layout has no centre line to drive";
    return b;
  }
  const double lap_m = line.length_m;
  const double s_gate = line.s_m[nearest_index(line.points, timing_point(track))];

  // the profile's points every step_m from the timing line (standing: from the start pose)
  const double run_up_m =
      standing ? std::min((timing_point(track) - track.start.position()).norm(), 0.5 * lap_m) : 0.0;
  const int per_lap = std::max(3, static_cast<int>(std::round(lap_m / step_m)));
  const double ds = lap_m / per_lap;
  const int before = static_cast<int>(std::ceil(run_up_m / ds));
  std::vector<double> s, kappa;
  for (int j = -before; j < (standing ? per_lap + 1 : per_lap); ++j) {
    s.push_back(j * ds);
    kappa.push_back(curvature_at(line, s_gate + j * ds));
  }
  if (standing) {
    for (double& v : s) v += before * ds;  // the trace starts at zero
    const SpeedTrace t = standing_start(s, kappa, envelope);
    const double t0 = t.time_s[before];
    b.lap_time_s = t.time_s.back() - t0;
    for (int j = before; j < before + per_lap; ++j) {
      b.s_m.push_back(s[j] - before * ds);
      b.speed_mps.push_back(t.speed_mps[j]);
    }
  } else {
    const SpeedTrace t = flying_lap(s, kappa, lap_m, envelope);
    b.lap_time_s = t.total_time_s;
    b.s_m = s;
    b.speed_mps = t.speed_mps;
  }
  b.line_length_m = lap_m;
  for (double si : b.s_m) b.line.push_back(point_at(line, s_gate + si));
  summarise(b);
  return b;
}

// acceleration: the centre line from standstill with the front wing at the start pose, timed
// from the first gate to the last (75 m on when there is one gate or none)
LapTimeBound acceleration_bound(const Track& track, const PerformanceEnvelope& envelope,
                                double step_m) {
  LapTimeBound b;
  const RacingLine line = make_line(track.centre_line, false, step_m);
  if (line.points.size() < 3) {
    b.message = "the layout has no centre line to drive";
    return b;
  }
  const double s_start = line.s_m[nearest_index(line.points, track.start.position())];
  const double s0 = line.s_m[nearest_index(line.points, timing_point(track))];
  double s1 = s0 + tracks::kAccelerationLengthM;
  if (track.timing_gates.size() >= 2) {
    const tracks::Gate& g = track.timing_gates.back();
    s1 = line.s_m[nearest_index(line.points, 0.5 * (g.left + g.right))];
  }
  if (!(s1 > s0 && s0 >= s_start)) {
    b.message = "the timing gates are not ahead of the start pose along the line";
    return b;
  }
  std::vector<double> s, kappa;
  for (size_t i = 0; i < line.s_m.size(); ++i) {
    if (line.s_m[i] < s_start) continue;
    s.push_back(line.s_m[i] - s_start);
    kappa.push_back(line.curvature[i]);
  }
  const SpeedTrace t = standing_start(s, kappa, envelope);
  b.lap_time_s = t.time_at(s1 - s_start) - t.time_at(s0 - s_start);
  b.line_length_m = s1 - s0;
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] + s_start < s0 || s[i] + s_start > s1) continue;
    b.s_m.push_back(s[i] + s_start - s0);
    b.speed_mps.push_back(t.speed_mps[i]);
    b.line.push_back(point_at(line, s[i] + s_start));
  }
  summarise(b);
  return b;
}

// skidpad: one lap of the tightest circle inside the inner ring at the cornering limit (the
// lap time grows with the radius below about 50 m, downforce included)
LapTimeBound skidpad_bound(const Track& track, const PerformanceEnvelope& envelope,
                           double clearance_m, double step_m) {
  LapTimeBound b;
  const std::vector<tracks::SkidpadCircleFit> fits = tracks::fit_skidpad_circles(track);
  double inner = 0.0;
  int rings = 0;
  for (const auto& f : fits) {
    if (f.inner_cones == 0) continue;
    inner += f.inner_radius_m;
    ++rings;
  }
  if (rings == 0) {
    b.message = "no skidpad circle of cones found";
    return b;
  }
  const double radius = inner / rings + clearance_m;
  const double v = cornering_speed_mps(envelope, 1.0 / radius);
  b.line_length_m = 2.0 * std::numbers::pi * radius;
  b.lap_time_s = b.line_length_m / v;
  const int points = std::max(8, static_cast<int>(std::round(b.line_length_m / step_m)));
  for (int i = 0; i < points; ++i) {
    const double phi = 2.0 * std::numbers::pi * i / points;
    b.s_m.push_back(b.line_length_m * i / points);
    b.speed_mps.push_back(v);
    b.line.push_back(fits.front().centre + radius * Vec2(std::cos(phi), std::sin(phi)));
  }
  summarise(b);
  return b;
}

}  // namespace

bool LapTimeOptions::is_valid(std::string* error) const {
  std::string e;
  if (!(grip_fraction > 0.0 && grip_fraction <= 2.0)) e = "grip_fraction must be in (0, 2]";
  if (!(step_m > 0.01 && step_m <= 2.0)) e = "step_m must be in (0.01, 2] m";
  if (clearance_m && !(*clearance_m >= 0.0)) e = "clearance_m must be >= 0";
  std::string line_error;
  if (e.empty() && !line.is_valid(&line_error)) e = "line: " + line_error;
  if (error) *error = e;
  return e.empty();
}

LapTimeBound lap_time_bound(const Track& track, const vehicle_models::VehicleParams& vehicle,
                            const LapTimeOptions& options) {
  LapTimeBound b;
  if (std::string error; !options.is_valid(&error)) {
    b.message = error;
    return b;
  }
  const EventType event = options.event.value_or(tracks::infer_event(track));
  const PerformanceEnvelope envelope = PerformanceEnvelope::of(vehicle, options.grip_fraction);
  RacingLineParams line = options.line;
  line.clearance_m = options.clearance_m.value_or(0.5 * vehicle.width_m + kConeBaseRadiusM);

  switch (event) {
    case EventType::kSkidpad:
      b = skidpad_bound(track, envelope, line.clearance_m, options.step_m);
      break;
    case EventType::kAcceleration:
      b = acceleration_bound(track, envelope, options.step_m);
      break;
    case EventType::kAutocross:
    case EventType::kTrackdrive:
      if (!track.closed) {
        b = acceleration_bound(track, envelope, options.step_m);  // an open course
        if (b.usable) b.line_length_m = b.s_m.empty() ? 0.0 : b.s_m.back();
      } else {
        b = circuit_bound(track, envelope, line, options.step_m, event == EventType::kAutocross);
      }
      break;
  }
  b.event = event;
  return b;
}

}  // namespace conesim::laptime
