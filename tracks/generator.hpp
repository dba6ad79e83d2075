#pragma once
// Random FSG-compliant circuits for autocross and trackdrive, deterministic by seed.

#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

#include "tracks/rules.hpp"
#include "tracks/track.hpp"

namespace conesim::tracks {

/// The kind of layout the generator draws. kStandard is the everyday mix; the others seek the
/// hard cases of the rules on purpose (each still passes check_rules strictly):
/// - kHairpins: three or more hairpins at the FSG minimum, 9.2-9.5 m outside diameter (or at
///   GeneratorParams::hairpin_outer_diameter_m);
/// - kSlalom: two or three slaloms of four to eight half waves;
/// - kChicanes: three or more tight S-bends (6-9 m radius);
/// - kNarrow: 3.05 m lanes throughout, cones dense enough in turns that the width holds;
/// - kStraightIntoHairpin: a 75-78 m straight (as the rule checker measures it) through the start
/// into a minimum hairpin;
/// - kHard: all of these together (narrow lanes, minimum hairpins, chicanes and a slalom, the
///   long straight into a hairpin).
enum class GeneratorProfile {
  kStandard,
  kHairpins,
  kSlalom,
  kChicanes,
  kNarrow,
  kStraightIntoHairpin,
  kHard
};

/// Direction of travel around the circuit.
enum class TravelDirection { kFromSeed, kCounterClockwise, kClockwise };

/// The profile's name on the command line: standard, hairpins, slalom, chicanes, narrow,
/// straight-into-hairpin, hard.
std::string_view to_string(GeneratorProfile profile);
/// The profile of a name; "mixed" is another name of "hard". nullopt for an unknown name.
std::optional<GeneratorProfile> profile_from_string(std::string_view name);
/// Every profile, kStandard first.
std::vector<GeneratorProfile> all_profiles();

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
  /// Attempts before giving up (each attempt draws a new layout from the seed's stream). The
  /// standard profile needs about 5, the hard profiles up to a few hundred (1-5 % of the drawn
  /// layouts are kept); a seed's track does not depend on this once it is found.
  int max_attempts = 2000;
  /// The kind of layout; kStandard keeps the tracks of earlier versions seed for seed.
  GeneratorProfile profile = GeneratorProfile::kStandard;
  /// Clockwise or counter-clockwise; kFromSeed draws it (both occur about equally often).
  TravelDirection direction = TravelDirection::kFromSeed;
  /// Outside diameter of the profiles' minimum hairpins (drawn up to 0.3 m more), metres. The
  /// default is the FSG minimum, 9 m, plus 0.2 m for the rule checker's fit to the cones. The
  /// default car's front corner sweeps 8.5 m at full lock (tests/sim/grip_slow_test.cpp).
  double hairpin_outer_diameter_m = 9.2;
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
  /// True when the lap turns clockwise overall (right-hand turns outnumber left ones by 360 deg).
  bool clockwise = false;
  /// Smallest designed outside diameter of a hairpin (outer boundary), metres.
  double min_hairpin_outer_diameter_m = 0.0;
  /// Longest straight of the design (straight pieces in a row), metres.
  double longest_straight_m = 0.0;
};

/// Builds a closed circuit of straights, sweepers, hairpins, chicanes and slaloms, with blue
/// cones on the left, yellow on the right, big orange cones at the start/finish line and a start
/// pose behind it. Same seed, same track. Track frame: the start pose at the origin facing +x,
/// the start line (and its timing gate) 6 m ahead; the lanes and the designed centre line (every
/// ~1 m) begin at the start line. Named "generated-<seed>", or "generated-<profile>-<seed>"
/// for the other profiles. Throws std::invalid_argument for parameters no compliant
/// layout can meet, std::runtime_error if no compliant layout is found within max_attempts.
Track generate_circuit(uint64_t seed, const GeneratorParams& params = {});

/// As above, and fills `report` (when not null) with the attempts it took.
Track generate_circuit(uint64_t seed, const GeneratorParams& params, GenerationReport* report);

}  // namespace conesim::tracks
