// A plug-in that misbehaves on purpose, for the tests of how a run ends when a team's code
// fails (tests/app/sdk_test.sh). Its driver creeps straight ahead, its SLAM dead-reckons, its
// perception finds nothing; each does its fault from `after_s` sim seconds on.
//
// config: {fault: none | throw | nan | slow | hang, after_s: 2, slow_ms: 300, refuse: false}

#include <chrono>
#include <conesim/sdk.hpp>
#include <stdexcept>
#include <string>
#include <thread>

namespace {

using namespace conesim::sdk;

// the fault and when it starts
struct Fault {
  std::string kind;
  TimeUs after_us = 0;
  double slow_ms = 300.0;

  explicit Fault(const Config& config) {
    static const char* const kKnown[] = {"fault", "after_s", "slow_ms", "refuse", nullptr};
    config.require_known(kKnown);
    if (config.boolean("refuse", false))
      throw std::invalid_argument("refuse: this plug-in was told to refuse its configuration");
    kind = config.text("fault", "none");
    if (kind != "none" && kind != "throw" && kind != "nan" && kind != "slow" && kind != "hang")
      throw std::invalid_argument("fault: expected none, throw, nan, slow or hang, got '" + kind +
                                  "'");
    after_us = static_cast<TimeUs>(config.number("after_s", 2.0) * 1e6);
    slow_ms = config.number("slow_ms", 300.0);
  }

  // does the fault at time t; returns true when the output is to be NaN
  bool strike(TimeUs t, const char* where) const {
    if (t < after_us) return false;
    if (kind == "throw") throw std::runtime_error(std::string("injected fault in ") + where);
    if (kind == "slow")
      std::this_thread::sleep_for(std::chrono::microseconds(static_cast<long>(slow_ms * 1e3)));
    // never returns (until the process ends)
    while (kind == "hang") std::this_thread::sleep_for(std::chrono::milliseconds(50));
    return kind == "nan";
  }
};

class FaultyDriver final : public Driver {
 public:
  FaultyDriver(const RunInfo&, const Config& config) : fault_(config) {}
  Command update(const DriverInput& in) override {
    Command c{0.0, in.estimate.speed_mps < 2.0 ? 1.0 : 0.0, 0};
    if (fault_.strike(in.now_us, "update")) c.steer_rad = std::nan("");
    return c;
  }

 private:
  Fault fault_;
};

class FaultySlam final : public Slam {
 public:
  FaultySlam(const RunInfo&, const Config& config) : fault_(config) {}
  void reset(const Pose2& start, TimeUs stamp_us, Span<MapCone>) override {
    pose_ = start;
    stamp_ = stamp_us;
  }
  void process(const SlamInput& in) override {
    pose_ = compose(pose_, in.odometry.delta);
    stamp_ = in.odometry.to_us;
    speed_ = in.odometry.speed_mps;
    nan_ = fault_.strike(stamp_, "process");
  }
  Estimate estimate() const override {
    Estimate e;
    e.stamp_us = stamp_;
    e.pose = pose_;
    e.speed_mps = speed_;
    if (nan_) e.pose.x_m = std::nan("");
    return e;
  }

 private:
  Fault fault_;
  Pose2 pose_;
  TimeUs stamp_ = 0;
  double speed_ = 0.0;
  bool nan_ = false;
};

class FaultyPerception final : public Perception {
 public:
  FaultyPerception(const RunInfo&, const Config& config) : fault_(config) {}
  ConeFrame on_lidar(const LidarSweep& sweep, const Motion&) override {
    cone_ = {1.0, 0.0, ConeClass::kUnknown, -1, {}};
    if (fault_.strike(sweep.end_us, "on_lidar")) {
      cone_.x_m = std::nan("");
      return {sweep.end_us, {&cone_, 1}};
    }
    return {sweep.end_us, {}};
  }

 private:
  Fault fault_;
  ConeObservation cone_;
};

}  // namespace

CONESIM_PLUGIN("faulty", FaultyPerception, FaultySlam, FaultyDriver)
