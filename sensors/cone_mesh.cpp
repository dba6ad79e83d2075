#include "sensors/cone_mesh.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace conesim::sensors {

namespace {

// distance from p to the segment [a, b] in the (radius, height) half-plane
double distance_2d(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double s = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (a + s * ab - p).norm();
}

}  // namespace

std::string_view to_string(SurfaceMaterial m) {
  switch (m) {
    case SurfaceMaterial::kGround:
      return "ground";
    case SurfaceMaterial::kBlue:
      return "blue";
    case SurfaceMaterial::kYellow:
      return "yellow";
    case SurfaceMaterial::kOrange:
      return "orange";
    case SurfaceMaterial::kWhite:
      return "white";
    case SurfaceMaterial::kBlack:
      return "black";
  }
  return "ground";
}

double ConeShape::body_radius_at(double z_m) const {
  const double s = std::clamp((z_m - plate_height_m) / (height_m - plate_height_m), 0.0, 1.0);
  return body_bottom_radius_m + s * (body_top_radius_m - body_bottom_radius_m);
}

SurfaceMaterial ConeShape::material_at(double z_m) const {
  if (z_m < plate_height_m) return plate_material;
  for (const ConeBand& band : bands)
    if (z_m < band.to_m) return band.material;
  return bands.back().material;
}

double ConeShape::surface_distance(const Eigen::Vector3d& p) const {
  // body: the side and the top cap in the (radius, height) half-plane
  const Eigen::Vector2d q(std::hypot(p.x(), p.y()), p.z());
  const Eigen::Vector2d bottom(body_bottom_radius_m, plate_height_m);
  const Eigen::Vector2d top(body_top_radius_m, height_m);
  const double body =
      std::min(distance_2d(q, bottom, top), distance_2d(q, top, Eigen::Vector2d(0.0, height_m)));

  // plate: the surface of an axis-aligned box (outside: distance to the box; inside: to a face)
  const Eigen::Vector3d half(0.5 * plate_width_m, 0.5 * plate_width_m, 0.5 * plate_height_m);
  const Eigen::Vector3d d = (p - Eigen::Vector3d(0.0, 0.0, 0.5 * plate_height_m)).cwiseAbs() - half;
  const double plate = d.maxCoeff() > 0.0 ? d.cwiseMax(0.0).norm() : -d.maxCoeff();
  return std::min(body, plate);
}

ConeShape cone_shape(core::ConeClass cls) {
  // the dimensions and bands of core/cone_geometry.hpp, which the camera's meshes share
  const core::ConeGeometry geometry = core::cone_geometry(cls);
  ConeShape s;
  s.plate_width_m = geometry.base_width_m;
  s.plate_height_m = geometry.plate_height_m;
  s.body_bottom_radius_m = geometry.bands.front().radius_bottom_m;
  s.body_top_radius_m = geometry.bands.back().radius_top_m;
  s.height_m = geometry.height_m;

  // paint: blue/white, yellow/black, orange/white; unknown cones plain orange
  using M = SurfaceMaterial;
  M base = M::kOrange, stripe = M::kWhite;
  switch (cls) {
    case core::ConeClass::kBlue:
      base = M::kBlue;
      break;
    case core::ConeClass::kYellow:
      base = M::kYellow, stripe = M::kBlack;
      break;
    case core::ConeClass::kOrangeSmall:
    case core::ConeClass::kOrangeBig:
      break;
    case core::ConeClass::kUnknown:
      stripe = M::kOrange;
      break;
  }
  s.plate_material = base;
  for (const core::ConeBand& band : geometry.bands)
    s.bands.push_back({band.z_bottom_m, band.z_top_m, band.stripe ? stripe : base});
  return s;
}

ConeMesh build_cone_mesh(const ConeShape& shape, int sides) {
  ConeMesh mesh;
  auto add_vertex = [&](double x, double y, double z) {
    mesh.vertices.emplace_back(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
    return static_cast<uint32_t>(mesh.vertices.size() - 1);
  };
  auto add_triangle = [&](uint32_t a, uint32_t b, uint32_t c, SurfaceMaterial m) {
    mesh.triangles.push_back({a, b, c});
    mesh.materials.push_back(m);
  };

  // plate: top face and four sides of the box (the underside lies on the ground)
  const double h = 0.5 * shape.plate_width_m;
  const double zp = shape.plate_height_m;
  const std::array<Eigen::Vector2d, 4> corners{Eigen::Vector2d(-h, -h), Eigen::Vector2d(h, -h),
                                               Eigen::Vector2d(h, h), Eigen::Vector2d(-h, h)};
  std::array<uint32_t, 4> low{}, high{};
  for (int i = 0; i < 4; ++i) {
    low[i] = add_vertex(corners[i].x(), corners[i].y(), 0.0);
    high[i] = add_vertex(corners[i].x(), corners[i].y(), zp);
  }
  add_triangle(high[0], high[1], high[2], shape.plate_material);
  add_triangle(high[0], high[2], high[3], shape.plate_material);
  for (int i = 0; i < 4; ++i) {
    const int j = (i + 1) % 4;
    add_triangle(low[i], low[j], high[j], shape.plate_material);
    add_triangle(low[i], high[j], high[i], shape.plate_material);
  }

  // body: one ring of vertices at the plate's top and at every band boundary
  std::vector<double> levels{shape.bands.front().from_m};
  for (const ConeBand& band : shape.bands) levels.push_back(band.to_m);
  std::vector<uint32_t> ring_start;
  for (double z : levels) {
    ring_start.push_back(static_cast<uint32_t>(mesh.vertices.size()));
    const double r = shape.body_radius_at(z);
    for (int k = 0; k < sides; ++k) {
      const double a = 2.0 * std::numbers::pi * k / sides;
      add_vertex(r * std::cos(a), r * std::sin(a), z);
    }
  }

  // body sides: two triangles per facet and band, in the band's material
  for (size_t b = 0; b < shape.bands.size(); ++b) {
    for (int k = 0; k < sides; ++k) {
      const uint32_t k1 = static_cast<uint32_t>((k + 1) % sides);
      const uint32_t a0 = ring_start[b] + static_cast<uint32_t>(k), a1 = ring_start[b] + k1;
      const uint32_t b0 = ring_start[b + 1] + static_cast<uint32_t>(k), b1 = ring_start[b + 1] + k1;
      add_triangle(a0, a1, b1, shape.bands[b].material);
      add_triangle(a0, b1, b0, shape.bands[b].material);
    }
  }

  // top cap: a fan around the centre in the top band's material
  const uint32_t centre = add_vertex(0.0, 0.0, shape.height_m);
  const uint32_t top = ring_start.back();
  for (int k = 0; k < sides; ++k) {
    add_triangle(centre, top + static_cast<uint32_t>(k),
                 top + static_cast<uint32_t>((k + 1) % sides), shape.bands.back().material);
  }
  return mesh;
}

double facet_deviation_m(const ConeShape& shape, int sides) {
  return shape.body_bottom_radius_m * (1.0 - std::cos(std::numbers::pi / sides));
}

}  // namespace conesim::sensors
