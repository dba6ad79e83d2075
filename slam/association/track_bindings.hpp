#pragma once
// Tracking-aided association's memory (docs/architecture.md, "Association"): what each of the
// perception's tracks has been, frame by frame, by the frames' own evidence. A track that the
// evidence has tied to one landmark for several frames makes that landmark the likelier for its
// next observation; the observation's own likelihood still decides against it when it points
// clearly elsewhere (the track swapped cones), and a fresh track has no say at all.

#include <map>
#include <string>
#include <utility>
#include <vector>

namespace conesim::slam {

/// The evidence of a frame's observations, kept per perception track. Deterministic.
class TrackBindings {
 public:
  /// memory_frames: a vote loses 1/memory_frames of its weight each frame the track is seen
  /// again, so the binding follows a track that moved to another cone after a few frames.
  /// Throws std::invalid_argument unless memory_frames >= 1.
  explicit TrackBindings(double memory_frames = 10.0);

  /// What the track's history takes off the cost (d^2 + ln det S) of pairing its observation
  /// with a landmark: 2 ln(1 + v), v the track's decayed count of frames whose own evidence
  /// pointed at the landmark. The prior odds of two landmarks, with one vote of each added
  /// (Laplace), are (1 + v_a) / (1 + v_b), so the cost difference is twice their log. 0 for an
  /// observation without a track (-1) and for a landmark the track never pointed at.
  double bonus(int track, int landmark) const;

  /// The landmark with the largest vote of a track, -1 when none (for tests and reports).
  int bound_landmark(int track) const;

  /// Records one frame: the observation of track tracks[k] was, by its own evidence (the frame's
  /// association without the tracks, or the landmark it started), of landmark evidence[k]
  /// (-1: of none). Observations without a track (-1) are skipped. Tracks unseen for
  /// kForgetFrames frames are forgotten (the tracker does not reuse ids).
  void record(const std::vector<int>& tracks, const std::vector<int>& evidence);

  /// Tracks remembered now.
  int tracks() const { return static_cast<int>(tracks_.size()); }

  static constexpr int kForgetFrames = 20;

 private:
  struct Track {
    // (landmark id, decayed vote), at most a few entries
    std::vector<std::pair<int, double>> votes;
    int last_frame = 0;
  };
  double keep_;
  int frame_ = 0;
  std::map<int, Track> tracks_;
};

}  // namespace conesim::slam
