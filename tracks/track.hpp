#pragma once
// The track: cones with stable ids and classes, the start pose, time-keeping gates and the
// ordered boundary lanes from which the centre line is derived.

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/cone.hpp"
#include "core/event.hpp"
#include "core/geometry.hpp"

namespace conesim::tracks {

using core::ConeClass;
using core::Pose2;
using core::Vec2;

using core::event_from_string;
using core::EventType;
using core::to_string;

/// One cone of the layout.
struct Cone {
  /// Stable id, unique within the track: the readers number the cones 0, 1, 2 ... in file
  /// order, so that whatever is kept per cone costs memory by the number of cones, never by
  /// the size of an id. The id a file gives is kept beside it (Track::file_id).
  int id = 0;
  ConeClass cls = ConeClass::kUnknown;
  /// Position of the cone's base centre in the track frame, metres.
  Vec2 position = Vec2::Zero();
  /// Position covariance when the source gives one (surveyed layouts), m^2.
  std::optional<Eigen::Matrix2d> covariance;
};

/// A time-keeping gate: the line between two photocell posts.
struct Gate {
  Vec2 left = Vec2::Zero();
  Vec2 right = Vec2::Zero();
};

/// A cone layout with everything the referee, the driver and the evaluator need.
struct Track {
  /// A short name, usually the file stem.
  std::string name;
  /// Every cone, each with a unique id.
  std::vector<Cone> cones;
  /// Pose the car starts from (rear axle centre is not implied: it is the reference point the
  /// importer gives, the front wing for fssim files).
  Pose2 start;
  /// Time-keeping gates in the order they are passed; the first starts the timing.
  std::vector<Gate> timing_gates;
  /// Left (blue) boundary: cone ids in driving order.
  std::vector<int> left_lane;
  /// Right (yellow) boundary: cone ids in driving order.
  std::vector<int> right_lane;
  /// True for a closed circuit (autocross, trackdrive): the last lane cone joins the first.
  bool closed = false;
  /// The event the layout was made for, when the source says so or it is recognised.
  std::optional<EventType> event;
  /// The driving line: derived from the lanes, or given by the layout (skidpad's figure eight).
  /// Closed circuits do not repeat the first point at the end.
  std::vector<Vec2> centre_line;
  /// Non-fatal oddities met while reading (a duplicate cone dropped, a guessed start pose).
  std::vector<std::string> warnings;
  /// The ids the file gave its cones (EUFS CSV's id column, anywhere in 0 .. 2^64 - 1), by cone
  /// id; empty when the file gave none. Every output a user reads shows these (file_id()).
  std::map<int, uint64_t> file_ids;

  /// The cone with this id; throws std::out_of_range when there is none. Constant time when
  /// the ids are the cones' places in `cones` (as the readers and the generator make them).
  const Cone& cone(int id) const;
  /// The id a user knows the cone by: the one its file gave, else its id.
  uint64_t file_id(int id) const;
  /// Positions of the cones of a lane, in order.
  std::vector<Vec2> lane_points(const std::vector<int>& lane) const;
  /// Number of cones of a class.
  int count(ConeClass c) const;
  /// The next free cone id.
  int next_id() const;
};

/// Builds the centre line from the ordered lanes: each left cone is paired with the nearest
/// point of the right boundary polyline and vice versa, the midpoints are ordered along the
/// lanes and resampled every spacing_m. Returns an empty line when either lane is empty, and
/// when the left lane or the midpoints' line is longer than kMaxCentreLineM (a malformed file).
std::vector<Vec2> derive_centre_line(const Track& track, double spacing_m = 1.0);

/// No centre line is derived along lanes, or through midpoints, longer than this (real courses
/// are under 2 km; the bound keeps a file with far-flung cones from asking for millions of
/// points), metres.
constexpr double kMaxCentreLineM = 20e3;

}  // namespace conesim::tracks
