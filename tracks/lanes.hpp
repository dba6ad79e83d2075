#pragma once
// Rebuilding the order of boundary cones when a format does not give it.

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

/// When the source gives no start pose: the middle of the big orange start gate (or the first
/// centre-line point), facing along the lanes. Adds a warning to the track.
void guess_start_pose(Track& track);

}  // namespace conesim::tracks
