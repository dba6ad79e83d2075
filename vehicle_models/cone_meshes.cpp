#include "vehicle_models/cone_meshes.hpp"

#include <cmath>
#include <numbers>
#include <sstream>

namespace conesim::vehicle_models {

namespace {

constexpr core::ConeClass kClasses[] = {core::ConeClass::kBlue, core::ConeClass::kYellow,
                                        core::ConeClass::kOrangeSmall, core::ConeClass::kOrangeBig,
                                        core::ConeClass::kUnknown};

// appends a vertex with its normal and texture coordinate, returns its index
int add_vertex(TriangleMesh& mesh, double x, double y, double z, double nx, double ny, double nz,
               const double (&uv)[2]) {
  mesh.vertices.insert(mesh.vertices.end(), {x, y, z});
  mesh.normals.insert(mesh.normals.end(), {nx, ny, nz});
  mesh.texcoords.insert(mesh.texcoords.end(), {uv[0], uv[1]});
  return mesh.vertex_count() - 1;
}

// the plate: a box from the ground to plate_height_m, one quad of four vertices per face
void add_plate(TriangleMesh& mesh, const core::ConeGeometry& shape) {
  const double h = 0.5 * shape.base_width_m, top = shape.plate_height_m;
  // each face: outward normal and two in-plane axes (u x v = normal)
  const double faces[6][3][3] = {
      {{0, 0, 1}, {1, 0, 0}, {0, 1, 0}}, {{0, 0, -1}, {0, 1, 0}, {1, 0, 0}},
      {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, {{-1, 0, 0}, {0, 0, 1}, {0, 1, 0}},
      {{0, 1, 0}, {0, 0, 1}, {1, 0, 0}}, {{0, -1, 0}, {1, 0, 0}, {0, 0, 1}},
  };
  const double half[3] = {h, h, 0.5 * top};
  for (const auto& [n, u, v] : faces) {
    constexpr int kCorners[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
    int first = -1;
    for (const auto& [su, sv] : kCorners) {
      double p[3];
      for (int i = 0; i < 3; ++i) p[i] = (n[i] + su * u[i] + sv * v[i]) * half[i];
      const int k =
          add_vertex(mesh, p[0], p[1], p[2] + 0.5 * top, n[0], n[1], n[2], kConeBodyTexcoord);
      if (first < 0) first = k;
    }
    mesh.faces.insert(mesh.faces.end(), {first, first + 1, first + 2, first, first + 2, first + 3});
  }
}

// one band: four rings of n vertices (side bottom, side top, top cap, bottom cap)
void add_band(TriangleMesh& mesh, const core::ConeBand& band, int n) {
  const double(&uv)[2] = band.stripe ? kConeStripeTexcoord : kConeBodyTexcoord;
  const double taper =
      (band.radius_bottom_m - band.radius_top_m) / (band.z_top_m - band.z_bottom_m);
  const double norm = std::sqrt(1.0 + taper * taper);
  const int first = mesh.vertex_count();
  for (int ring = 0; ring < 4; ++ring) {
    const bool top = ring == 1 || ring == 2;
    const double r = top ? band.radius_top_m : band.radius_bottom_m;
    const double z = top ? band.z_top_m : band.z_bottom_m;
    for (int i = 0; i < n; ++i) {
      const double a = 2.0 * std::numbers::pi * i / n;
      const double c = std::cos(a), s = std::sin(a);
      if (ring < 2)
        add_vertex(mesh, r * c, r * s, z, c / norm, s / norm, taper / norm, uv);
      else
        add_vertex(mesh, r * c, r * s, z, 0.0, 0.0, ring == 2 ? 1.0 : -1.0, uv);
    }
  }

  // side quads as two triangles each, caps as fans (top facing up, bottom down)
  for (int i = 0; i < n; ++i) {
    const int j = (i + 1) % n;
    mesh.faces.insert(mesh.faces.end(), {first + i, first + j, first + n + j, first + i,
                                         first + n + j, first + n + i});
  }
  for (int i = 1; i + 1 < n; ++i) {
    mesh.faces.insert(mesh.faces.end(), {first + 2 * n, first + 2 * n + i, first + 2 * n + i + 1});
    mesh.faces.insert(mesh.faces.end(), {first + 3 * n, first + 3 * n + i + 1, first + 3 * n + i});
  }
}

}  // namespace

TriangleMesh cone_mesh(const core::ConeGeometry& shape, int segments) {
  TriangleMesh mesh;
  add_plate(mesh, shape);
  for (const core::ConeBand& band : shape.bands) add_band(mesh, band, segments);
  return mesh;
}

std::string cone_mesh_name(bool big) {
  return big ? "cone_big" : "cone_small";
}

std::string cone_texture_name(core::ConeClass c) {
  return "cone_" + std::string(core::to_string(c));
}

ConePaint cone_paint(core::ConeClass c) {
  constexpr ConePaint kBlue{{0.05, 0.22, 0.80}, {0.95, 0.95, 0.95}};
  constexpr ConePaint kYellow{{0.98, 0.82, 0.05}, {0.06, 0.06, 0.06}};
  constexpr ConePaint kOrange{{1.0, 0.42, 0.02}, {0.95, 0.95, 0.95}};
  constexpr ConePaint kPlainOrange{{1.0, 0.42, 0.02}, {1.0, 0.42, 0.02}};
  switch (c) {
    case core::ConeClass::kBlue:
      return kBlue;
    case core::ConeClass::kYellow:
      return kYellow;
    case core::ConeClass::kOrangeSmall:
    case core::ConeClass::kOrangeBig:
      return kOrange;
    case core::ConeClass::kUnknown:
      break;
  }
  return kPlainOrange;
}

std::string cone_assets() {
  std::ostringstream x;
  x.precision(6);

  // one mesh per size, with texture coordinates that pick body or stripe paint
  for (const bool big : {false, true}) {
    const TriangleMesh mesh =
        cone_mesh(core::cone_geometry(big ? core::ConeClass::kOrangeBig : core::ConeClass::kBlue));
    x << "    <mesh name=\"" << cone_mesh_name(big) << "\" vertex=\"";
    for (const double v : mesh.vertices) x << v << ' ';
    x << "\" normal=\"";
    for (const double v : mesh.normals) x << v << ' ';
    x << "\" texcoord=\"";
    for (const double v : mesh.texcoords) x << v << ' ';
    x << "\" face=\"";
    for (const int f : mesh.faces) x << f << ' ';
    x << "\"/>\n";
  }

  // per class a 2 x 2 checker: body colour in the texel at kConeBodyTexcoord, stripe colour in
  // the one at kConeStripeTexcoord
  for (const core::ConeClass c : kClasses) {
    const ConePaint p = cone_paint(c);
    x << "    <texture name=\"" << cone_texture_name(c) << "\" type=\"2d\" builtin=\"checker\" "
      << "width=\"2\" height=\"2\" rgb1=\"" << p.body[0] << ' ' << p.body[1] << ' ' << p.body[2]
      << "\" rgb2=\"" << p.stripe[0] << ' ' << p.stripe[1] << ' ' << p.stripe[2] << "\"/>\n";
  }
  return x.str();
}

}  // namespace conesim::vehicle_models
