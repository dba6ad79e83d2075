#pragma once
// Large cone layouts for the cost benchmarks and tests (`conesim bench tracks`): a real circuit
// in a field of scattered cones, a long circuit with thousands of lane cones, and cones strewn
// at random, as a venue's cone map or a hostile file has them.

#include <cstdint>
#include <string>
#include <vector>

#include "tracks/track.hpp"

namespace conesim::sim {

/// The kinds of large layout.
enum class BigLayout {
  /// A generated trackdrive circuit (its lanes kept) among scattered cones of every class, at
  /// least 3 m off its lanes: a venue with clutter.
  kClutter,
  /// One long winding closed circuit, 3.5 m wide, every cone in a lane.
  kLong,
  /// Cones of random classes strewn uniformly, one per 25 m^2 (no lanes given).
  kRandom,
  /// The long circuit with one more cone (class unknown) 1000 km from it along x and y: a stray
  /// row in a file, which must not coarsen what the rest of the layout costs.
  kOutlier,
};

/// "clutter", "long", "random", "outlier".
const char* to_string(BigLayout kind);

/// A layout of about `cones` cones of the kind, the same for the same seed. Ids are the
/// track's own (0, 1, ...).
tracks::Track big_layout(BigLayout kind, int cones, uint64_t seed);

}  // namespace conesim::sim
