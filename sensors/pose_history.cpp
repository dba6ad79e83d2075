#include "sensors/pose_history.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace conesim::sensors {

PoseHistory::PoseHistory(core::TimeUs keep_us) : keep_us_(keep_us) {}

void PoseHistory::push(core::TimeUs t, const core::Pose3& pose) {
  // samples arrive in time order; the same instant again replaces the newest one
  if (!samples_.empty() && t <= samples_.back().t) {
    if (t == samples_.back().t) {
      samples_.back().pose = pose;
      return;
    }
    throw std::invalid_argument("PoseHistory::push: time " + std::to_string(t) +
                                " us is older than the newest sample " +
                                std::to_string(samples_.back().t) + " us");
  }
  samples_.push_back({t, pose});

  // forget what is older than the window, keeping at least two samples
  while (samples_.size() > 2 && samples_[1].t <= t - keep_us_) samples_.pop_front();
}

bool PoseHistory::covers(core::TimeUs from, core::TimeUs to) const {
  return !samples_.empty() && from <= to && samples_.front().t <= from && to <= samples_.back().t;
}

core::Pose3 PoseHistory::at(core::TimeUs t) const {
  // clamp outside the span
  if (t <= samples_.front().t) return samples_.front().pose;
  if (t >= samples_.back().t) return samples_.back().pose;

  // the first sample after t and the one before it
  const auto after = std::upper_bound(samples_.begin(), samples_.end(), t,
                                      [](core::TimeUs v, const Sample& s) { return v < s.t; });
  const auto before = after - 1;
  if (before->t == t) return before->pose;
  const double s = static_cast<double>(t - before->t) / static_cast<double>(after->t - before->t);
  return core::Pose3::interpolate(before->pose, after->pose, s);
}

core::Pose3 PoseHistory::at(core::TimeUs t, size_t& cursor) const {
  // clamp outside the span
  if (t <= samples_.front().t) return samples_.front().pose;
  if (t >= samples_.back().t) return samples_.back().pose;

  // the last sample at or before t: walk on from the cursor, or search when it is past t
  if (cursor + 1 >= samples_.size() || samples_[cursor].t > t) {
    const auto after = std::upper_bound(samples_.begin(), samples_.end(), t,
                                        [](core::TimeUs v, const Sample& s) { return v < s.t; });
    cursor = static_cast<size_t>(after - samples_.begin()) - 1;
  }
  while (samples_[cursor + 1].t <= t) ++cursor;

  // the same interpolation as at(t)
  const Sample& before = samples_[cursor];
  const Sample& after = samples_[cursor + 1];
  if (before.t == t) return before.pose;
  const double s = static_cast<double>(t - before.t) / static_cast<double>(after.t - before.t);
  return core::Pose3::interpolate(before.pose, after.pose, s);
}

}  // namespace conesim::sensors
