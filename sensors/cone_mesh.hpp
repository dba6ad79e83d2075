#pragma once
// The geometry of an FSG cone as the LiDAR sees it: a square base plate and a truncated cone
// body painted in horizontal bands, each band a surface material with its own reflectivity.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string_view>
#include <vector>

#include "core/cone.hpp"
#include "core/cone_geometry.hpp"

namespace conesim::sensors {

/// A paint or surface the LiDAR can hit; the reflectivity of each is configured.
enum class SurfaceMaterial : uint8_t { kGround, kBlue, kYellow, kOrange, kWhite, kBlack };

/// Number of SurfaceMaterial values.
inline constexpr int kSurfaceMaterialCount = 6;

/// The name of a material: ground, blue, yellow, orange, white, black.
std::string_view to_string(SurfaceMaterial m);

/// A horizontal band of the cone body between two heights above the ground.
struct ConeBand {
  double from_m = 0.0;
  double to_m = 0.0;
  SurfaceMaterial material = SurfaceMaterial::kOrange;
};

/// The shape of one cone class in its own frame: the base centre on the ground at the origin,
/// z up, the base plate's edges along x and y.
struct ConeShape {
  /// Side of the square base plate (the class's base width).
  double plate_width_m = 0.0;
  /// Thickness of the base plate; the body starts on top of it.
  double plate_height_m = 0.0;
  /// Radius of the body where it meets the plate.
  double body_bottom_radius_m = 0.0;
  /// Radius of the flat top.
  double body_top_radius_m = 0.0;
  /// Total height above the ground (the class's height).
  double height_m = 0.0;
  /// Paint of the base plate.
  SurfaceMaterial plate_material = SurfaceMaterial::kOrange;
  /// Body bands from the plate's top to the top, ascending and contiguous.
  std::vector<ConeBand> bands;

  /// Radius of the body at height z (clamped to the body's height range).
  double body_radius_at(double z_m) const;
  /// Material of the surface at height z: the plate below its top, then the bands.
  SurfaceMaterial material_at(double z_m) const;
  /// Distance from a point in the cone frame to the nearest surface of the exact shape
  /// (plate box or body of revolution including its top).
  double surface_distance(const Eigen::Vector3d& p) const;
};

/// The shape of a cone class from core::cone_geometry (small cones 228 x 228 x 325 mm, big cones
/// 285 x 285 x 505 mm, as the camera draws them), painted blue with a white band, yellow with a
/// black band, small orange with a white band, big orange with two white bands. Unknown cones
/// are plain small orange cones.
ConeShape cone_shape(core::ConeClass cls);

/// A triangle mesh with one material per triangle.
struct ConeMesh {
  std::vector<Eigen::Vector3f> vertices;
  std::vector<std::array<uint32_t, 3>> triangles;
  std::vector<SurfaceMaterial> materials;
};

/// Tessellates a shape with a polygon of `sides` sides for the body (vertices on the exact
/// radius, so the mesh lies inside the shape by at most facet_deviation_m()). The plate's
/// underside is left out: it lies on the ground.
ConeMesh build_cone_mesh(const ConeShape& shape, int sides);

/// Largest distance between the tessellated body and the exact one: r (1 - cos(pi / sides)).
double facet_deviation_m(const ConeShape& shape, int sides);

}  // namespace conesim::sensors
