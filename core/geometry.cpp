#include "core/geometry.hpp"

#include <algorithm>
#include <cstdio>

namespace conesim::core {

double distance_to_segment(const Vec2& p, const Vec2& a, const Vec2& b) {
  const Vec2 ab = b - a;
  const double len2 = ab.squaredNorm();
  if (len2 <= 0.0) return (p - a).norm();
  const double t = std::clamp((p - a).dot(ab) / len2, 0.0, 1.0);
  return (p - (a + t * ab)).norm();
}

bool segments_intersect(const Vec2& a1, const Vec2& a2, const Vec2& b1, const Vec2& b2) {
  const double d1 = cross(a2 - a1, b1 - a1);
  const double d2 = cross(a2 - a1, b2 - a1);
  const double d3 = cross(b2 - b1, a1 - b1);
  const double d4 = cross(b2 - b1, a2 - b1);
  return ((d1 > 0) != (d2 > 0)) && ((d3 > 0) != (d4 > 0)) && d1 != 0 && d2 != 0 && d3 != 0 &&
         d4 != 0;
}

std::string format_place(const Vec2& p) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "(%.1f, %.1f)", p.x(), p.y());
  return buf;
}

}  // namespace conesim::core
