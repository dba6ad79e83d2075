#pragma once
// The SLAM figures of a run, drawn from what the scorer kept (sim/slam_score.hpp): per back-end
// its map over the true cones with the wrong associations marked, the map error per class over
// the distance driven, the trajectory and its error; and with several back-ends, their maps and
// map errors on shared plots, one colour each. report.html (sim/report.cpp) shows them.

#include <filesystem>
#include <string>
#include <vector>

#include "core/autonomy_types.hpp"
#include "sim/slam_score.hpp"
#include "tracks/track.hpp"

namespace conesim::sim {

/// Writes <csv_prefix>map.csv (every landmark with the true cone it matched),
/// <csv_prefix>map_error.csv and the figures <prefix>map.png, <prefix>map_error.png,
/// <prefix>trajectory.png and <prefix>error.png for one back-end into `dir`.
void write_slam_figures(const SlamScorer& scorer, const tracks::Track& track,
                        const core::Estimate& final_estimate, const std::filesystem::path& dir,
                        const std::string& prefix, const std::string& csv_prefix);

/// One back-end on the shared plots.
struct LaneFigures {
  std::string name;
  bool driving = false;
  const SlamScorer* scorer = nullptr;
  const core::Estimate* estimate = nullptr;
};

/// slam_lanes.png (every back-end's map error over distance) and slam_lanes_map.png (every
/// back-end's final map over the true cones), one colour per back-end.
void write_lanes_figures(const std::vector<LaneFigures>& lanes, const tracks::Track& track,
                         const std::filesystem::path& dir);

}  // namespace conesim::sim
