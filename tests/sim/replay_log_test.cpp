// replay.bin's camera frames (issue 16): written by the recorder, read back with their boxes
// scaled to the small image, and the rule that keeps older readers working: a record type a
// reader does not know is skipped, the version stays 1.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "core/error.hpp"
#include "sim/replay.hpp"
#include "sim/sensor_rig.hpp"

namespace conesim::sim {
namespace {

namespace fs = std::filesystem;

struct TempDir {
  fs::path path;
  TempDir() {
    char name[] = "/tmp/conesim-replay-log-XXXXXX";
    path = ::mkdtemp(name);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

tracks::Track two_cones() {
  tracks::Track t;
  t.name = "two";
  t.cones.push_back({0, core::ConeClass::kBlue, core::Vec2(5.0, 1.5), std::nullopt});
  t.cones.push_back({1, core::ConeClass::kYellow, core::Vec2(5.0, -1.5), std::nullopt});
  return t;
}

// a 640 x 480 picture: grey with a bright square where the detected box is
core::RgbImage picture() {
  core::RgbImage img;
  img.width_px = 640, img.height_px = 480;
  img.rgb.assign(3 * 640 * 480, 90);
  for (int y = 200; y < 280; ++y)
    for (int x = 100; x < 160; ++x)
      for (int c = 0; c < 3; ++c) img.rgb[3 * (y * 640 + x) + c] = 250;
  return img;
}

std::string bytes_of(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(ReplayLog, CameraFramesComeBackWithTheirBoxesScaledToTheSmallImage) {
  TempDir dir;
  const core::RgbImage left = picture();
  {
    ReplayRecorder recorder(dir.path, two_cones(), 0.0);
    CameraReplayFrame frame;
    frame.t = 1'250'000;
    frame.left = &left;
    frame.detected.push_back({100.f, 200.f, 160.f, 280.f, core::ConeClass::kBlue, 7, 5.2f});
    frame.truth.push_back({98.f, 198.f, 162.f, 282.f, core::ConeClass::kBlue, 0, 5.2f});
    frame.truth.push_back({400.f, 200.f, 440.f, 260.f, core::ConeClass::kYellow, 1, 5.3f});
    recorder.on_camera(frame);
    frame.t = 1'500'000;
    frame.detected.clear();
    recorder.on_camera(frame);
    EXPECT_EQ(recorder.camera_frames_recorded(), 2);
    recorder.finish();
  }
  const ReplayLog log = read_replay_log(dir.path / kReplayLogFile);
  ASSERT_EQ(log.camera.size(), 2u);
  const ReplayLog::CameraFrame& f = log.camera[0];
  EXPECT_DOUBLE_EQ(f.t_s, 1.25);
  EXPECT_EQ(f.width, 320);
  EXPECT_EQ(f.height, 240);
  // a JPEG, and small
  ASSERT_GT(f.jpeg.size(), 4u);
  EXPECT_EQ(static_cast<unsigned char>(f.jpeg[0]), 0xFF);
  EXPECT_EQ(static_cast<unsigned char>(f.jpeg[1]), 0xD8);
  EXPECT_LT(f.jpeg.size(), 20'000u);
  ASSERT_EQ(f.detected.size(), 1u);
  EXPECT_FLOAT_EQ(f.detected[0].x0, 50.f);
  EXPECT_FLOAT_EQ(f.detected[0].y0, 100.f);
  EXPECT_FLOAT_EQ(f.detected[0].x1, 80.f);
  EXPECT_FLOAT_EQ(f.detected[0].y1, 140.f);
  EXPECT_EQ(f.detected[0].cls, 1 + static_cast<int>(core::ConeClass::kBlue));
  EXPECT_EQ(f.detected[0].id, 7);
  EXPECT_FLOAT_EQ(f.detected[0].range_m, 5.2f);
  ASSERT_EQ(f.truth.size(), 2u);
  EXPECT_EQ(f.truth[1].cls, 1 + static_cast<int>(core::ConeClass::kYellow));
  EXPECT_EQ(f.truth[1].id, 1);
  EXPECT_TRUE(log.camera[1].detected.empty());
  EXPECT_EQ(log.camera[1].truth.size(), 2u);
}

TEST(ReplayLog, KeepsVersionOneAndSkipsRecordTypesItDoesNotKnow) {
  TempDir dir;
  const core::RgbImage left = picture();
  {
    ReplayRecorder recorder(dir.path, two_cones(), 0.0);
    CameraReplayFrame frame;
    frame.left = &left;
    recorder.on_camera(frame);
    recorder.finish();
  }
  std::string data = bytes_of(dir.path / kReplayLogFile);
  uint32_t version = 0;
  std::memcpy(&version, data.data() + 4, 4);
  EXPECT_EQ(version, 1u);  // older readers refuse any other version
  // a record of a type from the future, then the file read again: it is skipped
  const std::string payload = "whatever a later conesim writes";
  data += static_cast<char>(200);
  const uint32_t size = static_cast<uint32_t>(payload.size());
  data.append(reinterpret_cast<const char*>(&size), 4);
  data += payload;
  {
    std::ofstream out(dir.path / kReplayLogFile, std::ios::binary | std::ios::trunc);
    out << data;
  }
  const ReplayLog log = read_replay_log(dir.path / kReplayLogFile);
  EXPECT_EQ(log.camera.size(), 1u);
  // a camera record cut short is refused with the file named
  data.resize(data.size() - payload.size() - 5 - 10);
  {
    std::ofstream out(dir.path / kReplayLogFile, std::ios::binary | std::ios::trunc);
    out << data;
  }
  EXPECT_THROW(read_replay_log(dir.path / kReplayLogFile), core::InputError);
}

}  // namespace
}  // namespace conesim::sim
