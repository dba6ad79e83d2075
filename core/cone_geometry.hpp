#pragma once
// The 3D shape of a track cone as the sensors see it: a square base plate and a tapered body cut
// into horizontal bands, each band either in the cone's body colour or its stripe colour. The
// camera's meshes (vehicle_models/cone_meshes.hpp) are built from it; the numbers match the
// LiDAR's sensors/cone_mesh.cpp, which could switch to this header (the MJCF builder in
// vehicle_models cannot include the sensors one).

#include <array>
#include <span>

#include "core/cone.hpp"

namespace conesim::core {

/// One horizontal band of a cone's body: a truncated cone between two heights.
struct ConeBand {
  /// Heights of the band's bottom and top above the ground, metres.
  double z_bottom_m;
  double z_top_m;
  /// Body radius at the band's bottom and top, metres.
  double radius_bottom_m;
  double radius_top_m;
  /// True for a stripe (white on blue and orange cones, black on yellow ones).
  bool stripe;
};

/// A cone class's shape: base plate plus bands from the bottom up. The base plate has the body
/// colour; the body is a truncated cone whose top is flat (the rounded tip is not modelled).
struct ConeGeometry {
  /// Side of the square base plate, metres (the FSG base width).
  double base_width_m;
  /// Thickness of the base plate, metres; the body starts on top of it.
  double plate_height_m;
  /// Total height including the plate, metres (the FSG cone height).
  double height_m;
  /// Bands from the bottom up; the first starts at plate_height_m, the last ends at height_m.
  std::span<const ConeBand> bands;
};

namespace detail {

// proportions shared with the LiDAR's sensors/cone_mesh.cpp: body bottom diameter 0.8 of the
// plate, flat top, stripes at fixed fractions of the height
constexpr double body_radius(double z, double plate, double height, double r0, double r1) {
  return r0 + (r1 - r0) * (z - plate) / (height - plate);
}

// small cone, 228 x 228 x 325 mm: body, one stripe at 35-62 % of the height, body
inline constexpr double kSmallPlate = 0.02, kSmallHeight = 0.325;
inline constexpr double kSmallR0 = 0.4 * 0.228, kSmallR1 = 0.025;
constexpr double small_radius(double z) {
  return body_radius(z, kSmallPlate, kSmallHeight, kSmallR0, kSmallR1);
}
inline constexpr double kSmallStripe[2] = {0.35 * kSmallHeight, 0.62 * kSmallHeight};
inline constexpr std::array<ConeBand, 3> kSmallBands{{
    {kSmallPlate, kSmallStripe[0], kSmallR0, small_radius(kSmallStripe[0]), false},
    {kSmallStripe[0], kSmallStripe[1], small_radius(kSmallStripe[0]), small_radius(kSmallStripe[1]),
     true},
    {kSmallStripe[1], kSmallHeight, small_radius(kSmallStripe[1]), kSmallR1, false},
}};

// big orange cone, 285 x 285 x 505 mm: stripes at 28-40 % and 56-68 % of the height
inline constexpr double kBigPlate = 0.025, kBigHeight = 0.505;
inline constexpr double kBigR0 = 0.4 * 0.285, kBigR1 = 0.03;
constexpr double big_radius(double z) {
  return body_radius(z, kBigPlate, kBigHeight, kBigR0, kBigR1);
}
inline constexpr double kBigStripes[4] = {0.28 * kBigHeight, 0.40 * kBigHeight, 0.56 * kBigHeight,
                                          0.68 * kBigHeight};
inline constexpr std::array<ConeBand, 5> kBigBands{{
    {kBigPlate, kBigStripes[0], kBigR0, big_radius(kBigStripes[0]), false},
    {kBigStripes[0], kBigStripes[1], big_radius(kBigStripes[0]), big_radius(kBigStripes[1]), true},
    {kBigStripes[1], kBigStripes[2], big_radius(kBigStripes[1]), big_radius(kBigStripes[2]), false},
    {kBigStripes[2], kBigStripes[3], big_radius(kBigStripes[2]), big_radius(kBigStripes[3]), true},
    {kBigStripes[3], kBigHeight, big_radius(kBigStripes[3]), kBigR1, false},
}};

}  // namespace detail

/// The shape of a cone class: big orange cones have their own, every other class the small one.
inline ConeGeometry cone_geometry(ConeClass c) {
  if (c == ConeClass::kOrangeBig)
    return {0.285, detail::kBigPlate, detail::kBigHeight, detail::kBigBands};
  return {0.228, detail::kSmallPlate, detail::kSmallHeight, detail::kSmallBands};
}

}  // namespace conesim::core
