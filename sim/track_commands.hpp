#pragma once
// The `conesim track ...` commands as plain functions: the command line only wires them up.

#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "tracks/track.hpp"

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

/// Makes the layout of an event: the FSG skidpad or acceleration, or a generated circuit.
tracks::Track make_event_track(tracks::EventType event, uint64_t seed);

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
};

/// Plots the track with gnuplot: cones in their colours, lanes, centre line, start pose and
/// gates; rule violations marked when there is no overlay, the driven path and knocked cones
/// when there is one.
void plot_track(const tracks::Track& track, std::optional<tracks::EventType> event,
                const std::filesystem::path& out_png, const PlotOverlay* overlay = nullptr);

}  // namespace conesim::sim
