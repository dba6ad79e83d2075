#pragma once
// The optimal one-to-one assignment (Hungarian): the scorers match maps and detections to the
// true cones with it, the cone tracker observations to tracks.

#include <Eigen/Core>
#include <vector>

namespace conesim::core {

/// The optimal one-to-one assignment of rows to columns of `cost` (any shape). Pairs whose cost
/// exceeds `cutoff` (or is NaN or infinite) are never assigned. Among the assignments that pair as
/// many rows as the cut-off allows, returns the one of least total cost: the matching is maximal
/// first and cheapest second, so a far-but-allowed pair is never dropped to save cost. Returns for
/// each row its column, or -1. Deterministic; O(n^3) on each group of rows and columns linked by
/// allowed pairs, so sparse problems (a map against its true cones at a 1 m cut-off) are fast.
std::vector<int> hungarian_assign(const Eigen::MatrixXd& cost, double cutoff);

}  // namespace conesim::core
