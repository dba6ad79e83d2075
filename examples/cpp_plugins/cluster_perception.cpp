// A LiDAR cone finder: de-skews each point with the car's motion to the sweep's end, keeps the
// points between the ground and a cone's height, clusters them on a 0.25 m grid, and takes each
// small cluster as a cone at its centroid. The colour comes from the stripes: a blue cone is
// dark-light-dark over its height (a bright stripe), a yellow one light-dark-light.
//
// config: {min_points: 3, max_range_m: 15, ground_clearance_m: 0.04}

#include <algorithm>
#include <cmath>
#include <conesim/sdk.hpp>
#include <map>
#include <stdexcept>
#include <utility>
#include <vector>

namespace {

using namespace conesim::sdk;

// rotates v by the unit quaternion q
Vec3 rotate(const Quaternion& q, const Vec3& v) {
  // t = 2 q_vec x v; v' = v + w t + q_vec x t
  const double tx = 2 * (q.y * v.z - q.z * v.y);
  const double ty = 2 * (q.z * v.x - q.x * v.z);
  const double tz = 2 * (q.x * v.y - q.y * v.x);
  return {v.x + q.w * tx + (q.y * tz - q.z * ty), v.y + q.w * ty + (q.z * tx - q.x * tz),
          v.z + q.w * tz + (q.x * ty - q.y * tx)};
}

class ClusterPerception final : public Perception {
 public:
  ClusterPerception(const RunInfo&, const Config& config) {
    static const char* const kKnown[] = {"min_points", "max_range_m", "ground_clearance_m",
                                         nullptr};
    config.require_known(kKnown);
    min_points_ = static_cast<int>(config.number("min_points", 3));
    max_range_m_ = config.number("max_range_m", 15.0);
    ground_m_ = config.number("ground_clearance_m", 0.04);
    if (min_points_ < 1) throw std::invalid_argument("min_points: expected at least 1");
  }

  ConeFrame on_lidar(const LidarSweep& sweep, const Motion& motion) override {
    struct P {
      double x, y, z, intensity, range;
    };
    std::map<std::pair<int, int>, std::vector<P>> cells;
    const double sweep_s = 1e-6 * static_cast<double>(sweep.end_us - sweep.stamp_us);
    for (const LidarPoint& p : sweep.points) {
      // into the vehicle frame at the firing time, then on to the sweep's end
      const Vec3 v = rotate(sweep.sensor_in_vehicle.orientation, {p.x_m, p.y_m, p.z_m});
      double x = v.x + sweep.sensor_in_vehicle.position_m.x;
      double y = v.y + sweep.sensor_in_vehicle.position_m.y;
      const double z = v.z + sweep.sensor_in_vehicle.position_m.z;
      if (z < ground_m_ || z > 0.6) continue;
      const double dt = std::max(0.0, sweep_s - p.time_offset_s);
      const double yaw = motion.yaw_rate_rps * dt;
      const double dx = motion.speed_mps * dt * std::cos(0.5 * yaw);
      const double dy = motion.speed_mps * dt * std::sin(0.5 * yaw);
      const double c = std::cos(yaw), s = std::sin(yaw);
      const double ex = x - dx, ey = y - dy;
      x = c * ex + s * ey;
      y = -s * ex + c * ey;
      const double r = std::hypot(x, y);
      if (r < 1.0 || r > max_range_m_) continue;
      cells[{static_cast<int>(std::floor(x / 0.25)), static_cast<int>(std::floor(y / 0.25))}]
          .push_back(
              {x, y, z, p.intensity, std::sqrt(p.x_m * p.x_m + p.y_m * p.y_m + p.z_m * p.z_m)});
    }

    // clusters: connected occupied cells (8-neighbourhood)
    cones_.clear();
    std::map<std::pair<int, int>, bool> done;
    for (const auto& [cell, unused] : cells) {
      if (done[cell]) continue;
      std::vector<std::pair<int, int>> stack{cell}, members;
      done[cell] = true;
      while (!stack.empty()) {
        const auto c = stack.back();
        stack.pop_back();
        members.push_back(c);
        for (int i = -1; i <= 1; ++i)
          for (int j = -1; j <= 1; ++j) {
            const std::pair<int, int> nb{c.first + i, c.second + j};
            if (cells.count(nb) && !done[nb]) done[nb] = true, stack.push_back(nb);
          }
      }
      std::vector<P> pts;
      for (const auto& m : members) pts.insert(pts.end(), cells[m].begin(), cells[m].end());
      double minx = 1e9, maxx = -1e9, miny = 1e9, maxy = -1e9, maxz = 0, sx = 0, sy = 0;
      for (const P& p : pts) {
        minx = std::min(minx, p.x), maxx = std::max(maxx, p.x);
        miny = std::min(miny, p.y), maxy = std::max(maxy, p.y);
        maxz = std::max(maxz, p.z), sx += p.x, sy += p.y;
      }
      // a cone: a few points, at most 0.45 m across
      if (static_cast<int>(pts.size()) < min_points_ || maxx - minx > 0.45 || maxy - miny > 0.45)
        continue;
      ConeObservation o;
      const double cx = sx / pts.size(), cy = sy / pts.size(), r = std::hypot(cx, cy);
      // the returns come from the near side: the axis is about 8 cm farther
      o.x_m = cx + 0.08 * cx / r;
      o.y_m = cy + 0.08 * cy / r;
      o.cls = colour(pts, maxz);
      o.covariance = {0.02, 0.0, 0.0, 0.02};
      cones_.push_back(o);
    }
    return {sweep.end_us, {cones_.data(), cones_.size()}};
  }

 private:
  // the stripes: a small cone's stripe is the band 0.11-0.20 m above the ground (FSG: 35-62 %
  // of 325 mm), white on blue, black on yellow. Each point's reflectivity (its intensity with
  // the range fall-off undone, VLP-16-like: 40 m) is compared with what a blue cone (dark body,
  // white stripe) and a yellow one (bright body, black stripe) would give there; the likelier
  // wins when clearly so. A cluster reaching above 0.36 m is a big orange cone.
  template <typename Points>
  static ConeClass colour(const Points& pts, double top) {
    if (top > 0.36) return ConeClass::kOrangeBig;
    double blue_error = 0.0, yellow_error = 0.0;
    for (const auto& p : pts) {
      const double reflectivity =
          p.intensity * (1.0 + p.range * p.range / (40.0 * 40.0)) / 255.0 / 0.8;
      const bool stripe = p.z > 0.114 && p.z < 0.2;
      const double blue = stripe ? 0.85 : 0.15, yellow = stripe ? 0.05 : 0.65;
      blue_error += (reflectivity - blue) * (reflectivity - blue);
      yellow_error += (reflectivity - yellow) * (reflectivity - yellow);
    }
    if (blue_error < 0.5 * yellow_error) return ConeClass::kBlue;
    if (yellow_error < 0.5 * blue_error) return ConeClass::kYellow;
    return ConeClass::kUnknown;
  }

  int min_points_ = 3;
  double max_range_m_ = 15.0;
  double ground_m_ = 0.04;
  std::vector<ConeObservation> cones_;
};

}  // namespace

CONESIM_PLUGIN_PERCEPTION("cluster_perception", ClusterPerception)
