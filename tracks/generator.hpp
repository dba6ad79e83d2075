#pragma once
// Random FSG-compliant circuits for autocross and trackdrive, deterministic by seed.

#include <cstdint>

#include "tracks/rules.hpp"
#include "tracks/track.hpp"

namespace conesim::tracks {

/// What the generator aims for; every track it returns passes check_rules for the event.
struct GeneratorParams {
  /// The event the track is for: autocross or trackdrive (same layout, same rules here).
  EventType event = EventType::kTrackdrive;
  /// Shortest lap accepted (centre line), metres.
  double min_lap_m = 200.0;
  /// Longest lap accepted (centre line), metres.
  double max_lap_m = 500.0;
  /// Narrowest track width; sections are drawn between this and 0.8 m more, metres.
  double width_m = 3.5;
  /// Cone spacing along a boundary on straights; tighter in turns (3 m in hairpins), metres.
  double cone_spacing_m = 4.5;
  /// Attempts before giving up (each attempt draws a new layout from the seed's stream).
  int max_attempts = 500;
};

/// What one call of generate_circuit did, for tuning and benchmarks.
struct GenerationReport {
  /// Layouts drawn, the accepted one included.
  int attempts = 0;
  /// Drawn layouts rejected by the generator's own geometry checks (clearance, length, ...).
  int rejected_geometry = 0;
  /// Layouts that passed the geometry checks but broke a rule of check_rules.
  int rejected_rules = 0;
  /// Primitives of the accepted layout, by kind.
  int hairpins = 0;
  int chicanes = 0;
  int slaloms = 0;
  int sweepers = 0;
  int corners = 0;
  /// Centre-line length of the accepted lap, metres.
  double lap_m = 0.0;
};

/// Builds a closed circuit of straights, sweepers, hairpins, chicanes and slaloms, with blue
/// cones on the left, yellow on the right, big orange cones at the start/finish line and a start
/// pose behind it. Same seed, same track. Track frame: the start pose at the origin facing +x,
/// the start line (and its timing gate) 6 m ahead; the lanes and the designed centre line (every
/// ~1 m) begin at the start line. Throws std::invalid_argument for parameters no compliant
/// layout can meet, std::runtime_error if no compliant layout is found within max_attempts.
Track generate_circuit(uint64_t seed, const GeneratorParams& params = {});

/// As above, and fills `report` (when not null) with the attempts it took.
Track generate_circuit(uint64_t seed, const GeneratorParams& params, GenerationReport* report);

}  // namespace conesim::tracks
