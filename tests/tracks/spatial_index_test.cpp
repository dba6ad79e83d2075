#include "tracks/spatial_index.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "core/rng.hpp"

namespace conesim::tracks {
namespace {

std::vector<Vec2> random_points(core::Rng& rng, size_t n, double lo, double hi) {
  std::vector<Vec2> pts;
  for (size_t i = 0; i < n; ++i)
    pts.emplace_back(core::uniform(rng, lo, hi), core::uniform(rng, lo, hi));
  return pts;
}

// the indexes answer exactly what a scan of every point or segment answers: on spread points,
// on points in tight clusters (many alike), and with one point kilometres from the rest
TEST(PointIndex, NearestAndWithinMatchAScan) {
  core::Rng rng(3);
  for (int layout = 0; layout < 3; ++layout) {
    std::vector<Vec2> pts = random_points(rng, 500, -100.0, 100.0);
    if (layout == 1)
      for (Vec2& p : pts) p = Vec2(std::round(p.x() / 40.0), std::round(p.y() / 40.0)) * 40.0;
    if (layout == 2) pts[7] = Vec2(3000.0, -2500.0);
    const PointIndex index(pts);
    for (int q = 0; q < 200; ++q) {
      // queries inside the points' box and far outside it
      const double reach = q % 4 == 0 ? 1e6 : 150.0;
      const Vec2 p(core::uniform(rng, -reach, reach), core::uniform(rng, -reach, reach));
      const auto even = [](size_t i) { return i % 2 == 0; };
      size_t scan = PointIndex::kNone;
      for (size_t i = 0; i < pts.size(); i += 2)
        if (scan == PointIndex::kNone || (pts[i] - p).squaredNorm() < (pts[scan] - p).squaredNorm())
          scan = i;
      EXPECT_EQ(index.nearest(p, even), scan) << "layout " << layout;

      const double r = core::uniform(rng, 0.0, 30.0);
      std::vector<size_t> within;
      for (size_t i = 0; i < pts.size(); ++i)
        if ((pts[i] - p).squaredNorm() <= r * r) within.push_back(i);
      EXPECT_EQ(index.within(p, r), within);
    }
  }
  // nothing accepted, nothing indexed
  const std::vector<Vec2> none;
  EXPECT_EQ(PointIndex(none).nearest({0.0, 0.0}, [](size_t) { return true; }),
            PointIndex::kNone);
}

TEST(PolylineIndex, NearestMatchesAScan) {
  core::Rng rng(5);
  for (bool closed : {false, true}) {
    // a wandering line with a few very long segments
    std::vector<Vec2> pts{{0.0, 0.0}};
    for (int i = 1; i < 400; ++i) {
      const double step = i % 97 == 0 ? 5000.0 : core::uniform(rng, 0.5, 6.0);
      const double a = core::uniform(rng, -3.2, 3.2);
      pts.push_back(pts.back() + step * Vec2(std::cos(a), std::sin(a)));
    }
    const PolylineIndex index(pts, closed);
    const size_t segments = closed ? pts.size() : pts.size() - 1;
    EXPECT_EQ(index.segment_count(), segments);
    for (int q = 0; q < 300; ++q) {
      const Vec2 p = pts[static_cast<size_t>(q) % pts.size()] +
                     Vec2(core::uniform(rng, -50.0, 50.0), core::uniform(rng, -50.0, 50.0)) *
                         (q % 5 == 0 ? 1000.0 : 1.0);
      double best = std::numeric_limits<double>::infinity();
      for (size_t i = 0; i < segments; ++i) {
        const Vec2 a = pts[i], ab = pts[(i + 1) % pts.size()] - a;
        const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
        best = std::min(best, (p - (a + t * ab)).squaredNorm());
      }
      EXPECT_DOUBLE_EQ(index.nearest(p).distance2, best);
    }
  }
  // a single point is its own polyline
  const std::vector<Vec2> one{{3.0, 4.0}};
  EXPECT_DOUBLE_EQ(PolylineIndex(one, false).nearest({0.0, 0.0}).distance2, 25.0);
}

TEST(PolylineIndex, SegmentsNearHoldEveryCrossing) {
  core::Rng rng(8);
  const std::vector<Vec2> pts = random_points(rng, 300, 0.0, 200.0);  // a scribble
  const PolylineIndex index(pts, false);
  for (size_t i = 0; i + 1 < pts.size(); ++i) {
    const Vec2 lo = pts[i].cwiseMin(pts[i + 1]), hi = pts[i].cwiseMax(pts[i + 1]);
    const std::vector<size_t> near = index.segments_near(lo, hi);
    for (size_t j = 0; j + 1 < pts.size(); ++j) {
      // a segment whose box overlaps this one's must be among them
      const Vec2 lo2 = pts[j].cwiseMin(pts[j + 1]), hi2 = pts[j].cwiseMax(pts[j + 1]);
      const bool overlap =
          lo.x() <= hi2.x() && lo2.x() <= hi.x() && lo.y() <= hi2.y() && lo2.y() <= hi.y();
      if (overlap) {
        EXPECT_TRUE(std::binary_search(near.begin(), near.end(), j)) << i << " " << j;
      }
    }
  }
}

}  // namespace
}  // namespace conesim::tracks
