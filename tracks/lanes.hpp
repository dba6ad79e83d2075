#pragma once
// Recovering the structure a format does not give: the order of boundary cones, whether the
// lanes close, the start pose and time-keeping gates made of big orange cones.

#include <vector>

#include "tracks/track.hpp"

namespace conesim::tracks {

/// Orders the cones with the given ids into a chain along the boundary, starting at the cone
/// nearest the start pose and walking in the start pose's direction of travel. Works for open
/// and closed layouts; cones that cannot be chained (outliers) are left out and returned in
/// `left_out` when it is given.
std::vector<int> order_lane(const Track& track, const std::vector<int>& cone_ids,
                            std::vector<int>* left_out = nullptr);

/// Rebuilds left_lane and right_lane from the blue and yellow cones (and orange cones that
/// continue a boundary), sets `closed` when both lanes close on themselves, and makes the
/// direction of travel keep blue on the left.
void rebuild_lanes(Track& track);

/// Extends the lanes of an open layout at both ends with the small orange cones (not yet in a lane)
/// that continue their line: the braking zone of an acceleration layout whose file lists it
/// apart (fssim's cones_orange).
void extend_open_lanes_with_orange(Track& track);

/// When the source gives no start pose: the middle of the first timing gate or of the big orange
/// start gate (else the first centre-line point, the first lane cones or the middle of the
/// cones), facing along the centre line or the lanes (else across the nearest blue/yellow
/// pair, blue on the left). Adds a warning to the track.
void guess_start_pose(Track& track);

/// True when the ordered lane closes on itself: its last cone is within a few metres of the
/// first one (about one cone spacing) and the lane is long enough to be a circuit.
bool lane_closes(const Track& track, const std::vector<int>& lane);

/// Puts lanes given in a file into driving order: reverses both when the left lane lies on the
/// right of the direction of travel (with a warning), and rotates closed lanes so that they
/// begin at the cone nearest the start pose.
void orient_lanes(Track& track);

/// Unit vector across the track near p, pointing from the right boundary to the left one:
/// taken from the lanes when both exist, else from the nearest blue and yellow cones, else the
/// start pose's left.
Vec2 left_direction_at(const Track& track, const Vec2& p);

/// left_direction_at for many places at once (the lanes indexed once).
std::vector<Vec2> left_directions_at(const Track& track, const std::vector<Vec2>& places);

/// Time-keeping gates made of the big orange cones: cones closer than 6 m to each other form a
/// group, the group is split into its left and right side (left_direction_at), and the gate
/// joins the middles of the two sides. Groups with cones on one side only give no gate.
std::vector<Gate> gates_from_big_orange(const Track& track);

}  // namespace conesim::tracks
