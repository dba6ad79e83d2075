// Sensor and vehicle faults (`faults:`): each does what it says to the sensors' data, the keys are
// checked like every scenario key, a faulted run repeats to the bit, a fault that never acts
// changes nothing, and a faulted run completes without NaN.

#include "sim/faults.hpp"

#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <numbers>

#include "core/error.hpp"
#include "sim/run.hpp"
#include "sim/scenario.hpp"

namespace conesim::sim {
namespace {

namespace fs = std::filesystem;
using core::TimeUs;

Fault make(FaultKind kind, double start_s = 0.0, std::optional<double> end_s = std::nullopt) {
  Fault f;
  f.kind = kind;
  f.start_s = start_s;
  f.end_s = end_s;
  return f;
}

// a sweep of n points with label i and x = i (which point is which, after a filter)
void numbered_sweep(size_t n, core::PointCloud& cloud, core::PointCloudLabels& labels) {
  cloud.stamp = 1'000'000;
  cloud.points.resize(n);
  labels.cone_id.resize(n);
  for (size_t i = 0; i < n; ++i) {
    cloud.points[i].x = static_cast<float>(i);
    cloud.points[i].y = 1.0f;
    cloud.points[i].time_offset_s = 0.05f * static_cast<float>(i) / static_cast<float>(n);
    labels.cone_id[i] = static_cast<int>(i);
  }
}

TEST(Faults, DropoutRemovesThatFractionWithinBinomialNoise) {
  Fault f = make(FaultKind::kLidarDropout);
  f.fraction = 0.3;
  const FaultInjector faults({f}, 7);
  const size_t n = 100'000;
  core::PointCloud cloud;
  core::PointCloudLabels labels;
  numbered_sweep(n, cloud, labels);
  FaultCounts counts = faults.zero_counts();
  faults.apply_lidar(cloud, labels, counts);
  // removed ~ Binomial(n, 0.3): sigma = sqrt(n p (1 - p)) = 145 points; 4 sigma
  const double removed = static_cast<double>(n - cloud.points.size());
  EXPECT_NEAR(removed, 0.3 * n, 4.0 * std::sqrt(n * 0.3 * 0.7));
  EXPECT_EQ(counts.affected[0], static_cast<int64_t>(removed));
  // the labels go with their points
  ASSERT_EQ(labels.cone_id.size(), cloud.points.size());
  for (size_t k = 0; k < cloud.points.size(); ++k)
    ASSERT_EQ(labels.cone_id[k], static_cast<int>(cloud.points[k].x));
  // another sweep draws other points; the same sweep the same ones
  core::PointCloud again, other;
  core::PointCloudLabels again_labels, other_labels;
  numbered_sweep(n, again, again_labels);
  numbered_sweep(n, other, other_labels);
  other.stamp += 100'000;
  faults.apply_lidar(again, again_labels, counts);
  faults.apply_lidar(other, other_labels, counts);
  EXPECT_EQ(again_labels.cone_id, labels.cone_id);
  EXPECT_NE(other_labels.cone_id, labels.cone_id);
}

TEST(Faults, DropoutActsOnlyWithinItsWindow) {
  // the window covers the second half of the sweep's 50 ms
  Fault f = make(FaultKind::kLidarDropout, 1.025, 2.0);
  f.fraction = 1.0;
  const FaultInjector faults({f}, 7);
  core::PointCloud cloud;
  core::PointCloudLabels labels;
  numbered_sweep(1000, cloud, labels);
  FaultCounts counts = faults.zero_counts();
  faults.apply_lidar(cloud, labels, counts);
  ASSERT_NEAR(static_cast<double>(cloud.points.size()), 500.0, 1.0);
  for (const core::LidarPoint& p : cloud.points) EXPECT_LT(p.time_offset_s, 0.0251f);
}

TEST(Faults, SectorBlackoutBlindsThatSectorOnly) {
  // a point every degree around the sensor; the front-left quarter, then the rear half across
  // +-180 degrees
  for (const auto& [from, to] : {std::pair{0.0, 90.0}, std::pair{90.0, -90.0}}) {
    Fault f = make(FaultKind::kLidarSectorBlackout);
    f.from_deg = from, f.to_deg = to;
    const FaultInjector faults({f}, 1);
    core::PointCloud cloud;
    core::PointCloudLabels labels;
    for (int deg = -179; deg <= 180; ++deg) {
      const double a = (deg + 0.5) * std::numbers::pi / 180.0;
      cloud.points.push_back({static_cast<float>(10.0 * std::cos(a)),
                              static_cast<float>(10.0 * std::sin(a)), 0.f, 0.f, 0, 0.f});
      labels.cone_id.push_back(deg);
    }
    FaultCounts counts = faults.zero_counts();
    faults.apply_lidar(cloud, labels, counts);
    EXPECT_EQ(cloud.points.size(), from == 0.0 ? 270u : 180u);
    for (int deg : labels.cone_id) {
      const double centre = deg + 0.5;
      const bool blind =
          from == 0.0 ? centre > 0.0 && centre < 90.0 : centre > 90.0 || centre < -90.0;
      EXPECT_FALSE(blind) << "a point at " << centre << " deg survived";
    }
  }
}

TEST(Faults, LostSweepsOneInNOrByProbability) {
  Fault every = make(FaultKind::kLidarLostSweeps);
  every.every = 10;
  const FaultInjector one_in_ten({every}, 3);
  FaultCounts counts = one_in_ten.zero_counts();
  std::vector<int> lost;
  for (int i = 0; i < 100; ++i)
    if (one_in_ten.lidar_sweep_lost(i, (i + 1) * 100'000, counts)) lost.push_back(i);
  EXPECT_EQ(lost.size(), 10u);
  EXPECT_EQ(lost.front(), 9);
  EXPECT_EQ(counts.affected[0], 10);

  // a probability of 0.2 over 2000 sweeps: sigma = sqrt(2000 * 0.2 * 0.8) = 17.9
  Fault p = make(FaultKind::kLidarLostSweeps, 0.0, 200.0);
  p.probability = 0.2;
  const FaultInjector by_chance({p}, 3);
  FaultCounts chance = by_chance.zero_counts();
  int n = 0;
  for (int i = 0; i < 2000; ++i) n += by_chance.lidar_sweep_lost(i, (i + 1) * 100'000, chance);
  EXPECT_NEAR(n, 400, 4 * 17.9);
  // none after the window
  EXPECT_FALSE(by_chance.lidar_sweep_lost(5000, core::from_seconds(300.0), chance));
}

TEST(Faults, DelayJitterKeepsOrderUnlessOutOfOrderIsAllowed) {
  for (const bool out_of_order : {false, true}) {
    Fault f = make(FaultKind::kDelayJitter);
    f.max_delay_s = 0.15;
    f.out_of_order = out_of_order;
    const FaultInjector faults({f}, 11);
    FaultCounts counts = faults.zero_counts();
    // frames every 100 ms, due 50 ms after their stamp
    TimeUs previous = 0;
    int overtaken = 0;
    for (int i = 0; i < 1000; ++i) {
      const TimeUs stamp = i * 100'000, due = stamp + 50'000;
      const TimeUs at = faults.delivery_us(stamp, due, previous, 0, counts);
      EXPECT_GE(at, due);
      EXPECT_LE(at, due + 150'000);
      overtaken += at < previous;
      previous = at;
    }
    // a frame late by u * 150 ms is overtaken by the next, 100 ms later and late by u' * 150 ms,
    // when u - u' > 2/3: probability 1/18, 55.5 of 999 frames, sigma 7.2
    if (out_of_order) {
      EXPECT_NEAR(overtaken, 55.5, 4 * 7.2);
    } else {
      EXPECT_EQ(overtaken, 0);
    }
  }
}

TEST(Faults, ImuBiasStepsAndWheelSlipActInTheirWindows) {
  Fault bias = make(FaultKind::kImuBiasStep, 2.0);
  bias.gyro_bias_rps = 0.01, bias.accel_bias_mps2 = 0.2;
  Fault slip = make(FaultKind::kWheelSlip, 1.0, 1.5);
  slip.factor = 1.5;
  const FaultInjector faults({bias, slip}, 5);
  FaultCounts counts = faults.zero_counts();
  core::ImuSample before{core::from_seconds(1.9), Eigen::Vector3d(0, 0, 0.1),
                         Eigen::Vector3d(1, 0, 9.81)};
  core::ImuSample after = before;
  after.stamp = core::from_seconds(2.0);
  faults.apply_imu(before, counts);
  faults.apply_imu(after, counts);
  EXPECT_DOUBLE_EQ(before.gyro_rps.z(), 0.1);
  EXPECT_DOUBLE_EQ(after.gyro_rps.z(), 0.11);
  EXPECT_DOUBLE_EQ(after.accel_mps2.x(), 1.2);
  core::WheelSpeeds wheels{core::from_seconds(1.2), {10.0, 10.0, 10.0, 10.0}};
  faults.apply_wheels(wheels, counts);
  EXPECT_DOUBLE_EQ(wheels.omega_rps[0], 10.0);  // the front wheels roll
  EXPECT_DOUBLE_EQ(wheels.omega_rps[2], 15.0);  // the driven rear wheels spin
  core::WheelSpeeds later{core::from_seconds(1.5), {10.0, 10.0, 10.0, 10.0}};
  faults.apply_wheels(later, counts);
  EXPECT_DOUBLE_EQ(later.omega_rps[3], 10.0);
  EXPECT_EQ(counts.affected, (std::vector<int64_t>{1, 1}));
}

// the message of the InputError that loading throws, or "" when it loads
class FaultKeys : public ::testing::Test {
 protected:
  std::string error_of(const std::string& text, const std::vector<std::string>& sets = {}) {
    try {
      load(text, sets);
    } catch (const core::InputError& e) {
      return e.what();
    }
    return "";
  }
  Scenario load(const std::string& text, const std::vector<std::string>& sets = {}) {
    dir_ = fs::temp_directory_path() / ("conesim-faults-" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    std::ofstream(dir_ / "s.yaml") << text;
    return load_scenario(dir_ / "s.yaml", sets);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
  const std::string lidar_ = "event: trackdrive\nperception: lidar\n";
};

TEST_F(FaultKeys, MapAndListFormsAndSetOverrides) {
  const Scenario s =
      load(lidar_ +
               "faults:\n"
               "  lidar_dropout: {fraction: 0.3}\n"
               "  lidar_sector_blackout:\n"
               "    - {start_s: 10, end_s: 15, from_deg: 0, to_deg: 90}\n"
               "    - {from_deg: 90, to_deg: -90}\n",
           {"faults.lidar_dropout.fraction=0.25", "faults.lidar_lost_sweeps={every: 10}"});
  ASSERT_EQ(s.faults.size(), 4u);
  EXPECT_EQ(s.faults[0].kind, FaultKind::kLidarDropout);
  EXPECT_DOUBLE_EQ(s.faults[0].fraction, 0.25);
  EXPECT_EQ(s.faults[2].end_s, std::nullopt);
  EXPECT_EQ(s.faults[3].every, 10);
  // none: no block, an empty one, or cleared from the command line
  EXPECT_TRUE(load(lidar_).faults.empty());
  EXPECT_TRUE(load(lidar_ + "faults: {}\n").faults.empty());
  EXPECT_TRUE(
      load(lidar_ + "faults: {lidar_dropout: {fraction: 0.3}}\n", {"faults={}"}).faults.empty());
}

TEST_F(FaultKeys, BadFaultsNameTheKeyAndWhatWasExpected) {
  const std::string kind = error_of(lidar_ + "faults:\n  radar_dropout: {}\n");
  EXPECT_NE(kind.find("s.yaml:4: faults.radar_dropout: unknown key; expected one of: "
                      "lidar_dropout"),
            std::string::npos)
      << kind;
  const std::string fraction = error_of(lidar_ + "faults:\n  lidar_dropout: {fraction: 1.5}\n");
  EXPECT_NE(fraction.find("faults.lidar_dropout.fraction: expected the share"), std::string::npos)
      << fraction;
  const std::string set = error_of(lidar_, {"faults.lidar_dropout.fraction=-1"});
  EXPECT_NE(set.find("--set: faults.lidar_dropout.fraction"), std::string::npos) << set;
  const std::string window =
      error_of(lidar_ + "faults:\n  camera_blackout: [{start_s: 5, end_s: 4}]\n");
  EXPECT_NE(window.find("faults.camera_blackout[0].end_s: expected a time after start_s"),
            std::string::npos)
      << window;
  const std::string key =
      error_of(lidar_ + "faults:\n  lidar_dropout: {fraction: 0.3, factor: 2}\n");
  EXPECT_NE(key.find("faults.lidar_dropout.factor: unknown key; expected one of: start_s, end_s, "
                     "fraction"),
            std::string::npos)
      << key;
  const std::string both =
      error_of(lidar_ + "faults:\n  lidar_lost_sweeps: {every: 10, probability: 0.1}\n");
  EXPECT_NE(both.find("faults.lidar_lost_sweeps.every: expected either"), std::string::npos)
      << both;
  // a fault of a sensor or a stack that is not in the loop would do nothing
  const std::string camera = error_of(lidar_ + "faults:\n  camera_blackout: {start_s: 3}\n");
  EXPECT_NE(camera.find("faults.camera_blackout: no camera in the loop (perception: lidar)"),
            std::string::npos)
      << camera;
  const std::string slip =
      error_of(lidar_ + "faults:\n  wheel_slip: {start_s: 3, end_s: 4, factor: 1.5}\n");
  EXPECT_NE(slip.find("faults.wheel_slip: the IMU and wheel encoders feed SLAM's odometry"),
            std::string::npos)
      << slip;
  const std::string lidar =
      error_of("event: trackdrive\nfaults: {lidar_dropout: {fraction: 0.3}}\n");
  EXPECT_NE(lidar.find("faults.lidar_dropout: no LiDAR in the loop"), std::string::npos) << lidar;
}

TEST_F(FaultKeys, ShippedFaultScenariosLoad) {
  for (const char* name :
       {"faults-lidar-dropout", "faults-lidar-sector", "faults-camera-blackout",
        "faults-gnss-outage", "faults-wheel-slip", "faults-imu-bias", "faults-delay-jitter"}) {
    const Scenario s = load_scenario(find_scenario(name));
    EXPECT_FALSE(s.faults.empty()) << name;
  }
}

// a shipped scenario run into a temporary folder, without pictures
RunResult run(const std::string& name, const std::string& tag, const std::vector<std::string>& sets,
              const DumpOptions& dump = {}, fs::path* kept = nullptr) {
  const Scenario s = load_scenario(find_scenario(name), sets);
  RunOptions options;
  options.out_dir =
      fs::temp_directory_path() / ("conesim-faults-" + tag + "-" + std::to_string(::getpid()));
  options.plot = false;
  options.dump = dump;
  RunResult r = run_scenario(s, scenario_track(s), options);
  if (kept)
    *kept = options.out_dir;
  else
    fs::remove_all(options.out_dir);
  return r;
}

nlohmann::json without_timing(nlohmann::json m) {
  m.erase("wall_time_s");
  m.erase("real_time_factor");
  for (auto& [lane, f] : m["slam"].items())
    for (const char* k : {"update_ms_median", "update_ms_p99", "update_cpu_ms_median",
                          "update_cpu_ms_p99", "association_us_median", "association_us_p99"})
      f.erase(k);
  m["sensors"].erase("lidar_detect_ms_mean");
  m["sensors"].erase("stereo_detect_ms_mean");
  return m;
}

// every number in a JSON tree is finite (nlohmann writes NaN as null, so look before)
bool all_finite(const nlohmann::json& j) {
  if (j.is_number_float()) return std::isfinite(j.get<double>());
  if (j.is_structured())
    for (const auto& v : j)
      if (!all_finite(v)) return false;
  return true;
}

TEST(FaultRuns, ShortFaultedSlamRunCompletesWithoutNaNAndRepeats) {
  // acceleration on GraphSLAM through wheel slip, an IMU bias step, a GNSS outage and frames
  // delivered up to 150 ms late and out of order
  const std::vector<std::string> faults = {
      "faults={wheel_slip: {start_s: 2.5, end_s: 3.0, factor: 1.5}, "
      "imu_bias_step: {start_s: 2, gyro_bias_rps: 0.005}, gnss_outage: {start_s: 1, end_s: 5}, "
      "delay_jitter: {max_delay_s: 0.15, out_of_order: true}}"};
  const RunResult a = run("acceleration-graphslam", "slam-a", faults);
  EXPECT_TRUE(a.referee.completed) << a.referee.dnf_reason;
  EXPECT_TRUE(all_finite(a.metrics));
  const nlohmann::json& f = a.metrics["faults"];
  ASSERT_EQ(f.size(), 4u) << f.dump();
  for (const nlohmann::json& fault : f) {
    // each did something (nothing reads GNSS: an outage has nothing to take)
    if (fault["kind"] != "gnss_outage") {
      EXPECT_GT(fault["affected"].get<int64_t>(), 0) << fault;
    }
    EXPECT_TRUE(fault["trajectory_rmse_during_m"].is_number()) << fault.dump();
    if (fault["kind"] == "delay_jitter") {
      EXPECT_GT(fault["frames_out_of_order"].get<int>(), 0);
    }
  }
  int fault_events = 0;
  for (const nlohmann::json& e : a.metrics["events"]) fault_events += e["kind"] == "fault";
  EXPECT_EQ(fault_events, 4);
  EXPECT_TRUE(a.metrics["slam"]["graph"]["ate_rmse_m"].is_number());
  // the same seed, the same run
  const RunResult b = run("acceleration-graphslam", "slam-b", faults);
  EXPECT_EQ(without_timing(a.metrics), without_timing(b.metrics));
}

TEST(FaultRuns, LostSweepsNeverReachPerceptionAndAFaultThatNeverActsChangesNothing) {
  const std::vector<std::string> lidar = {"perception=lidar", "sensors.lidar.model=vlp32c"};
  std::vector<std::string> lossy = lidar;
  lossy.push_back("faults={lidar_lost_sweeps: {every: 2}, lidar_dropout: {fraction: 0.3}}");
  const RunResult r = run("acceleration", "lost", lossy);
  EXPECT_TRUE(r.referee.completed) << r.referee.dnf_reason;
  const nlohmann::json& sensors = r.metrics["sensors"];
  const int scans = sensors["lidar_scans"].get<int>();
  const int lost = sensors["lidar_sweeps_lost"].get<int>();
  EXPECT_NEAR(lost, scans / 2, 1);
  // perception scores every frame it delivers: none of the lost sweeps
  EXPECT_EQ(r.metrics["perception"]["frames"].get<int>(), scans - lost);

  // faults that begin after the run: the sensors' noise and the run are those without faults
  std::vector<std::string> never = lidar;
  never.push_back(
      "faults={lidar_lost_sweeps: {start_s: 1000, every: 2}, lidar_dropout: {start_s: 1000, "
      "fraction: 0.3}, lidar_sector_blackout: {start_s: 1000, from_deg: 0, to_deg: 90}}");
  nlohmann::json with = without_timing(run("acceleration", "never", never).metrics);
  const nlohmann::json without = without_timing(run("acceleration", "none", lidar).metrics);
  EXPECT_EQ(with["faults"].size(), 3u);
  with.erase("faults");
  with["sensors"].erase("lidar_sweeps_lost");
  EXPECT_EQ(with, without);
}

// whether a PNG (as sensors::write_png writes it: 8-bit RGB) is all black: its filtered rows
// hold only zeros (with any PNG filter, a row of zeros under a row of zeros filters to zeros,
// and any other pixel leaves a byte that is not)
bool png_is_black(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::string idat;
  for (size_t at = 8; at + 8 <= bytes.size();) {
    const uint32_t length = (uint32_t(uint8_t(bytes[at])) << 24) |
                            (uint32_t(uint8_t(bytes[at + 1])) << 16) |
                            (uint32_t(uint8_t(bytes[at + 2])) << 8) | uint8_t(bytes[at + 3]);
    if (bytes.compare(at + 4, 4, "IDAT") == 0) idat += bytes.substr(at + 8, length);
    at += 12 + length;
  }
  std::vector<uint8_t> raw(1 << 24);
  uLongf size = raw.size();
  EXPECT_EQ(uncompress(raw.data(), &size, reinterpret_cast<const Bytef*>(idat.data()), idat.size()),
            Z_OK)
      << file;
  const uint32_t width = (uint32_t(uint8_t(bytes[16])) << 24) |
                         (uint32_t(uint8_t(bytes[17])) << 16) |
                         (uint32_t(uint8_t(bytes[18])) << 8) | uint8_t(bytes[19]);
  const size_t row = 1 + 3 * size_t(width);
  for (size_t i = 0; i < size; ++i)
    if (i % row != 0 && raw[i] != 0) return false;
  return size > 0;
}

std::string file_bytes(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

TEST(FaultRuns, BlackedOutFramesAreBlackAndFrozenFramesRepeatTheLastGoodOne) {
  // the camera at 10 Hz, its k-th frame at (k + 1) / 10 s: black from 2.0 to 2.5 s (frames
  // 19-23), frozen from 3.0 to 3.3 s (frames 29-31 repeat frame 28)
  DumpOptions dump;
  dump.sensors = {"camera"};
  dump.every = 1;  // every frame: the ones round the blackout are looked at one by one
  dump.review_png = false;
  fs::path dir;
  const RunResult r =
      run("acceleration", "camera",
          {"sensors.camera.enabled=true",
           "faults={camera_blackout: {start_s: 2, end_s: 2.5}, camera_frozen: {start_s: 3, "
           "end_s: 3.3}}"},
          dump, &dir);
  EXPECT_TRUE(r.referee.completed) << r.referee.dnf_reason;
  const fs::path left = dir / "images/camera/left";
  auto frame = [&left](int k) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.png", k);
    return left / name;
  };
  for (int k = 19; k <= 23; ++k) EXPECT_TRUE(png_is_black(frame(k))) << k;
  EXPECT_FALSE(png_is_black(frame(18)));
  EXPECT_FALSE(png_is_black(frame(24)));
  for (int k = 29; k <= 31; ++k) EXPECT_EQ(file_bytes(frame(k)), file_bytes(frame(28))) << k;
  // the car moves: the frame after the freeze is a new one
  EXPECT_NE(file_bytes(frame(32)), file_bytes(frame(28)));
  EXPECT_EQ(r.metrics["faults"][0]["affected"].get<int>(), 5);
  EXPECT_EQ(r.metrics["faults"][1]["affected"].get<int>(), 3);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace conesim::sim
