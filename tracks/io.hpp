#pragma once
// Reading and writing cone layouts in the public formats.
//
// Readers: fssim YAML, PacSim YAML, EUFS CSV (with or without the header line, as FSDS writes
// it), EPFL CSV. Writers: PacSim YAML and EUFS CSV. Every reader throws core::InputError
// naming the file, the line (CSV, YAML marks) or key, and what was expected.
//
// How the formats map onto a Track:
// - fssim: cones_left blue (left lane, file order), cones_right yellow (right lane),
//   cones_orange small orange, cones_orange_big big orange, tk_device posts paired into gates,
//   starting_pose_front_wing [x, y, yaw] the start (the front wing, not the rear axle).
// - PacSim: left/right lanes in file order (any class; invisible and timekeeping entries are
//   not cones and are skipped with a warning), unknown: cones in no lane, time_keeping: every
//   entry is a gate post whatever its class (as PacSim's loader reads it), consecutive posts
//   form a gate; start yaw = orientation[2]; lanesFirstWithLastConnected gives `closed`.
//   earthToTrack is the geodetic origin (lat, lon, alt) and ENU rotation of the track frame
//   that PacSim's GNSS model uses; cone positions are already in the track frame, so it is not
//   applied (a non-zero one gives a warning) and writers emit zeros.
// - EUFS CSV: car_start is the start pose (yaw in the direction column); midpoint and
//   inactive_noise rows are skipped; conesim's own files add an id column and a lane column
//   (left/right in driving order, closed/open on the car_start row) that give the lanes.
// - EPFL CSV: no start pose (guessed); std_X/std_Y give a diagonal covariance.
// - CSV formats give no lanes or gates: lanes are rebuilt (tracks/lanes.hpp), and each group of
//   big orange cones on both sides of the track becomes a gate, ordered along the track.
// - Closed when the file says so (PacSim) or both lanes close on themselves; cones of one class
//   within 1 cm of each other are one cone listed twice: the copy is dropped with a warning.
// - The event is set from the name (skidpad, accel...); ids run 0..n-1 in file order.

#include <cstdint>
#include <filesystem>
#include <string>

#include "tracks/track.hpp"

namespace conesim::tracks {

/// The formats conesim reads.
enum class TrackFormat { kFssimYaml, kPacsimYaml, kEufsCsv, kEpflCsv };

/// Largest track file accepted, bytes (a real layout is a few tens of kilobytes).
inline constexpr std::uintmax_t kMaxTrackFileBytes = 16u << 20;

/// Most cones a layout may have: real ones have a few hundred, a whole venue's cone map a few
/// thousand; every track operation costs O(n log n) in them (tests/bench/track_bench.cpp).
inline constexpr std::size_t kMaxTrackCones = 100000;

/// Reads a track file, telling the format from its extension and content. The result has
/// unique cone ids, ordered lanes with blue on the left of the direction of travel (rebuilt
/// where the format does not give the order), a start pose, gates and a centre line.
Track read_track(const std::filesystem::path& file);

/// Parses track text already in memory; `name` stands for the file in error messages.
Track parse_track(const std::string& text, TrackFormat format, const std::string& name);

/// Writes PacSim YAML: lanes in driving order as left/right, gates as pairs of time_keeping
/// posts (left first), every other cone under unknown with its class, the start pose, an
/// identity earthToTrack and lanesFirstWithLastConnected = closed. Cone ids and covariances
/// are not part of the format; a reader numbers the cones in file order.
void write_pacsim_yaml(const Track& track, const std::filesystem::path& file);

/// The text write_pacsim_yaml writes.
std::string pacsim_yaml_text(const Track& track);

/// Writes EUFS CSV: the header tag,x,y,direction,x_variance,y_variance,xy_covariance plus the
/// `id` and `lane` columns that read_track reads back, a car_start row (yaw in the direction
/// column, `closed` or `open` in the lane column), then the left lane and the right lane in
/// driving order (lane `left`, `right`) and the remaining cones by id. The lanes and whether
/// they close read back as written, so a CSV -> YAML -> CSV round trip keeps them (a figure
/// eight whose lanes cannot be rebuilt from the colours alone stays closed). Classes are
/// written as blue, yellow, orange, big_orange and unknown; gates are not written (a reader
/// makes them again from the big orange cones).
void write_eufs_csv(const Track& track, const std::filesystem::path& file);

/// The text write_eufs_csv writes.
std::string eufs_csv_text(const Track& track);

/// Writes by extension: .yaml/.yml PacSim YAML, .csv EUFS CSV; throws InputError otherwise.
void write_track(const Track& track, const std::filesystem::path& file);

}  // namespace conesim::tracks
