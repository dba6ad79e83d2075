#include "slam/association/track_bindings.hpp"

#include <cmath>
#include <stdexcept>

namespace conesim::slam {

TrackBindings::TrackBindings(double memory_frames) {
  if (!(memory_frames >= 1.0))
    throw std::invalid_argument("track bindings: memory_frames: expected >= 1, got " +
                                std::to_string(memory_frames));
  keep_ = 1.0 - 1.0 / memory_frames;
}

double TrackBindings::bonus(int track, int landmark) const {
  if (track < 0 || landmark < 0) return 0.0;
  const auto it = tracks_.find(track);
  if (it == tracks_.end()) return 0.0;
  for (const auto& [id, v] : it->second.votes)
    if (id == landmark) return 2.0 * std::log1p(v);
  return 0.0;
}

int TrackBindings::bound_landmark(int track) const {
  const auto it = tracks_.find(track);
  if (it == tracks_.end()) return -1;
  int best = -1;
  double best_v = 0.0;
  for (const auto& [id, v] : it->second.votes)
    if (v > best_v) best = id, best_v = v;
  return best;
}

void TrackBindings::record(const std::vector<int>& tracks, const std::vector<int>& evidence) {
  ++frame_;
  for (size_t k = 0; k < tracks.size() && k < evidence.size(); ++k) {
    if (tracks[k] < 0) continue;
    Track& t = tracks_[tracks[k]];
    t.last_frame = frame_;
    for (auto& [id, v] : t.votes) v *= keep_;
    std::erase_if(t.votes, [](const auto& e) { return e.second < 1e-3; });
    if (evidence[k] < 0) continue;
    bool found = false;
    for (auto& [id, v] : t.votes)
      if (id == evidence[k]) v += 1.0, found = true;
    if (!found) t.votes.emplace_back(evidence[k], 1.0);
  }
  std::erase_if(tracks_, [&](const auto& e) { return frame_ - e.second.last_frame > kForgetFrames; });
}

}  // namespace conesim::slam
