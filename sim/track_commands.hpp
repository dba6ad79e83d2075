#pragma once
// The `conesim track ...` commands as plain functions: the command line only wires them up.

#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "laptime/lap_time.hpp"
#include "tracks/generator.hpp"
#include "tracks/track.hpp"
#include "vehicle_models/vehicle_params.hpp"

namespace conesim::sim {

/// Exit codes shared by the commands.
inline constexpr int kExitOk = 0;
inline constexpr int kExitViolations = 1;
inline constexpr int kExitBadInput = 2;
/// Not for any input: a bug in conesim (or a failing machine), reported with its message.
inline constexpr int kExitInternalError = 3;

/// Reads each file and checks it against the rules of `event` (inferred per file when empty).
/// Unreadable files print "file:line: what was expected" to `err` and give exit 2; rule
/// violations are printed to `out` and give exit 1 only when `strict`.
int track_validate(const std::vector<std::filesystem::path>& files,
                   std::optional<tracks::EventType> event, bool strict, std::ostream& out,
                   std::ostream& err);

/// The `track info` JSON: cones per class, length_m, min_width_m, max_spacing_m, min_radius_m,
/// violations, plus event, closed and warnings.
nlohmann::json track_info(const tracks::Track& track, std::optional<tracks::EventType> event);

/// Makes the layout of an event: the FSG skidpad or acceleration, or a generated circuit drawn
/// with `circuit` (its event is replaced by `event`).
tracks::Track make_event_track(tracks::EventType event, uint64_t seed,
                               tracks::GeneratorParams circuit = {});

/// What `track corpus` writes.
struct CorpusOptions {
  /// Layouts to write.
  int count = 10;
  /// Seed of the first layout; layout i has seed + i.
  uint64_t seed = 0;
  /// Profiles taken in turn (layout i has profiles[i % size]).
  std::vector<tracks::GeneratorProfile> profiles = {tracks::GeneratorProfile::kHard};
  /// Events taken in turn (autocross, trackdrive).
  std::vector<tracks::EventType> events = {tracks::EventType::kTrackdrive};
  tracks::TravelDirection direction = tracks::TravelDirection::kFromSeed;
  /// Outside diameter of the minimum hairpins, metres (GeneratorParams).
  double hairpin_outer_diameter_m = tracks::GeneratorParams{}.hairpin_outer_diameter_m;
  /// Folder of the files and index.json; created when missing.
  std::filesystem::path out_dir;
  /// File format by extension: "csv" (EUFS CSV) or "yaml" (PacSim YAML).
  std::string format = "csv";
  /// The car the index's lap-time bounds are for.
  vehicle_models::VehicleParams vehicle;
};

/// Writes the corpus: one file per layout named <profile>-<event>-<seed>.<format>, and
/// index.json listing each file with its profile, event, seed, direction, features, length,
/// narrowest width, rule violations and lap-time bound. A seed that yields no compliant layout
/// is reported on `err` and skipped. Returns the exit code: 0 when every layout was written
/// and complies with its event's rules strictly, 1 otherwise.
int track_corpus(const CorpusOptions& options, std::ostream& out, std::ostream& err);

/// The `track laptime` JSON: event, lap_time_s, line_length_m, top_speed_mps, min_speed_mps,
/// grip_fraction, vehicle (and message when the bound is not usable).
nlohmann::json lap_time_json(const tracks::Track& track, const laptime::LapTimeBound& bound,
                             const vehicle_models::VehicleParams& vehicle, double grip_fraction);

/// Writes the bound's speed profile as CSV: s_m,speed_mps,x_m,y_m.
void write_speed_profile_csv(const laptime::LapTimeBound& bound, const std::filesystem::path& out);

/// Writes a track by the output's extension, all or nothing (a temporary file is renamed).
void write_track_atomically(const tracks::Track& track, const std::filesystem::path& out);

/// What a run adds on top of the track in its top-down figure.
struct PlotOverlay {
  /// The path the car drove (true positions).
  std::vector<core::Vec2> driven_path;
  /// Ids of the cones knocked over.
  std::vector<int> knocked_cones;
  /// A line under the title (result summary).
  std::string subtitle;
  /// A referee event drawn where it happened, with a short label ("off-course 1, lap 3").
  struct Mark {
    enum class Kind { kConeHit, kOffCourse, kDnf };
    Kind kind = Kind::kOffCourse;
    core::Vec2 where = core::Vec2::Zero();
    std::string label;
  };
  std::vector<Mark> marks;
  /// The car's speed at each point of driven_path, m/s: the path is coloured by it when given.
  std::vector<double> driven_speed_mps;
  /// Where each lap was counted, with its label ("lap 2: 31.40 s").
  std::vector<std::pair<core::Vec2, std::string>> lap_ends;
};

/// Plots the track with gnuplot: cones in their colours, lanes, centre line, start pose and
/// gates; rule violations marked when there is no overlay, the driven path and knocked cones
/// when there is one.
void plot_track(const tracks::Track& track, std::optional<tracks::EventType> event,
                const std::filesystem::path& out_png, const PlotOverlay* overlay = nullptr);

}  // namespace conesim::sim
