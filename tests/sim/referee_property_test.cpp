// The referee's boundaries as a property over every layout a user may load (the 47 public ones
// in tests/data/tracks) and hundreds of generated circuits: a car on the centre line is never
// off-course and knocks only cones its footprint really touches; a car pushed one wheel-width
// past a boundary is off-course.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "core/rng.hpp"
#include "sim/referee.hpp"
#include "tracks/generator.hpp"
#include "tracks/io.hpp"
#include "tracks/rules.hpp"

namespace conesim::sim {
namespace {

namespace fs = std::filesystem;
using core::EventType;
using core::Pose2;
using core::TimeUs;
using core::Vec2;
using tracks::Track;
using vehicle_models::VehicleParams;

// the true state of a car with its rear axle at pose: contact patches from wheelbase and track
VehicleTruth truth_at(const Pose2& pose, double speed_mps, const VehicleParams& car) {
  VehicleTruth t;
  t.pose = pose;
  t.vx_mps = speed_mps;
  const double h = 0.5 * car.track_m;
  t.wheel_positions = {pose.transform({car.wheelbase_m, h}), pose.transform({car.wheelbase_m, -h}),
                       pose.transform({0.0, h}), pose.transform({0.0, -h})};
  return t;
}

// every public layout that reads (one of them has a malformed row on purpose)
std::vector<Track> shared_layouts() {
  std::vector<Track> tracks;
  const fs::path root = fs::path(CONESIM_TEST_DATA) / "tracks";
  std::vector<fs::path> files;
  for (const auto& dir : fs::directory_iterator(root))
    if (dir.is_directory())
      for (const auto& f : fs::directory_iterator(dir.path()))
        if (f.path().extension() == ".yaml" || f.path().extension() == ".csv")
          files.push_back(f.path());
  std::sort(files.begin(), files.end());
  for (const fs::path& f : files) {
    try {
      tracks.push_back(tracks::read_track(f));
    } catch (const std::exception&) {
      // track_created.csv: malformed upstream, refused by the reader (tests/tracks/io_test.cpp)
    }
  }
  return tracks;
}

// the footprint centre's offset ahead of the rear axle
double footprint_centre_ahead_m(const VehicleParams& car) {
  return car.front_overhang_from_rear_axle_m - 0.5 * car.length_m;
}

// ids of the cones the footprint rectangle at pose overlaps (an independent brute-force check)
std::set<int> cones_under(const Track& track, const Pose2& rear_axle, const VehicleParams& car) {
  std::set<int> ids;
  const double front = car.front_overhang_from_rear_axle_m;
  const double rear = car.length_m - front;
  for (const tracks::Cone& c : track.cones) {
    const Vec2 local = rear_axle.inverse_transform(c.position);
    const double dx = std::max({-rear - local.x(), local.x() - front, 0.0});
    const double dy = std::max(std::abs(local.y()) - 0.5 * car.width_m, 0.0);
    const double r = 0.5 * core::cone_size(c.cls).base_m;
    if (dx * dx + dy * dy <= r * r) ids.insert(c.id);
  }
  return ids;
}

// drives the footprint centre along the track's centre line (one lap and a bit on a circuit)
// through a fresh referee; returns the referee's and the brute-force cone hits
struct CentreLineDrive {
  int off_course = 0;
  std::vector<std::string> off_course_reasons;
  std::set<int> referee_hits;
  std::set<int> footprint_hits;
  bool timed = false;
  std::string dnf_reason;
};
CentreLineDrive drive_centre_line(const Track& track, EventType event, const VehicleParams& car) {
  CentreLineDrive out;
  const std::vector<Vec2>& line = track.centre_line;
  if (line.size() < 2) return out;
  Referee referee(track, event, car);

  // the route: from where a run puts the car (front wing on the start pose) to the line's
  // point nearest the start, then along the line (a circuit: once round and a fifth again)
  size_t first = 0;
  for (size_t i = 0; i < line.size(); ++i)
    if ((line[i] - track.start.position()).squaredNorm() <
        (line[first] - track.start.position()).squaredNorm())
      first = i;
  const double behind = car.front_overhang_from_rear_axle_m - footprint_centre_ahead_m(car);
  std::vector<Vec2> route{track.start.position() - behind * track.start.heading()};
  if (track.closed) {
    for (size_t k = 0; k <= line.size() + line.size() / 5; ++k)
      route.push_back(line[(first + k) % line.size()]);
  } else {
    route.insert(route.end(), line.begin() + static_cast<long>(first), line.end());
  }
  const double ahead = footprint_centre_ahead_m(car);
  const double speed = 10.0;
  TimeUs t = 0;
  for (size_t k = 0; k + 1 < route.size(); ++k) {
    const Vec2 a = route[k], b = route[k + 1];
    const double len = (b - a).norm();
    if (len < 1e-9) continue;
    const double yaw = std::atan2(b.y() - a.y(), b.x() - a.x());
    for (double u = 0.0; u < len; u += 0.05) {
      const Vec2 c = a + (u / len) * (b - a);
      const Pose2 pose{c.x() - ahead * std::cos(yaw), c.y() - ahead * std::sin(yaw), yaw};
      t += 5000;  // 5 cm at 10 m/s
      const VehicleTruth truth = truth_at(pose, speed, car);
      referee.update(t, truth);
      if (referee.finished()) break;
      const std::set<int> under = cones_under(track, pose, car);
      out.footprint_hits.insert(under.begin(), under.end());
    }
    if (referee.finished()) break;
  }
  const RefereeResult& r = referee.result();
  out.off_course = r.off_course;
  for (const RefereeEvent& e : r.events)
    if (e.kind == RefereeEvent::Kind::kOffCourse) out.off_course_reasons.push_back(e.reason);
  out.referee_hits.insert(r.cones_hit.begin(), r.cones_hit.end());
  out.timed = !r.lap_times_s.empty() || r.raw_time_s > 0.0;
  out.dnf_reason = r.dnf_reason;
  return out;
}

TEST(RefereeProperty, ACarOnTheCentreLineOfEveryPublicLayoutIsNeverOffCourse) {
  const VehicleParams car;
  const std::vector<Track> layouts = shared_layouts();
  ASSERT_GE(layouts.size(), 46u);  // 47 files, one malformed
  int timed = 0;
  std::string untimed;
  for (const Track& track : layouts) {
    const EventType event = track.event.value_or(tracks::infer_event(track));
    const CentreLineDrive d = drive_centre_line(track, event, car);
    EXPECT_EQ(d.off_course, 0) << track.name << ": "
                               << (d.off_course_reasons.empty() ? "" : d.off_course_reasons[0]);
    // the referee knocks exactly the cones the footprint touches
    EXPECT_EQ(d.referee_hits, d.footprint_hits) << track.name;
    timed += d.timed ? 1 : 0;
    if (!d.timed) untimed += " " + track.name + " (" + d.dnf_reason + ")";
  }
  // off-course is judged only while timed: the drive must have reached the timing gate
  EXPECT_EQ(timed, static_cast<int>(layouts.size())) << "never timed:" << untimed;
}

TEST(RefereeProperty, ACarOnTheCentreLineOfGeneratedCircuitsIsNeverOffCourseNorHitsACone) {
  const VehicleParams car;
  for (uint64_t seed = 1; seed <= 200; ++seed) {
    const Track track = tracks::generate_circuit(seed);
    const CentreLineDrive d = drive_centre_line(track, EventType::kAutocross, car);
    EXPECT_TRUE(d.timed) << "seed " << seed;
    EXPECT_EQ(d.off_course, 0) << "seed " << seed << ": "
                               << (d.off_course_reasons.empty() ? "" : d.off_course_reasons[0]);
    // generated circuits are at least 3 m wide: the car's 1.4 m fits on the centre line
    EXPECT_TRUE(d.referee_hits.empty()) << "seed " << seed;
    EXPECT_EQ(d.referee_hits, d.footprint_hits) << "seed " << seed;
  }
}

// the lanes as the referee judges them: closed ones joined end to start
std::vector<std::pair<Vec2, Vec2>> lane_segments(const Track& track) {
  std::vector<std::pair<Vec2, Vec2>> segs;
  for (const auto* lane : {&track.left_lane, &track.right_lane}) {
    const std::vector<Vec2> pts = track.lane_points(*lane);
    for (size_t i = 0; i + 1 < pts.size(); ++i) segs.emplace_back(pts[i], pts[i + 1]);
    if (track.closed && pts.size() > 2) segs.emplace_back(pts.back(), pts.front());
  }
  return segs;
}

// true when segments ab and cd cross
bool crosses(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d) {
  const double d1 = core::cross(b - a, c - a), d2 = core::cross(b - a, d - a);
  const double d3 = core::cross(d - c, a - c), d4 = core::cross(d - c, b - c);
  return ((d1 > 0) != (d2 > 0)) && ((d3 > 0) != (d4 > 0));
}

// pushes a car one wheel-width past random places of each lane and asks the referee; the
// independent judge: a wheel is outside when the straight line from a point just inside the
// boundary to it crosses the lanes an odd number of times. Returns (samples judged, misjudged).
std::pair<int, int> push_out(const Track& track, EventType event, const VehicleParams& car,
                             core::Rng& rng, int samples_per_lane, std::string* first_miss) {
  const Referee referee(track, event, car);
  const std::vector<std::pair<Vec2, Vec2>> segs = lane_segments(track);
  int judged = 0, misjudged = 0;
  for (int side = 0; side < 2; ++side) {
    const std::vector<Vec2> lane =
        track.lane_points(side == 0 ? track.left_lane : track.right_lane);
    if (lane.size() < 3) continue;
    for (int s = 0; s < samples_per_lane; ++s) {
      // a point on a random segment, the outward normal (left lane: to the left of travel)
      const size_t i =
          static_cast<size_t>(core::uniform(rng, 0.0, 1.0) * static_cast<double>(lane.size() - 1));
      const Vec2 a = lane[i], b = lane[i + 1];
      if ((b - a).norm() < 1.0) continue;
      const Vec2 dir = (b - a).normalized();
      const Vec2 left_normal(-dir.y(), dir.x());
      const Vec2 out = side == 0 ? left_normal : Vec2(-left_normal);
      const Vec2 p = a + core::uniform(rng, 0.25, 0.75) * (b - a);
      const Vec2 inside = p - 0.3 * out;

      // the car parallel to the boundary, its near wheels one wheel-width past the line
      const double near = car.wheel_width_m + 0.5 * car.wheel_width_m;
      const Vec2 axle_mid = p + (near + 0.5 * car.track_m) * out;
      const double yaw = std::atan2(dir.y(), dir.x());
      const Vec2 rear = axle_mid - 0.5 * car.wheelbase_m * dir;
      const VehicleTruth truth = truth_at({rear.x(), rear.y(), yaw}, 0.0, car);

      // only where the independent judge is sure: no lane within 0.15 m of a wheel or of the
      // inside point (bar the pushed segment), and far from the open ends of an open layout
      bool clear = true;
      for (const auto& [c, d] : segs) {
        const bool own = (c - a).norm() < 1e-9 && (d - b).norm() < 1e-9;
        if (!own && core::distance_to_segment(inside, c, d) < 0.25) clear = false;
        for (const Vec2& w : truth.wheel_positions)
          if (core::distance_to_segment(w, c, d) < 0.15) clear = false;
      }
      if (!track.closed) {
        for (const Vec2& end : {lane.front(), lane.back()})
          if ((p - end).norm() < 15.0) clear = false;
      }
      if (!clear) continue;
      bool all_out = true;
      for (const Vec2& w : truth.wheel_positions) {
        int crossings = 0;
        for (const auto& [c, d] : segs) crossings += crosses(inside, w, c, d) ? 1 : 0;
        all_out = all_out && crossings % 2 == 1;
      }
      if (!all_out) continue;  // pushed onto another part of the track
      ++judged;
      if (!referee.all_wheels_off(truth)) {
        ++misjudged;
        if (first_miss && first_miss->empty()) {
          char buf[160];
          std::snprintf(buf, sizeof buf, "%s: car pushed past the %s lane at (%.2f, %.2f) on track",
                        track.name.c_str(), side == 0 ? "left" : "right", p.x(), p.y());
          *first_miss = buf;
        }
      }
    }
  }
  return {judged, misjudged};
}

TEST(RefereeProperty, ACarPushedOneWheelWidthPastABoundaryIsOffCourse) {
  const VehicleParams car;
  core::Rng rng(7);
  int judged = 0, misjudged = 0;
  std::string first_miss;
  for (const Track& track : shared_layouts()) {
    const EventType event = track.event.value_or(tracks::infer_event(track));
    if (event == EventType::kSkidpad) continue;  // judged from its circles: tests in referee_test
    const auto [j, m] = push_out(track, event, car, rng, 40, &first_miss);
    judged += j;
    misjudged += m;
  }
  for (uint64_t seed = 1; seed <= 200; ++seed) {
    const auto [j, m] =
        push_out(tracks::generate_circuit(seed), EventType::kTrackdrive, car, rng, 10, &first_miss);
    judged += j;
    misjudged += m;
  }
  EXPECT_GT(judged, 3000);  // the samples the independent judge was sure of
  EXPECT_EQ(misjudged, 0) << first_miss;
}

}  // namespace
}  // namespace conesim::sim
