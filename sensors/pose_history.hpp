#pragma once
// The vehicle poses of the recent past, pushed by the harness every physics step, so that a
// sensor that fires over an interval (a spinning LiDAR) can ask for the pose at any instant.

#include <deque>

#include "core/measurements.hpp"
#include "core/time.hpp"

namespace conesim::sensors {

/// A time-ordered buffer of vehicle poses (vehicle frame in the track frame) that interpolates
/// between samples: linear in position, slerp in orientation.
class PoseHistory {
 public:
  /// Keeps the samples of the last keep_us microseconds (and always the newest two).
  explicit PoseHistory(core::TimeUs keep_us = core::kUsPerSecond);

  /// Appends the pose at time t. A sample at the newest time replaces it; an older time is a
  /// harness bug and throws std::invalid_argument.
  void push(core::TimeUs t, const core::Pose3& pose);

  /// True when no sample has been pushed (or all were cleared).
  bool empty() const { return samples_.empty(); }
  /// Time of the oldest sample kept; the history must not be empty.
  core::TimeUs oldest() const { return samples_.front().t; }
  /// Time of the newest sample; the history must not be empty.
  core::TimeUs newest() const { return samples_.back().t; }
  /// Number of samples kept.
  size_t size() const { return samples_.size(); }

  /// True when [from, to] lies inside the span of the samples.
  bool covers(core::TimeUs from, core::TimeUs to) const;

  /// The pose at time t, interpolated between the two samples around it; outside the span the
  /// nearest end is returned. The history must not be empty.
  core::Pose3 at(core::TimeUs t) const;

  /// The same pose as at(t), for callers that visit times in increasing order (the columns of
  /// a sweep): `cursor` starts at 0 and is passed back each time, so that the samples are
  /// walked once instead of searched at every call.
  core::Pose3 at(core::TimeUs t, size_t& cursor) const;

  /// Drops every sample.
  void clear() { samples_.clear(); }

 private:
  struct Sample {
    core::TimeUs t;
    core::Pose3 pose;
  };
  core::TimeUs keep_us_;
  std::deque<Sample> samples_;
};

}  // namespace conesim::sensors
