#pragma once
// Conversions between the SLAM back-ends' odometry and the SDK's, exact in every number: a
// built-in back-end run as a plug-in (graph_slam_plugin.cpp) gets what it gets built in.

#include <conesim/sdk.hpp>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "sdk/builtin/bridge.hpp"
#include "slam/backend.hpp"

namespace conesim::sdk_bridge {

/// The odometry between two frames into the SDK's type (the covariance row-major).
inline sdk::OdometryDelta to_sdk(const slam::OdometryDelta& o) {
  sdk::OdometryDelta out;
  out.from_us = o.from;
  out.to_us = o.to;
  out.delta = to_sdk(o.delta);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) out.covariance[3 * r + c] = o.covariance(r, c);
  out.distance_m = o.distance_m;
  out.speed_mps = o.speed_mps;
  out.yaw_rate_rps = o.yaw_rate_rps;
  return out;
}

/// The odometry between two frames from the SDK's type.
inline slam::OdometryDelta from_sdk(const sdk::OdometryDelta& o) {
  slam::OdometryDelta out;
  out.from = o.from_us;
  out.to = o.to_us;
  out.delta = from_sdk(o.delta);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) out.covariance(r, c) = o.covariance[3 * r + c];
  out.distance_m = o.distance_m;
  out.speed_mps = o.speed_mps;
  out.yaw_rate_rps = o.yaw_rate_rps;
  return out;
}

/// A built-in back-end behind the SDK's Slam interface: what GraphSLAM's plug-in and the other
/// back-ends' plug-in both are (graph_slam_plugin.cpp, slam_backends_plugin.cpp).
class BackendSlam : public sdk::Slam {
 public:
  explicit BackendSlam(std::unique_ptr<slam::Backend> backend) : backend_(std::move(backend)) {}

  void reset(const sdk::Pose2& start, sdk::TimeUs stamp_us,
             sdk::Span<sdk::MapCone> prior_map) override {
    backend_->reset(from_sdk(start), stamp_us);
    if (prior_map.empty()) return;
    std::vector<core::MapCone> map;
    for (const sdk::MapCone& c : prior_map) map.push_back(from_sdk(c));
    backend_->set_prior_map(map);
  }

  void process(const sdk::SlamInput& in) override {
    backend_->process({from_sdk(in.odometry), from_sdk(in.observations), {}});
    // what it did with each observation, and the landmarks the new ones started
    codes_.clear();
    started_.clear();
    for (const slam::Association& a : backend_->last_associations()) {
      codes_.push_back(a.code());
      started_.push_back(a.kind == slam::Association::Kind::kNew ? a.landmark_id : -1);
    }
  }

  sdk::Estimate estimate() const override { return to_sdk(backend_->estimate(), map_); }
  sdk::Span<int32_t> associations() const override { return {codes_.data(), codes_.size()}; }
  sdk::Span<int32_t> new_landmark_ids() const override {
    return {started_.data(), started_.size()};
  }
  int32_t loop_closures() const override { return backend_->loop_closures(); }

 private:
  std::unique_ptr<slam::Backend> backend_;
  std::vector<int32_t> codes_;
  std::vector<int32_t> started_;
  mutable std::vector<sdk::MapCone> map_;
};

}  // namespace conesim::sdk_bridge
