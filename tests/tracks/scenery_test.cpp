// Scenery and clutter (issue 17): placed from the seed, never within the margin of the lanes,
// the cones or the driving line, on generated circuits and on shared layouts.

#include "tracks/scenery.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <set>
#include <string>

#include "core/measurements.hpp"
#include "tracks/generator.hpp"
#include "tracks/io.hpp"
#include "tracks/track_area.hpp"

namespace conesim::tracks {
namespace {

using core::ClutterClass;

// the layout's driving line (as the placement measures it) and its length
std::vector<Vec2> driving_line(const Track& track) {
  std::vector<Vec2> line =
      track.centre_line.size() >= 2 ? track.centre_line : derive_centre_line(track);
  if (track.closed && !line.empty()) line.push_back(line.front());
  return line;
}

double length_of(const std::vector<Vec2>& line) {
  double length = 0.0;
  for (size_t i = 1; i < line.size(); ++i) length += (line[i] - line[i - 1]).norm();
  return length;
}

// distance from p to a polyline, by a scan of its segments
double distance_to(const std::vector<Vec2>& line, const Vec2& p) {
  double best = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i + 1 < line.size(); ++i) {
    const Vec2 d = line[i + 1] - line[i];
    const double t = std::clamp((p - line[i]).dot(d) / std::max(d.squaredNorm(), 1e-12), 0.0, 1.0);
    best = std::min(best, (line[i] + t * d - p).norm());
  }
  return best;
}

// every point of every object's footprint keeps the margin from the lanes (the track's own
// area and its nearest boundary), from every cone's centre and from the driving line; returns
// the smallest clearance from the lanes met, so that a test can see the margin bite
double expect_clear(const Track& track, const ClutterConfig& config,
                    const std::vector<SceneryObject>& objects) {
  const TrackArea area = TrackArea::of(track);
  const std::vector<Vec2> line = driving_line(track);
  double smallest = std::numeric_limits<double>::infinity();
  for (const SceneryObject& o : objects)
    for (const Vec2& p : footprint_points(o)) {
      const std::string where = track.name + ": " + std::string(core::to_string(o.cls)) + " at (" +
                                std::to_string(p.x()) + ", " + std::to_string(p.y()) + ")";
      if (!area.empty()) {
        EXPECT_FALSE(area.contains(p)) << where;
        const double clearance = area.nearest_boundary(p)->distance_m;
        EXPECT_GE(clearance, config.margin_m - 1e-9) << where;
        smallest = std::min(smallest, clearance);
      }
      for (const Cone& c : track.cones)
        EXPECT_GE((c.position - p).norm(), config.margin_m) << where;
      EXPECT_GE(distance_to(line, p), config.margin_m - 1e-9) << where;
    }
  return smallest;
}

TEST(Scenery, DensityZeroPlacesNothing) {
  const Track track = generate_circuit(3);
  EXPECT_TRUE(place_scenery(track, ClutterConfig{}, 1).empty());
}

TEST(Scenery, GeneratedCircuitsKeepTheMargin) {
  ClutterConfig config;
  config.objects_per_100m = 3.0;
  for (uint64_t seed : {1u, 2u, 3u, 7u, 11u}) {
    const Track track = generate_circuit(seed);
    const std::vector<SceneryObject> objects = place_scenery(track, config, seed);
    // nearly every object the density asks for finds a place
    const double wanted =
        std::round(config.objects_per_100m * length_of(driving_line(track)) / 100);
    EXPECT_GE(static_cast<double>(objects.size()), 0.9 * wanted) << seed;
    // some object stands within a metre of the margin: the check is not passed by distance
    EXPECT_LT(expect_clear(track, config, objects), config.margin_m + 1.0) << seed;
  }
}

// the grass edge lines both sides of generated circuits and shared layouts in 4 m strips (some
// left out where a corner leaves no clear place within the spread), never within the margin
TEST(Scenery, TheGrassEdgeLinesTheTrackOutsideTheMargin) {
  ClutterConfig config;
  config.grass_edge = true;
  const std::filesystem::path data = CONESIM_TEST_DATA;
  for (const Track& track :
       {generate_circuit(1), generate_circuit(5), read_track(data / "tracks/pacsim/FSG19.yaml"),
        read_track(data / "tracks/eufs/acceleration.csv")}) {
    const std::vector<SceneryObject> strips = place_scenery(track, config, 1);
    const double wanted = 2.0 * std::floor(length_of(driving_line(track)) / 4.0);
    EXPECT_GE(static_cast<double>(strips.size()), 0.7 * wanted) << track.name;
    EXPECT_LE(static_cast<double>(strips.size()), wanted + 2.0) << track.name;
    for (const SceneryObject& o : strips) EXPECT_EQ(o.cls, ClutterClass::kGrassEdge);
    // each strip keeps its bounding circle clear: its long side lies nearer than that
    ASSERT_FALSE(strips.empty());
    EXPECT_LT(expect_clear(track, config, strips), config.margin_m + strips.front().radius_m)
        << track.name;
  }
}

TEST(Scenery, SharedLayoutsKeepTheMargin) {
  ClutterConfig config;
  config.objects_per_100m = 4.0;
  config.margin_m = 3.5;
  const std::filesystem::path data = CONESIM_TEST_DATA;
  for (const char* file : {"tracks/eufs/small_track.csv", "tracks/eufs/Jellybean_02_03_2023.csv",
                           "tracks/eufs/acceleration.csv", "tracks/eufs/skidpad.csv",
                           "tracks/pacsim/FSG19.yaml", "tracks/epfl/track_3_cones.csv"}) {
    const Track track = read_track(data / file);
    const std::vector<SceneryObject> objects = place_scenery(track, config, 5);
    EXPECT_FALSE(objects.empty()) << file;
    expect_clear(track, config, objects);
  }
}

TEST(Scenery, TheSeedDecidesAndTheOffsetChangesIt) {
  const Track track = generate_circuit(4);
  ClutterConfig config;
  config.objects_per_100m = 2.0;
  const auto a = place_scenery(track, config, 9), b = place_scenery(track, config, 9);
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].cls, b[i].cls);
    EXPECT_EQ(a[i].pose.x, b[i].pose.x);
    EXPECT_EQ(a[i].pose.y, b[i].pose.y);
  }
  config.seed_offset = 1;
  const auto c = place_scenery(track, config, 9);
  ASSERT_FALSE(c.empty());
  EXPECT_NE(c.front().pose.x, a.front().pose.x);
}

TEST(Scenery, EveryClassIsPlacedAndBoundedByItsRadius) {
  const Track track = generate_circuit(2);
  ClutterConfig config;
  config.objects_per_100m = 10.0;
  std::set<ClutterClass> seen;
  for (const SceneryObject& o : place_scenery(track, config, 3)) {
    seen.insert(o.cls);
    EXPECT_GT(o.height_m, 0.1);
    for (const Vec2& p : footprint_points(o))
      EXPECT_LE((p - o.pose.position()).norm(), o.radius_m + 1e-9);
  }
  // every class but the grass edge, which is laid only when asked
  EXPECT_EQ(seen.size(), static_cast<size_t>(core::kClutterClassCount - 1));
  EXPECT_FALSE(seen.count(ClutterClass::kGrassEdge));
}

TEST(Scenery, ValidateNamesTheKeyAndTheRange) {
  ClutterConfig config;
  EXPECT_EQ(config.validate(), "");
  config.objects_per_100m = -1.0;
  EXPECT_EQ(config.validate(), "objects_per_100m: expected a number in [0, 100], got -1");
  config = {};
  config.margin_m = 0.5;
  EXPECT_NE(config.validate().find("margin_m: expected a number in [1, 50]"), std::string::npos);
  EXPECT_THROW(place_scenery(generate_circuit(1), config, 1), std::invalid_argument);
}

TEST(Scenery, ClutterLabelsAreNeverConeIdsNorTheGround) {
  for (ClutterClass c : core::kClutterClasses) {
    const int label = core::clutter_label(c);
    EXPECT_LT(label, core::PointCloudLabels::kGroundLabel);
    EXPECT_EQ(core::clutter_of_label(label), c);
  }
  EXPECT_FALSE(core::clutter_of_label(0));
  EXPECT_FALSE(core::clutter_of_label(core::PointCloudLabels::kGroundLabel));
  EXPECT_FALSE(core::clutter_of_label(-2 - core::kClutterClassCount));
}

}  // namespace
}  // namespace conesim::tracks
