#include "tracks/scenery.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include "core/rng.hpp"
#include "core/validate.hpp"
#include "tracks/spatial_index.hpp"
#include "tracks/track_area.hpp"

namespace conesim::tracks {

namespace {

using core::ClutterClass;
using Shape = ScenePrimitive::Shape;

// the scenery's own random stream (sim/sensor_rig.cpp's are 101, 102; faults 301)
constexpr uint64_t kSceneryStream = 401;
// places tried per object before it is left out
constexpr int kAttempts = 60;
// gap between two objects, metres
constexpr double kObjectGapM = 0.5;
// at most this many objects, whatever the density and the length
constexpr int kMaxObjects = 5000;
// how often each class of object is drawn (ClutterClass order; the grass edge is laid, not
// drawn)
constexpr int kDrawnClasses = 7;
constexpr std::array<double, kDrawnClasses> kClassWeight = {0.15, 0.10, 0.15, 0.08,
                                                            0.20, 0.20, 0.12};
// the grass edge: strips this long, farther out in steps of this much until clear
constexpr double kEdgeStripM = 4.0;
constexpr double kEdgeStepM = 0.5;

ScenePrimitive box(const Eigen::Vector3d& centre, const Eigen::Vector3d& half,
                   std::array<float, 4> rgba, double reflectivity) {
  ScenePrimitive p;
  p.shape = Shape::kBox;
  p.centre = centre;
  p.size = half;
  p.rgba = rgba;
  p.reflectivity = reflectivity;
  return p;
}

ScenePrimitive round_solid(Shape shape, const Eigen::Vector3d& centre, double r_bottom,
                           double r_top, double half_length, std::array<float, 4> rgba,
                           double reflectivity) {
  ScenePrimitive p;
  p.shape = shape;
  p.centre = centre;
  p.size = {r_bottom, r_top, half_length};
  p.rgba = rgba;
  p.reflectivity = reflectivity;
  return p;
}

// the horizontal reach and the top of a primitive placed in the object frame
void bounds_of(const ScenePrimitive& p, double& reach, double& top) {
  if (p.shape == Shape::kBox) {
    for (int i = 0; i < 8; ++i) {
      const Eigen::Vector3d corner(i & 1 ? p.size.x() : -p.size.x(),
                                   i & 2 ? p.size.y() : -p.size.y(),
                                   i & 4 ? p.size.z() : -p.size.z());
      const Eigen::Vector3d q = p.centre + p.rotation * corner;
      reach = std::max(reach, q.head<2>().norm());
      top = std::max(top, q.z());
    }
    return;
  }
  // a round solid: both end discs, bounded by their radii about the axis
  const double r = std::max(p.size.x(), p.size.y());
  const Eigen::Vector3d axis = p.rotation.col(2);
  for (double end : {-1.0, 1.0}) {
    const Eigen::Vector3d c = p.centre + end * p.size.z() * axis;
    // a disc of radius r about the axis reaches r sqrt(1 - axis_i^2) along each world axis
    const double across_z = r * std::sqrt(std::max(0.0, 1.0 - axis.z() * axis.z()));
    reach = std::max(reach, c.head<2>().norm() + r);
    top = std::max(top, c.z() + across_z);
  }
}

}  // namespace

std::string ClutterConfig::validate() const {
  if (std::string e = core::check_range("objects_per_100m", objects_per_100m, 0.0, 100.0);
      !e.empty())
    return e;
  if (std::string e = core::check_range("margin_m", margin_m, 1.0, 50.0); !e.empty()) return e;
  return core::check_range("spread_m", spread_m, 0.0, 100.0);
}

SceneryObject make_scenery_object(ClutterClass cls, const Pose2& pose, int variant) {
  SceneryObject o;
  o.cls = cls;
  o.pose = pose;
  constexpr std::array<float, 4> kGrey = {0.55f, 0.55f, 0.55f, 1.f};
  constexpr std::array<float, 4> kConcrete = {0.7f, 0.7f, 0.68f, 1.f};
  switch (cls) {
    case ClutterClass::kBarrier:
      // two water-filled road barriers end to end, red and white
      o.parts.push_back(box({-1.0, 0.0, 0.4}, {0.98, 0.25, 0.4}, {0.8f, 0.1f, 0.1f, 1.f}, 0.5));
      o.parts.push_back(box({1.0, 0.0, 0.4}, {0.98, 0.25, 0.4}, {0.92f, 0.92f, 0.92f, 1.f}, 0.7));
      break;
    case ClutterClass::kFence:
      // three 3.5 m construction fence panels on concrete feet
      for (int i = -1; i <= 1; ++i)
        o.parts.push_back(box({3.5 * i, 0.0, 1.0}, {1.74, 0.02, 0.88}, kGrey, 0.25));
      for (int i = 0; i < 4; ++i)
        o.parts.push_back(box({-5.25 + 3.5 * i, 0.0, 0.06}, {0.3, 0.1, 0.06}, kConcrete, 0.4));
      break;
    case ClutterClass::kTyreStack:
      // two stacks of four tyres
      for (double x : {-0.31, 0.31})
        o.parts.push_back(round_solid(Shape::kCylinder, {x, 0.0, 0.4}, 0.3, 0.3, 0.4,
                                      {0.08f, 0.08f, 0.08f, 1.f}, 0.05));
      break;
    case ClutterClass::kTent: {
      // a 3 x 3 m gazebo: four legs and a white roof
      for (int i = 0; i < 4; ++i)
        o.parts.push_back(round_solid(Shape::kCylinder,
                                      {i & 1 ? 1.45 : -1.45, i & 2 ? 1.45 : -1.45, 1.0}, 0.025,
                                      0.025, 1.0, kGrey, 0.4));
      o.parts.push_back(box({0.0, 0.0, 2.15}, {1.5, 1.5, 0.15}, {0.95f, 0.95f, 0.95f, 1.f}, 0.7));
      break;
    }
    case ClutterClass::kPerson:
      // legs, torso (a team shirt) and head
      o.parts.push_back(box({0.0, 0.0, 0.43}, {0.12, 0.17, 0.43}, {0.15f, 0.18f, 0.3f, 1.f}, 0.2));
      o.parts.push_back(box({0.0, 0.0, 1.15}, {0.13, 0.22, 0.29}, {0.2f, 0.55f, 0.25f, 1.f}, 0.3));
      o.parts.push_back(round_solid(Shape::kCylinder, {0.0, 0.0, 1.58}, 0.1, 0.1, 0.13,
                                    {0.85f, 0.68f, 0.55f, 1.f}, 0.35));
      break;
    case ClutterClass::kGrassEdge:
      // a 4 m strip of grass, 1 m wide, its top 6 cm above the asphalt
      o.parts.push_back(
          box({0.0, 0.0, 0.03}, {0.5 * kEdgeStripM, 0.5, 0.03}, {0.25f, 0.45f, 0.15f, 1.f}, 0.2));
      break;
    case ClutterClass::kSpareCone:
    case ClutterClass::kLyingCone: {
      // a small cone's body (FSG 228 x 228 x 325 mm) in blue, yellow or orange, on its plate
      // or on its side
      constexpr std::array<std::array<float, 4>, 3> kColour = {
          {{0.05f, 0.2f, 0.8f, 1.f}, {0.95f, 0.85f, 0.05f, 1.f}, {1.f, 0.45f, 0.f, 1.f}}};
      const std::array<float, 4> colour = kColour[static_cast<size_t>(std::abs(variant) % 3)];
      if (cls == ClutterClass::kSpareCone) {
        o.parts.push_back(box({0.0, 0.0, 0.01}, {0.114, 0.114, 0.01}, colour, 0.4));
        o.parts.push_back(
            round_solid(Shape::kFrustum, {0.0, 0.0, 0.1725}, 0.09, 0.025, 0.1525, colour, 0.4));
      } else {
        // the axis along x, the body resting on the ground
        ScenePrimitive body =
            round_solid(Shape::kFrustum, {0.0, 0.0, 0.09}, 0.09, 0.025, 0.1625, colour, 0.4);
        body.rotation =
            Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitY()).toRotationMatrix();
        o.parts.push_back(body);
      }
      break;
    }
  }
  for (const ScenePrimitive& p : o.parts) bounds_of(p, o.radius_m, o.height_m);
  return o;
}

std::vector<Vec2> footprint_points(const SceneryObject& object) {
  std::vector<Vec2> out;
  for (const ScenePrimitive& p : object.parts) {
    if (p.shape == Shape::kBox) {
      for (int i = 0; i < 8; ++i) {
        const Eigen::Vector3d corner(i & 1 ? p.size.x() : -p.size.x(),
                                     i & 2 ? p.size.y() : -p.size.y(),
                                     i & 4 ? p.size.z() : -p.size.z());
        out.push_back(object.pose.transform((p.centre + p.rotation * corner).head<2>()));
      }
      continue;
    }
    const double r = std::max(p.size.x(), p.size.y());
    const Eigen::Vector3d axis = p.rotation.col(2);
    for (double end : {-1.0, 1.0})
      for (int k = 0; k < 16; ++k) {
        const double a = 2.0 * std::numbers::pi * k / 16;
        const Eigen::Vector3d c = p.centre + end * p.size.z() * axis;
        out.push_back(object.pose.transform(c.head<2>() + r * Vec2(std::cos(a), std::sin(a))));
      }
  }
  return out;
}

std::vector<SceneryObject> place_scenery(const Track& track, const ClutterConfig& config,
                                         uint64_t scenario_seed) {
  if (const std::string e = config.validate(); !e.empty())
    throw std::invalid_argument("world.clutter." + e);
  std::vector<SceneryObject> out;
  if (config.objects_per_100m <= 0.0 && !config.grass_edge) return out;

  // the driving line, its length and its points by arc length
  std::vector<Vec2> line = track.centre_line;
  if (line.size() < 2) line = derive_centre_line(track);
  if (line.size() < 2) return out;
  const bool closed = track.closed;
  if (closed) line.push_back(line.front());
  std::vector<double> arc(line.size(), 0.0);
  for (size_t i = 1; i < line.size(); ++i) arc[i] = arc[i - 1] + (line[i] - line[i - 1]).norm();
  const double length = arc.back();
  if (!(length > 0.0)) return out;
  const int count = config.objects_per_100m <= 0.0
                        ? 0
                        : static_cast<int>(std::min<double>(
                              kMaxObjects, std::round(config.objects_per_100m * length / 100.0)));

  // what an object keeps clear of: the area between the lanes and their polylines, every cone,
  // the driving line and the start
  const TrackArea area = TrackArea::of(track);
  std::vector<Vec2> cone_points;
  for (const Cone& c : track.cones) cone_points.push_back(c.position);
  const PointIndex cones(cone_points);
  const PolylineIndex driving(line, false);
  double cone_reach = 0.0;
  for (const Cone& c : track.cones)
    cone_reach = std::max(cone_reach, 0.5 * std::numbers::sqrt2 * core::cone_size(c.cls).base_m);
  std::vector<Vec2> placed_at;
  std::vector<double> placed_radius;

  // the place on the driving line at arc length s and the line's direction there
  const auto on_line = [&line, &arc](double s, Vec2& tangent) {
    const size_t seg = static_cast<size_t>(
        std::clamp<std::ptrdiff_t>(std::upper_bound(arc.begin(), arc.end(), s) - arc.begin() - 1, 0,
                                   static_cast<std::ptrdiff_t>(line.size()) - 2));
    const double seg_len = std::max(1e-9, arc[seg + 1] - arc[seg]);
    tangent = (line[seg + 1] - line[seg]) / seg_len;
    return Vec2(line[seg] + (s - arc[seg]) * tangent);
  };
  // whether p keeps `clear` from the lanes, the cones and the driving line, and more from the
  // start
  const auto clear_of_track = [&](const Vec2& p, double clear) {
    if (!area.empty()) {
      if (area.contains(p)) return false;
      const auto nearest = area.nearest_boundary(p);
      if (nearest && nearest->distance_m < clear) return false;
    }
    const size_t near_cone = cones.nearest(p, [](size_t) { return true; });
    if (near_cone != PointIndex::kNone && (cone_points[near_cone] - p).norm() < clear + cone_reach)
      return false;
    if (std::sqrt(driving.nearest(p).distance2) < clear) return false;
    return (p - track.start.position()).norm() >= clear + 3.0;
  };

  core::Rng rng(
      core::derive_seed(core::derive_seed(scenario_seed, kSceneryStream), config.seed_offset));
  double total_weight = 0.0;
  for (double w : kClassWeight) total_weight += w;
  for (int i = 0; i < count; ++i) {
    // the class and its look, then places until one is clear
    double pick = core::uniform(rng, 0.0, total_weight);
    int k = 0;
    while (k + 1 < kDrawnClasses && pick >= kClassWeight[static_cast<size_t>(k)])
      pick -= kClassWeight[static_cast<size_t>(k++)];
    const auto cls = static_cast<ClutterClass>(k);
    const int variant = static_cast<int>(core::uniform_int(rng, 0, 2));
    const SceneryObject shape = make_scenery_object(cls, Pose2{}, variant);
    const double clear = config.margin_m + shape.radius_m;
    for (int attempt = 0; attempt < kAttempts; ++attempt) {
      // a place beside the driving line, heading along it (people and cones any way)
      const double s = core::uniform(rng, 0.0, length);
      const double side = core::uniform(rng, 0.0, 1.0) < 0.5 ? -1.0 : 1.0;
      const double out_m = clear + core::uniform(rng, 0.0, config.spread_m);
      const double yaw_jitter = core::uniform(rng, -0.3, 0.3);
      const double free_yaw = core::uniform(rng, -std::numbers::pi, std::numbers::pi);
      Vec2 tangent;
      const Vec2 at = on_line(s, tangent);
      const Vec2 p = at + side * out_m * Vec2(-tangent.y(), tangent.x());

      // clear of the track and of the other objects
      if (!clear_of_track(p, clear)) continue;
      bool overlaps = false;
      for (size_t j = 0; j < placed_at.size() && !overlaps; ++j)
        overlaps = (placed_at[j] - p).norm() < placed_radius[j] + shape.radius_m + kObjectGapM;
      if (overlaps) continue;

      const bool free_turn = cls == ClutterClass::kPerson || cls == ClutterClass::kSpareCone ||
                             cls == ClutterClass::kLyingCone;
      const double yaw = free_turn ? free_yaw : std::atan2(tangent.y(), tangent.x()) + yaw_jitter;
      out.push_back(make_scenery_object(cls, Pose2{p.x(), p.y(), yaw}, variant));
      placed_at.push_back(p);
      placed_radius.push_back(shape.radius_m);
      break;
    }
  }

  // the grass edge: strips along both sides of the driving line, each as near as it may lie
  // (objects may stand on it)
  if (config.grass_edge) {
    const double clear =
        config.margin_m + make_scenery_object(ClutterClass::kGrassEdge, Pose2{}).radius_m;
    for (double s = 0.5 * kEdgeStripM; s < length; s += kEdgeStripM)
      for (double side : {1.0, -1.0}) {
        Vec2 tangent;
        const Vec2 at = on_line(s, tangent);
        const Vec2 normal = side * Vec2(-tangent.y(), tangent.x());
        for (double out_m = clear; out_m <= clear + config.spread_m; out_m += kEdgeStepM) {
          const Vec2 p = at + out_m * normal;
          if (!clear_of_track(p, clear)) continue;
          out.push_back(make_scenery_object(
              ClutterClass::kGrassEdge, Pose2{p.x(), p.y(), std::atan2(tangent.y(), tangent.x())}));
          break;
        }
      }
  }
  return out;
}

void lay_on_ground(std::vector<SceneryObject>& objects, const GroundModel& ground) {
  for (SceneryObject& o : objects) {
    if (o.cls != ClutterClass::kGrassEdge) continue;
    // the plane through the ground over the strip's footprint: its slopes from heights a
    // strip's half length and half width away
    const double x = o.pose.x, y = o.pose.y, h = 0.5 * kEdgeStripM;
    const double gx = (ground.height(x + h, y) - ground.height(x - h, y)) / (2.0 * h);
    const double gy = (ground.height(x, y + h) - ground.height(x, y - h)) / (2.0 * h);
    const Eigen::Vector3d normal = Eigen::Vector3d(-gx, -gy, 1.0).normalized();
    o.tilt = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), normal).toRotationMatrix();
  }
}

}  // namespace conesim::tracks
