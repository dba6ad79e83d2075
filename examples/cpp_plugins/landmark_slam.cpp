// A small landmark SLAM: dead reckoning on conesim's odometry, nearest-neighbour association
// of each cone to the map, a rigid 2D alignment of the matched cones that pulls the pose back
// onto the map, and landmarks as running means of their sightings with a class vote. A cone
// starts a tentative landmark only where no landmark is near; a tentative one not seen again
// within a few frames is dropped. The map is complete once the car comes back to the start
// after a lap. With a prior map (skidpad) it only localises.
//
// config: {gate_m: 1.0, correction_gain: 0.5, confirm_sightings: 2}

#include <algorithm>
#include <cmath>
#include <conesim/sdk.hpp>
#include <stdexcept>
#include <vector>

namespace {

using namespace conesim::sdk;

class LandmarkSlam final : public Slam {
 public:
  LandmarkSlam(const RunInfo&, const Config& config) {
    static const char* const kKnown[] = {"gate_m", "correction_gain", "confirm_sightings", nullptr};
    config.require_known(kKnown);
    gate_m_ = config.number("gate_m", 1.0);
    gain_ = config.number("correction_gain", 0.5);
    confirm_ = static_cast<int>(config.number("confirm_sightings", 2));
    if (!(gate_m_ > 0.0)) throw std::invalid_argument("gate_m: expected a distance > 0");
    if (!(gain_ >= 0.0 && gain_ <= 1.0))
      throw std::invalid_argument("correction_gain: expected 0 to 1");
  }

  void reset(const Pose2& start, TimeUs stamp_us, Span<MapCone> prior_map) override {
    pose_ = start;
    start_ = start;
    stamp_ = stamp_us;
    travelled_m_ = 0.0;
    landmarks_.clear();
    for (const MapCone& c : prior_map)
      landmarks_.push_back({c.id, c.cls, c.x_m, c.y_m, 1000, 0, {}});
    localising_ = !prior_map.empty();
    complete_ = localising_;
    next_id_ = 0;
    for (const Landmark& l : landmarks_) next_id_ = std::max(next_id_, l.id + 1);
  }

  void process(const SlamInput& in) override {
    // predict with the odometry
    pose_ = compose(pose_, in.odometry.delta);
    stamp_ = in.odometry.to_us;
    speed_ = in.odometry.speed_mps;
    yaw_rate_ = in.odometry.yaw_rate_rps;
    travelled_m_ += in.odometry.distance_m;
    ++frame_;
    // tentative landmarks not seen again within a few frames were clutter or a misplacement
    std::erase_if(landmarks_, [this](const Landmark& l) {
      return l.sightings < confirm_ && frame_ - l.last_frame > 5;
    });

    // associate each cone with the nearest landmark of a compatible class within the gate
    associations_.assign(in.observations.cones.size, -2);
    started_.assign(in.observations.cones.size, -1);
    std::vector<int> matched(in.observations.cones.size, -1);
    std::vector<double> wx(in.observations.cones.size), wy(in.observations.cones.size);
    for (uint64_t i = 0; i < in.observations.cones.size; ++i) {
      const ConeObservation& o = in.observations.cones[i];
      transform(pose_, o.x_m, o.y_m, &wx[i], &wy[i]);
      int best = -1;
      double best_d = gate_m_;
      for (size_t k = 0; k < landmarks_.size(); ++k) {
        const Landmark& l = landmarks_[k];
        if (o.cls != ConeClass::kUnknown && l.cls != ConeClass::kUnknown && o.cls != l.cls)
          continue;
        const double d = std::hypot(wx[i] - l.x, wy[i] - l.y);
        if (d < best_d) best_d = d, best = static_cast<int>(k);
      }
      matched[i] = best;
    }

    // align: the rotation and shift that best map the matched sightings onto their landmarks
    // (2D Kabsch), applied to the pose with the gain
    double pcx = 0, pcy = 0, qcx = 0, qcy = 0;
    int n = 0;
    for (size_t i = 0; i < matched.size(); ++i)
      if (matched[i] >= 0 && landmarks_[matched[i]].sightings >= confirm_) {
        pcx += wx[i], pcy += wy[i], qcx += landmarks_[matched[i]].x,
            qcy += landmarks_[matched[i]].y;
        ++n;
      }
    if (n >= 2) {
      pcx /= n, pcy /= n, qcx /= n, qcy /= n;
      double sxx = 0, sxy = 0, syx = 0, syy = 0;
      for (size_t i = 0; i < matched.size(); ++i)
        if (matched[i] >= 0 && landmarks_[matched[i]].sightings >= confirm_) {
          const double px = wx[i] - pcx, py = wy[i] - pcy;
          const double qx = landmarks_[matched[i]].x - qcx, qy = landmarks_[matched[i]].y - qcy;
          sxx += px * qx, sxy += px * qy, syx += py * qx, syy += py * qy;
        }
      const double angle = gain_ * std::atan2(sxy - syx, sxx + syy);
      const double c = std::cos(angle), s = std::sin(angle);
      // the pose moved as the points are: about their centroid, then by the centroids' gap
      const double dx = pose_.x_m - pcx, dy = pose_.y_m - pcy;
      pose_.x_m = pcx + c * dx - s * dy + gain_ * (qcx - pcx);
      pose_.y_m = pcy + s * dx + c * dy + gain_ * (qcy - pcy);
      pose_.yaw_rad = normalize_angle(pose_.yaw_rad + angle);
    }

    // update the map from the corrected pose: running means, and new landmarks
    for (uint64_t i = 0; i < in.observations.cones.size; ++i) {
      const ConeObservation& o = in.observations.cones[i];
      transform(pose_, o.x_m, o.y_m, &wx[i], &wy[i]);
      if (matched[i] >= 0) {
        Landmark& l = landmarks_[matched[i]];
        associations_[i] = l.id;
        l.last_frame = frame_;
        if (localising_) continue;
        const int w = std::min(l.sightings, 50);
        l.x = (l.x * w + wx[i]) / (w + 1);
        l.y = (l.y * w + wy[i]) / (w + 1);
        vote(l, o.cls);
        ++l.sightings;
      } else if (!localising_ && !complete_ && nearest_m(wx[i], wy[i]) > 1.5) {
        associations_[i] = -1;
        started_[i] = next_id_;
        Landmark l{next_id_++, ConeClass::kUnknown, wx[i], wy[i], 1, frame_, {}};
        vote(l, o.cls);
        landmarks_.push_back(l);
      }
    }

    // back at the start after a lap: the map is complete and only localised on from now
    if (!complete_ && travelled_m_ > 50.0 &&
        std::hypot(pose_.x_m - start_.x_m, pose_.y_m - start_.y_m) < 4.0) {
      complete_ = true;
      ++loop_closures_;
    }
  }

  Estimate estimate() const override {
    map_.clear();
    for (const Landmark& l : landmarks_)
      if (l.sightings >= confirm_) {
        MapCone c;
        c.id = l.id;
        c.cls = l.cls;
        c.x_m = l.x;
        c.y_m = l.y;
        c.covariance = {0.01, 0.0, 0.0, 0.01};
        map_.push_back(c);
      }
    Estimate e;
    e.stamp_us = stamp_;
    e.pose = pose_;
    e.speed_mps = speed_;
    e.yaw_rate_rps = yaw_rate_;
    e.map = {map_.data(), map_.size()};
    e.phase = localising_ || complete_ ? SlamPhase::kLocalisation : SlamPhase::kMapping;
    e.map_complete = complete_ ? 1 : 0;
    return e;
  }

  Span<int32_t> associations() const override {
    return {associations_.data(), associations_.size()};
  }

  // the landmark each new one started, so its first sighting is scored too
  Span<int32_t> new_landmark_ids() const override { return {started_.data(), started_.size()}; }

  int32_t loop_closures() const override { return loop_closures_; }

 private:
  struct Landmark {
    int32_t id;
    ConeClass cls;
    double x;
    double y;
    int sightings;
    int64_t last_frame;
    // sightings per class (blue, yellow, orange small, orange big)
    int votes[4];
  };

  // a sighting's class counts for the landmark; its class is the one seen most
  static void vote(Landmark& l, ConeClass cls) {
    const int k = static_cast<int>(cls);
    if (k < 0 || k > 3) return;
    ++l.votes[k];
    int best = -1;
    for (int i = 0; i < 4; ++i)
      if (l.votes[i] > 0 && (best < 0 || l.votes[i] > l.votes[best])) best = i;
    l.cls = static_cast<ConeClass>(best);
  }

  // distance to the nearest landmark of any class
  double nearest_m(double x, double y) const {
    double best = 1e9;
    for (const Landmark& l : landmarks_) best = std::min(best, std::hypot(x - l.x, y - l.y));
    return best;
  }

  double gate_m_ = 1.0;
  double gain_ = 0.5;
  int confirm_ = 2;
  Pose2 pose_, start_;
  TimeUs stamp_ = 0;
  double speed_ = 0.0, yaw_rate_ = 0.0, travelled_m_ = 0.0;
  std::vector<Landmark> landmarks_;
  std::vector<int32_t> associations_;
  std::vector<int32_t> started_;
  mutable std::vector<MapCone> map_;
  bool localising_ = false, complete_ = false;
  int32_t next_id_ = 0, loop_closures_ = 0;
  int64_t frame_ = 0;
};

}  // namespace

CONESIM_PLUGIN_SLAM("landmark_slam", LandmarkSlam)
