#pragma once
// Reading and writing cone layouts in the public formats.
//
// Readers: fssim YAML, PacSim YAML, EUFS CSV (with or without the header line, as FSDS writes
// it), EPFL CSV. Writers: PacSim YAML and EUFS CSV. Every reader throws core::InputError
// naming the file, the line (CSV, YAML marks) or key, and what was expected.

#include <filesystem>
#include <string>

#include "tracks/track.hpp"

namespace conesim::tracks {

/// The formats conesim reads.
enum class TrackFormat { kFssimYaml, kPacsimYaml, kEufsCsv, kEpflCsv };

/// Largest track file accepted, bytes (a real layout is a few tens of kilobytes).
inline constexpr std::uintmax_t kMaxTrackFileBytes = 16u << 20;

/// Reads a track file, telling the format from its extension and content. The result has
/// unique cone ids, ordered lanes with blue on the left of the direction of travel (rebuilt
/// where the format does not give the order), a start pose, gates and a centre line.
Track read_track(const std::filesystem::path& file);

/// Parses track text already in memory; `name` stands for the file in error messages.
Track parse_track(const std::string& text, TrackFormat format, const std::string& name);

/// Writes PacSim YAML (lanes in driving order, gates as time_keeping, the rest as unknown).
void write_pacsim_yaml(const Track& track, const std::filesystem::path& file);

/// Writes EUFS CSV with the header line, a car_start row and each cone's id in the
/// `direction` column position's neighbour... see io.cpp for the exact column use.
void write_eufs_csv(const Track& track, const std::filesystem::path& file);

/// Writes by extension: .yaml/.yml PacSim YAML, .csv EUFS CSV; throws InputError otherwise.
void write_track(const Track& track, const std::filesystem::path& file);

}  // namespace conesim::tracks
