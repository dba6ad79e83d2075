#pragma once
// The ground under a layout (issue 17): one height model for the physics, the LiDAR, the camera
// and the cones standing on it. Flat (z = 0 everywhere) by default; otherwise a venue grade, a
// crown falling away from the driving line, long undulations and small bumps, drawn from the
// scenario seed on a stream of their own and sampled on a regular grid that every consumer
// shares: the MuJoCo height field, the LiDAR's triangle mesh and height() are the same surface.

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "tracks/track.hpp"

namespace conesim::tracks {

/// The scenario's `world.ground` block. All zero: the flat plane of today.
struct GroundConfig {
  /// Rise per 100 m along the grade's heading, percent.
  double grade_percent = 0.0;
  /// Heading the ground rises towards, degrees from the track's x axis; drawn from the seed when
  /// not given.
  std::optional<double> grade_heading_deg;
  /// Cross fall on each side of the driving line, percent (a crowned road: highest on the line,
  /// rounded over its middle 3 m, falling at this rate out to 8 m from it).
  double crown_percent = 0.0;
  /// Long undulations: three waves of random heading, each of a third of this amplitude, metres.
  double undulation_amplitude_m = 0.0;
  /// Their mean wavelength (each wave 0.7-1.4 times it), metres.
  double undulation_wavelength_m = 40.0;
  /// Small bumps: domes of a cos^2 profile, 0.5-1 times this high, metres.
  double bump_height_m = 0.0;
  /// Their radius, metres.
  double bump_radius_m = 0.5;
  /// How many bumps stand on 100 square metres of ground.
  double bumps_per_100m2 = 0.0;
  /// Added to the scenario seed: another ground on the same layout and run.
  uint64_t seed_offset = 0;

  /// True when nothing makes the ground other than the plane z = 0.
  bool flat() const;
  /// Empty when valid, else "key: expected ...".
  std::string validate() const;
};

/// The heights of the ground on a regular grid: vertex (i, j) stands at (x0 + i cell, y0 + j
/// cell, z[j nx + i]); each cell is two triangles split along its diagonal from (i, j) to
/// (i + 1, j + 1).
struct GroundGrid {
  double x0 = 0.0, y0 = 0.0, cell_m = 1.0;
  int nx = 0, ny = 0;
  std::vector<float> z;
  double min_z = 0.0, max_z = 0.0;
  /// The grade's plane z = slope . (x, y) + plane_z0, and how far the ground lies above it at
  /// most and at least (the crown, the undulations and the bumps): a ray can meet the ground
  /// only where its height above the plane lies within [residual_min, residual_max].
  Eigen::Vector2d slope = Eigen::Vector2d::Zero();
  double plane_z0 = 0.0;
  double residual_min = 0.0, residual_max = 0.0;

  /// The height at a vertex.
  double at(int i, int j) const { return z[static_cast<size_t>(j) * nx + i]; }
};

/// The ground: flat, or a height field over the layout and a margin around it.
class GroundModel {
 public:
  /// The flat plane z = 0.
  GroundModel() = default;
  /// The ground for a layout: deterministic for (track, config, seed); flat for a flat config.
  /// Throws std::invalid_argument for a config that fails validate().
  GroundModel(const Track& track, const GroundConfig& config, uint64_t scenario_seed);

  /// True for the plane z = 0 (no grid).
  bool flat() const { return grid_.z.empty(); }
  /// The ground's height at a point, metres (beyond the grid: the nearest edge's height).
  double height(double x, double y) const;
  /// The ground's upward unit normal at a point.
  Eigen::Vector3d normal(double x, double y) const;
  /// The grid (empty when flat).
  const GroundGrid& grid() const { return grid_; }

 private:
  GroundGrid grid_;
};

}  // namespace conesim::tracks
