#pragma once
// Random FSG-compliant circuits for autocross and trackdrive, deterministic by seed.

#include <cstdint>

#include "tracks/rules.hpp"
#include "tracks/track.hpp"

namespace conesim::tracks {

/// What the generator aims for; every track it returns passes check_rules for the event.
struct GeneratorParams {
  EventType event = EventType::kTrackdrive;
  double min_lap_m = 200.0;
  double max_lap_m = 500.0;
  double width_m = 3.5;
  double cone_spacing_m = 4.5;
  /// Attempts before giving up (each attempt draws a new layout from the seed's stream).
  int max_attempts = 500;
};

/// Builds a closed circuit of straights, sweepers, hairpins, chicanes and slaloms, with blue
/// cones on the left, yellow on the right, big orange cones at the start/finish line and a start
/// pose behind it. Same seed, same track. Throws std::runtime_error if no compliant layout is
/// found within max_attempts.
Track generate_circuit(uint64_t seed, const GeneratorParams& params = {});

}  // namespace conesim::tracks
