#pragma once
// Triangle meshes of the cones (core/cone_geometry.hpp) and their MJCF assets: one mesh per cone
// size and one two-texel texture per paint scheme, so that a whole cone is one draw call. The
// assets are not used by any geom, so they cost the physics nothing (ARCHITECTURE decision 1);
// the camera draws them into the scene each frame.

#include <string>
#include <vector>

#include "core/cone_geometry.hpp"

namespace conesim::vehicle_models {

/// Number of sides of the polygon that approximates a band's circular section.
inline constexpr int kConeMeshSegments = 16;

/// Texture coordinates that pick the body and the stripe colour from a cone texture.
inline constexpr double kConeBodyTexcoord[2] = {0.25, 0.25};
inline constexpr double kConeStripeTexcoord[2] = {0.75, 0.25};

/// A closed triangle mesh with one normal and one texture coordinate per vertex. Each face of
/// the plate and each band's side and caps have their own vertices, so edges stay sharp and
/// every band has one colour.
struct TriangleMesh {
  /// x y z of each vertex, metres.
  std::vector<double> vertices;
  /// Unit normal of each vertex.
  std::vector<double> normals;
  /// u v of each vertex: kConeBodyTexcoord or kConeStripeTexcoord.
  std::vector<double> texcoords;
  /// Three vertex indices per triangle, counter-clockwise seen from outside.
  std::vector<int> faces;

  /// Number of vertices.
  int vertex_count() const { return static_cast<int>(vertices.size() / 3); }
};

/// The mesh of a whole cone (plate and bands) in the cone frame: base centre on the ground, z up,
/// plate edges along x and y.
TriangleMesh cone_mesh(const core::ConeGeometry& shape, int segments = kConeMeshSegments);

/// Name of the MJCF mesh asset of the big orange cone (big) or of the small cones.
std::string cone_mesh_name(bool big);

/// Name of the MJCF texture asset of a cone class (body colour and stripe colour).
std::string cone_texture_name(core::ConeClass c);

/// RGB in 0-1 of the body and stripe paint of a cone class (FSG: blue with a white stripe,
/// yellow with a black stripe, orange with white stripes; unknown cones plain orange).
struct ConePaint {
  double body[3];
  double stripe[3];
};
ConePaint cone_paint(core::ConeClass c);

/// MJCF assets for inside <asset>: the cone meshes and one texture per cone class.
std::string cone_assets();

}  // namespace conesim::vehicle_models
