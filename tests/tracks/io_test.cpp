#include "tracks/io.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numbers>
#include <random>
#include <set>
#include <string>

#include "core/error.hpp"

namespace conesim::tracks {
namespace {

namespace fs = std::filesystem;
using core::InputError;
using ::testing::Contains;
using ::testing::HasSubstr;

std::string data(const std::string& path) {
  return std::string(CONESIM_TEST_DATA) + "/tracks/" + path;
}

// the cone whose file gave it this id (the test fails when there is none)
const Cone& cone_with_file_id(const Track& track, uint64_t file_id) {
  for (const Cone& c : track.cones)
    if (track.file_id(c.id) == file_id) return c;
  ADD_FAILURE() << "no cone with file id " << file_id;
  return track.cones.front();
}

// a fresh directory under the system temp dir, removed at the end of the test
class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = std::string(info->test_suite_name()) + "_" + info->name();
    for (char& c : name) c = c == '/' ? '_' : c;
    path_ =
        fs::temp_directory_path() / ("conesim_io_test_" + std::to_string(::getpid()) + "_" + name);
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  fs::path operator/(const std::string& name) const { return path_ / name; }

 private:
  fs::path path_;
};

void write_file(const fs::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary);
  out << text;
}

// the InputError a parse raises (fails the test when there is none)
InputError parse_error(const std::string& text, TrackFormat format, const std::string& name) {
  try {
    parse_track(text, format, name);
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << "no InputError for " << name;
  return InputError(name, 0, "none");
}

InputError read_error(const fs::path& file) {
  try {
    read_track(file);
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << "no InputError for " << file;
  return InputError(file.string(), 0, "none");
}

int count_warnings(const Track& track, const std::string& text) {
  return static_cast<int>(
      std::count_if(track.warnings.begin(), track.warnings.end(),
                    [&](const std::string& w) { return w.find(text) != std::string::npos; }));
}

double polyline_length(const std::vector<Vec2>& pts, bool closed) {
  double length = 0.0;
  for (size_t i = 0; i + 1 < pts.size(); ++i) length += (pts[i + 1] - pts[i]).norm();
  if (closed && pts.size() > 1) length += (pts.back() - pts.front()).norm();
  return length;
}

// ---------------------------------------------------------------------------------------------
// the shared files import with the counts they imply

struct Expected {
  std::string file;
  int blue, yellow, orange_small, orange_big;
  int duplicates;  // cones listed twice (dropped with a warning)
  int gates;
  bool closed;
  std::optional<Pose2> start;  // nullopt: the file has none
};

// Counts taken from the files with grep/awk: entries per list or tag, minus the repeated ones.
// fssim: the circuits repeat their first lane cone at the end of the list, acceleration and
// skidpad list one orange cone twice; pacsim skidpad/acceleration list lane cones in
// left/right (with invisible placeholders) and the rest under unknown; eufs skidpad repeats the
// first blue and the first yellow cone at the end of their circles.
const std::vector<Expected> kExpected = {
    {"fssim/FSG.yaml", 95 - 1, 89 - 1, 0, 4, 2, 1, true, Pose2{0.0, 0.0, 0.0}},
    {"fssim/FSI.yaml", 80, 75 - 1, 0, 4, 1, 1, true, Pose2{0.0, 0.0, 0.0}},
    {"fssim/acceleration.yaml", 14, 14, 42 - 1, 8, 1, 2, false, Pose2{-2.0, 0.0, 0.087}},
    {"fssim/skidpad.yaml", 29, 29, 12 - 1, 4, 1, 1, false, Pose2{-16.5, 0.0, 0.0}},
    {"pacsim/FSG19.yaml", 82, 73, 0, 0, 0, 1, true, Pose2{0.0, 0.0, 0.0}},
    {"pacsim/FSG21.yaml", 74, 60, 0, 0, 0, 1, true, Pose2{0.0, 0.0, 0.0}},
    {"pacsim/FSE23.yaml", 94, 93, 0, 0, 0, 1, true, Pose2{0.0, 0.0, 0.0}},
    {"pacsim/acceleration.yaml", 14, 14, 15 + 15 + 1, 8, 0, 2, false, Pose2{-1.98, 0.0, 0.0}},
    {"pacsim/skidpad.yaml", 13 + 16, 13 + 16, 5 + 5 + 1, 4, 0, 2, false, Pose2{-16.68, 0.0, 0.0}},
    {"eufs/acceleration.csv", 14, 14, 12, 6, 0, 2, false, Pose2{-53.0, 0.0, 0.0}},
    {"eufs/skidpad.csv", 30 - 1, 30 - 1, 20, 4, 2, 1, false, Pose2{0.0, -14.4, 1.57079632679}},
    {"epfl/fsds_competition_1_cones.csv", 85, 85, 0, 4, 0, 1, true, std::nullopt},
    {"epfl/fsds_default_cones.csv", 96, 96, 0, 4, 0, 1, true, std::nullopt},
};

class SharedFile : public ::testing::TestWithParam<Expected> {};

TEST_P(SharedFile, ImportsWithTheCountsTheFileImplies) {
  const Expected& e = GetParam();
  const Track track = read_track(data(e.file));

  // cones per class, the repeated ones dropped with a warning each
  EXPECT_EQ(track.count(ConeClass::kBlue), e.blue);
  EXPECT_EQ(track.count(ConeClass::kYellow), e.yellow);
  EXPECT_EQ(track.count(ConeClass::kOrangeSmall), e.orange_small);
  EXPECT_EQ(track.count(ConeClass::kOrangeBig), e.orange_big);
  EXPECT_EQ(track.count(ConeClass::kUnknown), 0);
  EXPECT_EQ(count_warnings(track, "copy dropped"), e.duplicates);

  // ids unique and 0..n-1
  std::set<int> ids;
  for (const Cone& c : track.cones) ids.insert(c.id);
  EXPECT_EQ(ids.size(), track.cones.size());
  EXPECT_EQ(*ids.begin(), 0);
  EXPECT_EQ(*ids.rbegin(), static_cast<int>(track.cones.size()) - 1);

  // gates, closed flag, start pose, centre line
  EXPECT_EQ(static_cast<int>(track.timing_gates.size()), e.gates);
  EXPECT_EQ(track.closed, e.closed);
  if (e.start) {
    EXPECT_NEAR(track.start.x, e.start->x, 1e-9);
    EXPECT_NEAR(track.start.y, e.start->y, 1e-9);
    EXPECT_NEAR(track.start.yaw, e.start->yaw, 1e-9);
    EXPECT_EQ(count_warnings(track, "no start pose"), 0);
  } else {
    EXPECT_EQ(count_warnings(track, "no start pose"), 1);
  }
  EXPECT_FALSE(track.left_lane.empty());
  EXPECT_FALSE(track.right_lane.empty());
  EXPECT_GE(track.centre_line.size(), 2u);
}

INSTANTIATE_TEST_SUITE_P(AllFiles, SharedFile, ::testing::ValuesIn(kExpected),
                         [](const auto& info) {
                           std::string name = info.param.file;
                           for (char& c : name)
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           return name;
                         });

// ---------------------------------------------------------------------------------------------
// closed circuits

class Circuit : public ::testing::TestWithParam<std::string> {};

TEST_P(Circuit, ClosedWithAllBoundaryConesBlueOnTheLeftAndAPlausibleLength) {
  const Track track = read_track(data(GetParam()));
  ASSERT_TRUE(track.closed);

  // every blue cone in the left lane, every yellow one in the right lane
  std::vector<int> blue, yellow;
  for (const Cone& c : track.cones) {
    if (c.cls == ConeClass::kBlue) blue.push_back(c.id);
    if (c.cls == ConeClass::kYellow) yellow.push_back(c.id);
  }
  std::vector<int> left = track.left_lane, right = track.right_lane;
  std::sort(left.begin(), left.end());
  std::sort(right.begin(), right.end());
  EXPECT_EQ(left, blue);
  EXPECT_EQ(right, yellow);

  // blue on the left and yellow on the right of the direction of travel along the centre line
  const std::vector<Vec2>& line = track.centre_line;
  ASSERT_GE(line.size(), 100u);
  const auto nearest = [&](ConeClass cls, const Vec2& p) {
    Vec2 best(1e9, 1e9);
    for (const Cone& c : track.cones)
      if (c.cls == cls && (c.position - p).norm() < (best - p).norm()) best = c.position;
    return best;
  };
  int blue_left = 0, yellow_right = 0;
  for (size_t i = 0; i < line.size(); ++i) {
    const Vec2 dir = line[(i + 1) % line.size()] - line[i];
    if (core::cross(dir, nearest(ConeClass::kBlue, line[i]) - line[i]) > 0.0) ++blue_left;
    if (core::cross(dir, nearest(ConeClass::kYellow, line[i]) - line[i]) < 0.0) ++yellow_right;
  }
  EXPECT_GT(blue_left, 0.95 * static_cast<double>(line.size()));
  EXPECT_GT(yellow_right, 0.95 * static_cast<double>(line.size()));

  // FSG rules: autocross/trackdrive laps are 200-500 m
  const double length = polyline_length(line, true);
  EXPECT_GT(length, 200.0);
  EXPECT_LT(length, 600.0);

  // the lanes begin near the start, and the start faces along the centre line
  EXPECT_LT((track.cone(track.left_lane.front()).position - track.start.position()).norm(), 6.0);
  EXPECT_LT((track.cone(track.right_lane.front()).position - track.start.position()).norm(), 6.0);
  EXPECT_GT((line[1] - line[0]).normalized().dot(track.start.heading()), 0.7);
}

INSTANTIATE_TEST_SUITE_P(AllCircuits, Circuit,
                         ::testing::Values("fssim/FSG.yaml", "fssim/FSI.yaml", "pacsim/FSG19.yaml",
                                           "pacsim/FSG21.yaml", "pacsim/FSE23.yaml",
                                           "epfl/fsds_competition_1_cones.csv",
                                           "epfl/fsds_default_cones.csv"));

// ---------------------------------------------------------------------------------------------
// what each format gives

TEST(ReadTrack, FssimKeepsTheFileOrderOfTheLanesAndIdsFollowTheFile) {
  const Track track = read_track(data("fssim/FSG.yaml"));
  // the first cones_left entry is cone 0 and begins the left lane
  EXPECT_EQ(track.cone(0).cls, ConeClass::kBlue);
  EXPECT_NEAR(track.cone(0).position.x(), -1.7667433023452759, 1e-12);
  EXPECT_NEAR(track.cone(0).position.y(), 1.4703056812286377, 1e-12);
  EXPECT_EQ(track.left_lane.front(), 0);
  for (size_t i = 0; i < track.left_lane.size(); ++i)
    EXPECT_EQ(track.left_lane[i], static_cast<int>(i));
  // tk_device: one gate at x = 6 with the left post at +y
  ASSERT_EQ(track.timing_gates.size(), 1u);
  EXPECT_EQ(track.timing_gates[0].left, Vec2(6.0, 3.0));
  EXPECT_EQ(track.timing_gates[0].right, Vec2(6.0, -3.0));
  EXPECT_EQ(track.name, "FSG");
  EXPECT_FALSE(track.event.has_value());
}

TEST(ReadTrack, PacsimGatesArePairedPostsWithTheLeftPostOnTheLeft) {
  // FSG19 lists the right post first
  const Track track = read_track(data("pacsim/FSG19.yaml"));
  ASSERT_EQ(track.timing_gates.size(), 1u);
  EXPECT_NEAR(track.timing_gates[0].left.y(), 6.806625052193919, 1e-12);
  EXPECT_NEAR(track.timing_gates[0].right.y(), -6.926741964879694, 1e-12);
}

TEST(ReadTrack, PacsimSkipsInvisibleEntriesWithAWarning) {
  const Track track = read_track(data("pacsim/acceleration.yaml"));
  EXPECT_EQ(count_warnings(track, "skipped 6 invisible"), 1);
  // lanes as given: 14 blue + 15 small orange on the left, in file order along +x
  const std::vector<Vec2> left = track.lane_points(track.left_lane);
  ASSERT_EQ(left.size(), 29u);
  for (size_t i = 0; i + 1 < left.size(); ++i) EXPECT_LT(left[i].x(), left[i + 1].x());
  EXPECT_EQ(track.event, EventType::kAcceleration);
}

TEST(ReadTrack, PacsimEarthToTrackIsTheGeodeticOriginAndDoesNotMoveCones) {
  const std::string text =
      "track:\n"
      "  earthToTrack:\n"
      "    position: [47.2, 8.5, 400.0]\n"
      "    orientation: [0.0, 0.0, 0.3]\n"
      "  left:\n"
      "  - position: [0.0, 2.0, 0.0]\n"
      "    class: blue\n"
      "  - position: [5.0, 2.0, 0.0]\n"
      "    class: blue\n"
      "  right:\n"
      "  - position: [0.0, -2.0]\n"
      "    class: yellow\n"
      "  - position: [5.0, -2.0]\n"
      "    class: yellow\n";
  const Track track = parse_track(text, TrackFormat::kPacsimYaml, "geo.yaml");
  EXPECT_EQ(track.cone(0).position, Vec2(0.0, 2.0));
  EXPECT_EQ(track.cone(3).position, Vec2(5.0, -2.0));
  EXPECT_EQ(count_warnings(track, "earthToTrack"), 1);
  EXPECT_EQ(count_warnings(track, "no start pose"), 1);
}

TEST(ReadTrack, EufsReadsCovarianceCarStartAndSkipsMidpoints) {
  const Track track = read_track(data("eufs/skidpad.csv"));
  ASSERT_TRUE(track.cone(0).covariance.has_value());
  EXPECT_DOUBLE_EQ((*track.cone(0).covariance)(0, 0), 0.01);
  EXPECT_DOUBLE_EQ((*track.cone(0).covariance)(1, 1), 0.01);
  EXPECT_DOUBLE_EQ((*track.cone(0).covariance)(0, 1), 0.0);
  EXPECT_EQ(track.count(ConeClass::kUnknown), 0);  // 30 midpoint rows skipped
  EXPECT_NEAR(track.start.yaw, 1.57079632679, 1e-12);
  EXPECT_EQ(track.event, EventType::kSkidpad);
}

TEST(ReadTrack, EufsGatesFromBigOrangeConesInTheOrderPassed) {
  const Track track = read_track(data("eufs/acceleration.csv"));
  ASSERT_EQ(track.timing_gates.size(), 2u);
  EXPECT_EQ(track.timing_gates[0].left, Vec2(-50.25, 1.5));
  EXPECT_EQ(track.timing_gates[0].right, Vec2(-50.25, -1.5));
  EXPECT_EQ(track.timing_gates[1].left, Vec2(25.0, 1.5));
}

TEST(ReadTrack, EpflHasNoCovarianceWhenTheStdsAreZeroAndAGuessedStartBehindTheGate) {
  const Track track = read_track(data("epfl/fsds_competition_1_cones.csv"));
  for (const Cone& c : track.cones) EXPECT_FALSE(c.covariance.has_value());
  // the big orange cones stand at x = -2.0 / 1.45, y = 5.57 / 6.87; the track runs along +y,
  // and the guessed start stands 6 m behind the middle of that gate
  const Vec2 gate_middle((-2.000356449999998 + 1.4522998000000067) / 2,
                         (5.571884770000005 + 6.871884770000008) / 2);
  EXPECT_NEAR((track.start.position() - gate_middle).norm(), 6.0, 1e-6);
  EXPECT_GT((gate_middle - track.start.position()).dot(track.start.heading()), 5.9);
  EXPECT_GT(track.start.heading().y(), 0.9);
  ASSERT_EQ(track.timing_gates.size(), 1u);
  EXPECT_LT(track.timing_gates[0].left.x(), track.timing_gates[0].right.x());
}

TEST(ReadTrack, EpflStandardDeviationsBecomeACovariance) {
  const std::string text =
      "cone_type,X,Y,Z,std_X,std_Y,std_Z,right,left\n"
      "blue,0.0,2.0,0.0,0.1,0.2,0.0,0,1\n"
      "yellow,0.0,-2.0,0.0,0.0,0.0,0.0,1,0\n";
  const Track track = parse_track(text, TrackFormat::kEpflCsv, "std.csv");
  ASSERT_TRUE(track.cone(0).covariance.has_value());
  EXPECT_NEAR((*track.cone(0).covariance)(0, 0), 0.01, 1e-15);
  EXPECT_NEAR((*track.cone(0).covariance)(1, 1), 0.04, 1e-15);
  EXPECT_FALSE(track.cone(1).covariance.has_value());
}

TEST(ReadTrack, EufsWithoutHeaderAsFsdsWritesIt) {
  const std::string text =
      "blue,0.0,2.0,0.0,0.0,0.0,0.0\r\n"
      "blue,5.0,2.0,0.0,0.0,0.0,0.0\r\n"
      "yellow,0.0,-2.0,0.0,0.0,0.0,0.0\r\n"
      "yellow,5.0,-2.0,0.0,0.0,0.0,0.0\r\n"
      "car_start,-3.0,0.0,0.0,0.0,0.0,0.0\r\n";
  const Track track = parse_track(text, TrackFormat::kEufsCsv, "fsds.csv");
  EXPECT_EQ(track.cones.size(), 4u);
  EXPECT_EQ(track.start.x, -3.0);
  EXPECT_EQ(track.left_lane, (std::vector<int>{0, 1}));
  EXPECT_EQ(track.right_lane, (std::vector<int>{2, 3}));
}

TEST(ReadTrack, ConesWhoseBasesWouldOverlapAreOneConeListedTwice) {
  // a blue cone 0.12 m from another (their 0.228 m bases overlap) is a copy; one 0.25 m away
  // stands beside it, and a yellow cone on the same spot is another cone
  const std::string text =
      "blue,0.0,2.0,0.0,0.0,0.0,0.0\n"
      "blue,0.12,2.0,0.0,0.0,0.0,0.0\n"
      "blue,5.0,2.0,0.0,0.0,0.0,0.0\n"
      "blue,5.25,2.0,0.0,0.0,0.0,0.0\n"
      "yellow,0.0,-2.0,0.0,0.0,0.0,0.0\n"
      "yellow,5.0,-2.0,0.0,0.0,0.0,0.0\n"
      "yellow,5.0,2.0,0.0,0.0,0.0,0.0\n";
  const Track track = parse_track(text, TrackFormat::kEufsCsv, "overlap.csv");
  EXPECT_EQ(track.count(ConeClass::kBlue), 3);
  EXPECT_EQ(track.count(ConeClass::kYellow), 3);
  ASSERT_EQ(count_warnings(track, "copy dropped"), 1);
  EXPECT_EQ(count_warnings(track,
                           "overlap.csv:2: repeats the blue cone at (0.000, 2.000) (0.12 m "
                           "apart: their bases would overlap)"),
            1);
}

TEST(ReadTrack, DetectsTheFormatFromTheContent) {
  TempDir dir;
  write_file(dir / "a.yml", "cones_left: [[0, 2], [5, 2]]\ncones_right: [[0, -2], [5, -2]]\n");
  write_file(dir / "b.csv",
             "cone_type,X,Y,Z,std_X,std_Y,std_Z,right,left\nblue,0,2,0,0,0,0,0,1\n"
             "yellow,0,-2,0,0,0,0,1,0\n");
  EXPECT_EQ(read_track(dir / "a.yml").cones.size(), 4u);
  EXPECT_EQ(read_track(dir / "b.csv").cones.size(), 2u);
}

// ---------------------------------------------------------------------------------------------
// round trips: every shared file through both writers

struct RoundTrip {
  std::string file;
  std::string ext;
};

class RoundTripTest : public ::testing::TestWithParam<RoundTrip> {};

TEST_P(RoundTripTest, SameConesStartLanesAndClosedFlag) {
  const RoundTrip& p = GetParam();
  TempDir dir;
  const Track original = read_track(data(p.file));
  const fs::path copy_file = dir / ("copy" + p.ext);
  write_track(original, copy_file);
  const Track copy = read_track(copy_file);

  // cones: same count per class, each at the same place
  for (ConeClass cls : {ConeClass::kBlue, ConeClass::kYellow, ConeClass::kOrangeSmall,
                        ConeClass::kOrangeBig, ConeClass::kUnknown})
    EXPECT_EQ(copy.count(cls), original.count(cls)) << core::to_string(cls);
  ASSERT_EQ(copy.cones.size(), original.cones.size());
  EXPECT_EQ(count_warnings(copy, "copy dropped"), 0);
  for (const Cone& c : original.cones) {
    const bool found = std::any_of(copy.cones.begin(), copy.cones.end(), [&](const Cone& k) {
      return k.cls == c.cls && (k.position - c.position).norm() < 1e-6;
    });
    EXPECT_TRUE(found) << "cone " << c.id;
  }

  // csv keeps the ids (as the file's ids of the cones), classes and covariances
  if (p.ext == ".csv") {
    for (const Cone& c : original.cones) {
      const Cone& k = cone_with_file_id(copy, original.file_id(c.id));
      EXPECT_EQ(k.cls, c.cls);
      EXPECT_LT((k.position - c.position).norm(), 1e-6);
      EXPECT_EQ(k.covariance.has_value(), c.covariance.has_value());
    }
  }

  // start pose and closed flag
  EXPECT_NEAR(copy.start.x, original.start.x, 1e-9);
  EXPECT_NEAR(copy.start.y, original.start.y, 1e-9);
  EXPECT_NEAR(copy.start.yaw, original.start.yaw, 1e-9);
  EXPECT_EQ(copy.closed, original.closed);

  // lanes: PacSim YAML carries them; CSV has none, so they are rebuilt from the colours and
  // match where the original lanes were colour lanes too (circuits, eufs and epfl files)
  const bool lanes_from_colours =
      original.closed || p.file.starts_with("eufs/") || p.file.starts_with("epfl/");
  if (p.ext == ".yaml" || lanes_from_colours) {
    const std::vector<Vec2> left = original.lane_points(original.left_lane);
    const std::vector<Vec2> right = original.lane_points(original.right_lane);
    const std::vector<Vec2> copy_left = copy.lane_points(copy.left_lane);
    const std::vector<Vec2> copy_right = copy.lane_points(copy.right_lane);
    ASSERT_EQ(copy_left.size(), left.size());
    ASSERT_EQ(copy_right.size(), right.size());
    for (size_t i = 0; i < left.size(); ++i) EXPECT_LT((copy_left[i] - left[i]).norm(), 1e-6);
    for (size_t i = 0; i < right.size(); ++i) EXPECT_LT((copy_right[i] - right[i]).norm(), 1e-6);
    if (p.ext == ".csv") {
      // the same cones by the ids the file gave them
      const auto file_ids = [](const Track& t, const std::vector<int>& lane) {
        std::vector<uint64_t> ids;
        for (int id : lane) ids.push_back(t.file_id(id));
        return ids;
      };
      EXPECT_EQ(file_ids(copy, copy.left_lane), file_ids(original, original.left_lane));
      EXPECT_EQ(file_ids(copy, copy.right_lane), file_ids(original, original.right_lane));
    }
  }

  // yaml carries the gates
  if (p.ext == ".yaml") {
    ASSERT_EQ(copy.timing_gates.size(), original.timing_gates.size());
    for (size_t i = 0; i < copy.timing_gates.size(); ++i) {
      EXPECT_LT((copy.timing_gates[i].left - original.timing_gates[i].left).norm(), 1e-6);
      EXPECT_LT((copy.timing_gates[i].right - original.timing_gates[i].right).norm(), 1e-6);
    }
  }
}

std::vector<RoundTrip> round_trips() {
  std::vector<RoundTrip> out;
  for (const Expected& e : kExpected)
    for (const char* ext : {".yaml", ".csv"}) out.push_back({e.file, ext});
  return out;
}

INSTANTIATE_TEST_SUITE_P(AllFiles, RoundTripTest, ::testing::ValuesIn(round_trips()),
                         [](const auto& info) {
                           std::string name = info.param.file + info.param.ext;
                           for (char& c : name)
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           return name;
                         });

TEST(WriteEufsCsv, IdsThatAreNotInFileOrderSurvive) {
  TempDir dir;
  Track track;
  track.name = "ids";
  track.cones = {{7, ConeClass::kBlue, {0.0, 2.0}, std::nullopt},
                 {3, ConeClass::kBlue, {5.0, 2.0}, std::nullopt},
                 {12, ConeClass::kYellow, {0.0, -2.0}, std::nullopt},
                 {0, ConeClass::kYellow, {5.0, -2.0}, std::nullopt},
                 {5, ConeClass::kUnknown, {9.0, 0.0}, std::nullopt}};
  track.left_lane = {7, 3};
  track.right_lane = {12, 0};
  track.start = {-2.0, 0.0, 0.0};
  write_eufs_csv(track, dir / "ids.csv");
  const Track copy = read_track(dir / "ids.csv");
  for (const Cone& c : track.cones) {
    EXPECT_EQ(cone_with_file_id(copy, static_cast<uint64_t>(c.id)).cls, c.cls);
    EXPECT_EQ(cone_with_file_id(copy, static_cast<uint64_t>(c.id)).position, c.position);
  }
  const auto file_ids = [&copy](const std::vector<int>& lane) {
    std::vector<int> out;
    for (int id : lane) out.push_back(static_cast<int>(copy.file_id(id)));
    return out;
  };
  EXPECT_EQ(file_ids(copy.left_lane), track.left_lane);
  EXPECT_EQ(file_ids(copy.right_lane), track.right_lane);
}

// ids anywhere in 0 .. 2^64 - 1: the cones are numbered in file order, the file's ids kept and
// written back unchanged, and nothing is sized by them
TEST(EufsCsv, IdsAnywhereIn64Bits) {
  TempDir dir;
  const std::string text =
      "tag,x,y,direction,x_variance,y_variance,xy_covariance,id,lane\n"
      "car_start,-2.0,0.0,0.0,0.0,0.0,0.0,,open\n"
      "blue,0.0,2.0,0.0,0.0,0.0,0.0,18446744073709551615,left\n"
      "blue,5.0,2.0,0.0,0.0,0.0,0.0,9223372036854775808,left\n"
      "yellow,0.0,-2.0,0.0,0.0,0.0,0.0,9223372036854775807,right\n"
      "yellow,5.0,-2.0,0.0,0.0,0.0,0.0,0,right\n"
      "unknown,9.0,0.0,0.0,0.0,0.0,0.0,,\n";
  const Track t = parse_track(text, TrackFormat::kEufsCsv, "huge.csv");
  ASSERT_EQ(t.cones.size(), 5u);
  for (size_t i = 0; i < t.cones.size(); ++i) EXPECT_EQ(t.cones[i].id, static_cast<int>(i));
  EXPECT_EQ(t.file_id(0), 18446744073709551615ull);
  EXPECT_EQ(t.file_id(1), 9223372036854775808ull);
  EXPECT_EQ(t.file_id(2), 9223372036854775807ull);
  EXPECT_EQ(t.file_id(3), 0ull);
  // a cone without an id gets the next free one after the largest (past 2^64 - 1: 1, as 0 is
  // taken)
  EXPECT_EQ(t.file_id(4), 1ull);
  write_eufs_csv(t, dir / "out.csv");
  std::ifstream in(dir / "out.csv");
  const std::string written((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_THAT(written, HasSubstr(",18446744073709551615,left\n"));
  EXPECT_THAT(written, HasSubstr(",9223372036854775808,left\n"));
  EXPECT_THAT(written, HasSubstr(",9223372036854775807,right\n"));
  const Track again = read_track(dir / "out.csv");
  EXPECT_EQ(again.file_ids, t.file_ids);
}

TEST(WriteEufsCsv, WritesTheHeaderCarStartAndTagNames) {
  TempDir dir;
  Track track;
  track.cones = {{0, ConeClass::kOrangeSmall, {1.0, 2.0}, std::nullopt},
                 {1, ConeClass::kOrangeBig, {3.0, 4.0}, std::nullopt},
                 {2, ConeClass::kUnknown, {5.0, 6.0}, std::nullopt}};
  track.start = {1.5, -2.0, 0.25};
  write_eufs_csv(track, dir / "t.csv");
  std::ifstream in(dir / "t.csv");
  std::string header, start, a, b, c;
  std::getline(in, header);
  std::getline(in, start);
  std::getline(in, a);
  std::getline(in, b);
  std::getline(in, c);
  EXPECT_EQ(header, "tag,x,y,direction,x_variance,y_variance,xy_covariance,id,lane");
  EXPECT_EQ(start, "car_start,1.5,-2.0,0.25,0.0,0.0,0.0,,open");
  EXPECT_THAT(a, ::testing::StartsWith("orange,"));
  EXPECT_THAT(b, ::testing::StartsWith("big_orange,"));
  EXPECT_THAT(c, ::testing::StartsWith("unknown,"));
}

// a figure eight of Gerono (x = a sin t, y = 0.66 a sin t cos t) with cones every 3 m each side
// of the centre line, none within 8 m of the crossing: EUFS CSV text, rows along the course
std::string figure_eight_csv() {
  constexpr int kSamples = 4000;
  const double a = 60.0, b = 0.66 * a, half_width = 1.5, spacing = 3.0;
  std::vector<Vec2> line;
  for (int i = 0; i < kSamples; ++i) {
    const double t = 2.0 * std::numbers::pi * i / kSamples;
    line.emplace_back(a * std::sin(t), b * std::sin(t) * std::cos(t));
  }
  std::vector<double> s{0.0};
  for (int i = 1; i <= kSamples; ++i)
    s.push_back(s.back() + (line[i % kSamples] - line[i - 1]).norm());
  std::string csv = "tag,x,y,direction,x_variance,y_variance,xy_covariance\n";
  const int cones = static_cast<int>(s.back() / spacing);
  for (int k = 0, j = 0; k < cones; ++k) {
    const double at = k * s.back() / cones;
    while (s[j + 1] < at) ++j;
    const Vec2 p0 = line[j], p1 = line[(j + 1) % kSamples];
    const Vec2 p = p0 + (at - s[j]) / (s[j + 1] - s[j]) * (p1 - p0);
    const Vec2 normal = Vec2(-(p1 - p0).y(), (p1 - p0).x()).normalized();
    if (p.norm() < 8.0) continue;
    for (const auto& [tag, side] : {std::pair{"blue", 1.0}, std::pair{"yellow", -1.0}}) {
      // millimetres, as surveyed layouts give them
      const Vec2 c = p + side * half_width * normal;
      char row[80];
      std::snprintf(row, sizeof row, "%s,%.3f,%.3f,0,0,0,0\n", tag, c.x(), c.y());
      csv += row;
    }
  }
  return csv;
}

TEST(RoundTrip, CsvYamlCsvKeepsTheLanesAndTheClosedFlagOfAFigureEight) {
  // the lanes of a figure eight cannot be told from the colours alone: conesim's CSV carries
  // them (issue 20 item 10: the round trip turned the closed track into an open one)
  TempDir dir;
  write_file(dir / "eight.csv", figure_eight_csv());
  const Track first = read_track(dir / "eight.csv");
  ASSERT_TRUE(first.closed);
  write_track(first, dir / "eight.yaml");
  const Track yaml = read_track(dir / "eight.yaml");
  write_track(yaml, dir / "eight2.csv");
  const Track again = read_track(dir / "eight2.csv");
  EXPECT_TRUE(yaml.closed);
  EXPECT_TRUE(again.closed);
  EXPECT_EQ(again.left_lane.size(), first.left_lane.size());
  EXPECT_EQ(again.right_lane.size(), first.right_lane.size());
  // and once more: the files are the same
  write_track(again, dir / "eight3.csv");
  std::ifstream f2(dir / "eight2.csv"), f3(dir / "eight3.csv");
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(f2), {}),
            std::string(std::istreambuf_iterator<char>(f3), {}));
}

TEST(ReadTrack, ConesimCsvLaneColumnIsChecked) {
  const std::string header = "tag,x,y,direction,x_variance,y_variance,xy_covariance,id,lane\n";
  try {
    parse_track(header + "blue,1,2,0,0,0,0,0,middle\n", TrackFormat::kEufsCsv, "l.csv");
    FAIL() << "a bad lane was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("l.csv:2: lane: expected left, right"), std::string::npos)
        << e.what();
  }
}

// a UTF-8 byte-order mark before the header is no data (issue 20 item 10)
TEST(ReadTrack, ByteOrderMarkIsIgnored) {
  const Track t = parse_track(
      "\xEF\xBB\xBFtag,x,y,direction,x_variance,y_variance,xy_covariance\n"
      "blue,0,2,0,0,0,0\nblue,5,2,0,0,0,0\nyellow,0,-2,0,0,0,0\n",
      TrackFormat::kEufsCsv, "bom.csv");
  EXPECT_EQ(t.cones.size(), 3u);
}

// a key given twice is no longer silent (issue 20 item 8)
TEST(ReadTrack, KeyGivenTwiceIsAWarningWithBothLines) {
  const Track t = parse_track(
      "cones_left: [[0, 2], [5, 2]]\ncones_right: [[0, -2], [5, -2]]\ncones_left: [[10, 2]]\n",
      TrackFormat::kFssimYaml, "twice.yaml");
  bool warned = false;
  for (const std::string& w : t.warnings)
    warned = warned ||
             w.find("twice.yaml:3: cones_left: given again (also on line 1)") != std::string::npos;
  EXPECT_TRUE(warned) << ::testing::PrintToString(t.warnings);
}

TEST(WriteTrack, UnknownExtensionIsAnInputError) {
  TempDir dir;
  EXPECT_THROW(write_track(Track{}, dir / "t.json"), InputError);
}

// ---------------------------------------------------------------------------------------------
// bad input: an InputError naming the file, the line or key, and what was expected

constexpr const char* kEufsHeaderLine = "tag,x,y,direction,x_variance,y_variance,xy_covariance\n";

TEST(BadInput, MalformedYamlNamesTheParserLine) {
  const InputError e = parse_error("cones_left:\n  - [0, 1]\n  - [2, 3\ncones_right: []\n",
                                   TrackFormat::kFssimYaml, "bad.yaml");
  EXPECT_THAT(e.what(), HasSubstr("bad.yaml:"));
  EXPECT_THAT(e.what(), HasSubstr("malformed YAML"));
  EXPECT_GE(e.line(), 3);
}

TEST(BadInput, DeeplyNestedYamlIsRefusedWithoutCrashing) {
  const std::string text = "cones_left: " + std::string(100000, '[');
  EXPECT_THROW(parse_track(text, TrackFormat::kFssimYaml, "deep.yaml"), InputError);
}

TEST(BadInput, UnknownPacsimClass) {
  const InputError e = parse_error(
      "track:\n  left:\n  - position: [0.0, 1.0, 0.0]\n    class: purple\n  right: []\n",
      TrackFormat::kPacsimYaml, "p.yaml");
  EXPECT_EQ(e.line(), 4);
  EXPECT_THAT(e.what(), HasSubstr("p.yaml:4: left: unknown cone class 'purple' (expected blue"));
}

TEST(BadInput, UnknownEufsTag) {
  const InputError e = parse_error(std::string(kEufsHeaderLine) + "green,0,1,0,0,0,0\n",
                                   TrackFormat::kEufsCsv, "e.csv");
  EXPECT_THAT(e.what(), HasSubstr("e.csv:2: tag: unknown tag 'green' (expected blue"));
}

TEST(BadInput, UnknownEpflConeType) {
  const InputError e =
      parse_error("cone_type,X,Y,Z,std_X,std_Y,std_Z,right,left\nred,0,1,0,0,0,0,0,1\n",
                  TrackFormat::kEpflCsv, "f.csv");
  EXPECT_THAT(e.what(), HasSubstr("f.csv:2: cone_type: unknown type 'red'"));
}

TEST(BadInput, NanCoordinateInCsv) {
  const InputError e =
      parse_error(std::string(kEufsHeaderLine) + "blue,0,1,0,0,0,0\nblue,nan,1,0,0,0,0\n",
                  TrackFormat::kEufsCsv, "n.csv");
  EXPECT_THAT(e.what(), HasSubstr("n.csv:3: x: expected a finite number, found 'nan'"));
}

TEST(BadInput, InfiniteCoordinateInCsv) {
  const InputError e = parse_error(std::string(kEufsHeaderLine) + "blue,0,-inf,0,0,0,0\n",
                                   TrackFormat::kEufsCsv, "i.csv");
  EXPECT_THAT(e.what(), HasSubstr("i.csv:2: y: expected a finite number"));
}

TEST(BadInput, OverflowingCoordinateInCsv) {
  const InputError e = parse_error(std::string(kEufsHeaderLine) + "blue,1e999,0,0,0,0,0\n",
                                   TrackFormat::kEufsCsv, "o.csv");
  EXPECT_THAT(e.what(), HasSubstr("o.csv:2: x: expected a finite number"));
}

TEST(BadInput, NanAndInfinityInYaml) {
  const InputError nan = parse_error("cones_left:\n- [.nan, 1.0]\ncones_right: []\n",
                                     TrackFormat::kFssimYaml, "n.yaml");
  EXPECT_THAT(nan.what(), HasSubstr("n.yaml:2: cones_left x: expected a finite number"));
  const InputError inf = parse_error("cones_left: []\ncones_right:\n- [1.0, -.inf]\n",
                                     TrackFormat::kFssimYaml, "i.yaml");
  EXPECT_THAT(inf.what(), HasSubstr("i.yaml:3: cones_right y: expected a finite number"));
}

TEST(BadInput, HugeCoordinates) {
  EXPECT_THAT(parse_error(std::string(kEufsHeaderLine) + "blue,1e300,0,0,0,0,0\n",
                          TrackFormat::kEufsCsv, "h.csv")
                  .what(),
              HasSubstr("h.csv:2: x: expected a coordinate within +-1e7 m, found '1e300'"));
  EXPECT_THAT(
      parse_error("cones_left:\n- [0, -2e9]\ncones_right: []\n", TrackFormat::kFssimYaml, "h.yaml")
          .what(),
      HasSubstr("h.yaml:2: cones_left: expected coordinates within +-1e7 m"));
}

TEST(BadInput, EmptyFile) {
  EXPECT_THAT(parse_error("", TrackFormat::kEufsCsv, "empty.csv").what(),
              HasSubstr("empty.csv: the file is empty"));
  EXPECT_THAT(parse_error("  \n\n", TrackFormat::kPacsimYaml, "empty.yaml").what(),
              HasSubstr("the file is empty"));
  TempDir dir;
  write_file(dir / "empty.yaml", "");
  EXPECT_THAT(read_error(dir / "empty.yaml").what(), HasSubstr("the file is empty"));
}

TEST(BadInput, NoConesAtAll) {
  EXPECT_THAT(parse_error(kEufsHeaderLine, TrackFormat::kEufsCsv, "h.csv").what(),
              HasSubstr("h.csv: expected at least one cone"));
}

TEST(BadInput, MissingColumns) {
  const InputError e =
      parse_error(std::string(kEufsHeaderLine) + "blue,0,1,0\n", TrackFormat::kEufsCsv, "m.csv");
  EXPECT_THAT(e.what(), HasSubstr("m.csv:2: expected 7 columns (tag,x,y,direction,x_variance,"
                                  "y_variance,xy_covariance), found 4"));
}

TEST(BadInput, WrongColumnCount) {
  const InputError e =
      parse_error("cone_type,X,Y,Z,std_X,std_Y,std_Z,right,left\nblue,0,1,0,0,0,0,0,1,7\n",
                  TrackFormat::kEpflCsv, "w.csv");
  EXPECT_THAT(e.what(), HasSubstr("w.csv:2: expected 9 columns"));
  EXPECT_THAT(e.what(), HasSubstr("found 10"));
}

TEST(BadInput, WrongHeader) {
  EXPECT_THAT(parse_error("tag,x,y\nblue,0,1\n", TrackFormat::kEufsCsv, "h.csv").what(),
              HasSubstr("h.csv:1: expected the header tag,x,y,direction"));
  EXPECT_THAT(parse_error("blue,0,1,0,0,0,0,0,1\n", TrackFormat::kEpflCsv, "h2.csv").what(),
              HasSubstr("h2.csv:1: expected the header cone_type,X,Y"));
}

TEST(BadInput, NotANumber) {
  const InputError e = parse_error(std::string(kEufsHeaderLine) + "blue,1.5,abc,0,0,0,0\n",
                                   TrackFormat::kEufsCsv, "x.csv");
  EXPECT_THAT(e.what(), HasSubstr("x.csv:2: y: expected a number, found 'abc'"));
  const InputError trailing = parse_error(std::string(kEufsHeaderLine) + "blue,1.5m,0,0,0,0,0\n",
                                          TrackFormat::kEufsCsv, "x.csv");
  EXPECT_THAT(trailing.what(), HasSubstr("x.csv:2: x: expected a number, found '1.5m'"));
  const InputError yaml = parse_error("cones_left:\n- [1.0, two]\ncones_right: []\n",
                                      TrackFormat::kFssimYaml, "x.yaml");
  EXPECT_THAT(yaml.what(), HasSubstr("x.yaml:2: cones_left y: expected a number, found 'two'"));
}

TEST(BadInput, NegativeVariance) {
  const InputError e = parse_error(std::string(kEufsHeaderLine) + "blue,0,1,0,-0.1,0,0\n",
                                   TrackFormat::kEufsCsv, "v.csv");
  EXPECT_THAT(e.what(), HasSubstr("v.csv:2: x_variance: expected a value >= 0"));
}

TEST(BadInput, RepeatedIdAndBadId) {
  const std::string header = "tag,x,y,direction,x_variance,y_variance,xy_covariance,id\n";
  EXPECT_THAT(parse_error(header + "blue,0,1,0,0,0,0,4\nblue,5,1,0,0,0,0,4\n",
                          TrackFormat::kEufsCsv, "id.csv")
                  .what(),
              HasSubstr("id.csv:3: id: 4 is already used on line 2"));
  EXPECT_THAT(parse_error(header + "blue,0,1,0,0,0,0,-2\n", TrackFormat::kEufsCsv, "id.csv").what(),
              HasSubstr("id.csv:2: id: expected an integer from 0 to 18446744073709551615, "
                        "found '-2'"));
  EXPECT_THAT(parse_error(header + "blue,0,1,0,0,0,0,18446744073709551616\n", TrackFormat::kEufsCsv,
                          "id.csv")
                  .what(),
              HasSubstr("id.csv:2: id: expected an integer from 0 to 18446744073709551615"));
  EXPECT_THAT(parse_error(header + "blue,0,1,0,0,0,0,18446744073709551615\n"
                                   "blue,5,1,0,0,0,0,18446744073709551615\n",
                          TrackFormat::kEufsCsv, "id.csv")
                  .what(),
              HasSubstr("id.csv:3: id: 18446744073709551615 is already used on line 2"));
}

TEST(BadInput, SecondCarStart) {
  const InputError e =
      parse_error(std::string(kEufsHeaderLine) +
                      "car_start,0,0,0,0,0,0\nblue,0,1,0,0,0,0\ncar_start,1,0,0,0,0,0\n",
                  TrackFormat::kEufsCsv, "s.csv");
  EXPECT_THAT(e.what(), HasSubstr("s.csv:4: a second car_start row (the first is on line 2)"));
}

TEST(BadInput, HugeFileIsRefusedBeforeReading) {
  TempDir dir;
  const fs::path file = dir / "huge.csv";
  write_file(file, "");
  fs::resize_file(file, kMaxTrackFileBytes + 1);  // sparse: nothing is written
  const InputError e = read_error(file);
  EXPECT_THAT(e.what(), HasSubstr("larger than the limit"));
  EXPECT_THROW(parse_track(std::string(kMaxTrackFileBytes + 1, ' '), TrackFormat::kEufsCsv, "big"),
               InputError);
}

TEST(BadInput, TooManyCones) {
  std::string text = kEufsHeaderLine;
  for (size_t i = 0; i <= kMaxTrackCones; ++i) text += "blue," + std::to_string(i) + ",0,0,0,0,0\n";
  EXPECT_THAT(parse_error(text, TrackFormat::kEufsCsv, "many.csv").what(),
              HasSubstr("more than 100000 cones"));
}

TEST(BadInput, MissingFileAndDirectory) {
  TempDir dir;
  EXPECT_THAT(read_error(dir / "nope.yaml").what(), HasSubstr("nope.yaml: cannot open"));
  fs::create_directories(dir / "sub.csv");
  EXPECT_THAT(read_error(dir / "sub.csv").what(), HasSubstr("not a regular file"));
}

TEST(BadInput, UnknownExtensionAndUnknownYamlLayout) {
  TempDir dir;
  write_file(dir / "t.txt", "blue,0,1,0,0,0,0\n");
  EXPECT_THAT(read_error(dir / "t.txt").what(), HasSubstr("unknown extension '.txt'"));
  write_file(dir / "t.yaml", "cones: []\n");
  EXPECT_THAT(read_error(dir / "t.yaml").what(), HasSubstr("expected a mapping with track:"));
}

TEST(BadInput, ConePositionThatIsNotATwoOrThreeElementList) {
  const InputError scalar =
      parse_error("cones_left:\n- 1.0\ncones_right: []\n", TrackFormat::kFssimYaml, "p.yaml");
  EXPECT_THAT(scalar.what(),
              HasSubstr("p.yaml:2: cones_left: expected a position [x, y] or [x, y, z]"));
  const InputError one =
      parse_error("track:\n  left:\n  - position: [1.0]\n    class: blue\n  right: []\n",
                  TrackFormat::kPacsimYaml, "p.yaml");
  EXPECT_THAT(one.what(), HasSubstr("p.yaml:3: left: position: expected a position"));
  const InputError four =
      parse_error("track:\n  left: []\n  right:\n  - position: [1, 2, 3, 4]\n    class: yellow\n",
                  TrackFormat::kPacsimYaml, "p.yaml");
  EXPECT_THAT(four.what(), HasSubstr("p.yaml:4: right: position: expected a position"));
}

TEST(BadInput, MissingKeys) {
  EXPECT_THAT(parse_error("cones_left: []\n", TrackFormat::kFssimYaml, "k.yaml").what(),
              HasSubstr("k.yaml: cones_right: missing"));
  EXPECT_THAT(parse_error("track:\n  right: []\n", TrackFormat::kPacsimYaml, "k.yaml").what(),
              HasSubstr("k.yaml: track.left: missing"));
  EXPECT_THAT(parse_error("track:\n  left:\n  - class: blue\n  right: []\n",
                          TrackFormat::kPacsimYaml, "k.yaml")
                  .what(),
              HasSubstr("k.yaml:3: left: position: missing"));
  EXPECT_THAT(parse_error("cones_left: []\ncones_right: []\nstarting_pose_front_wing: [1, 2]\n",
                          TrackFormat::kFssimYaml, "k.yaml")
                  .what(),
              HasSubstr("k.yaml:3: starting_pose_front_wing [x, y, yaw]: expected a list of 3"));
}

TEST(BadInput, WrongYamlShapes) {
  EXPECT_THAT(parse_error("- 1\n- 2\n", TrackFormat::kFssimYaml, "s.yaml").what(),
              HasSubstr("s.yaml:1: expected a mapping"));
  EXPECT_THAT(parse_error("track: 3\n", TrackFormat::kPacsimYaml, "s.yaml").what(),
              HasSubstr("s.yaml:1: track: expected a mapping"));
  EXPECT_THAT(
      parse_error("cones_left: 5\ncones_right: []\n", TrackFormat::kFssimYaml, "s.yaml").what(),
      HasSubstr("s.yaml:1: cones_left: expected a list"));
  EXPECT_THAT(parse_error("track:\n  lanesFirstWithLastConnected: maybe\n  left: []\n  right: []\n",
                          TrackFormat::kPacsimYaml, "s.yaml")
                  .what(),
              HasSubstr("s.yaml:2: lanesFirstWithLastConnected: expected true or false"));
}

// damaged copies of the real files (cut short, bytes changed) give a track or an InputError,
// never another exception, a crash or a hang
TEST(BadInput, DamagedFilesNeverCrash) {
  std::mt19937 rng(2026);
  const std::vector<std::pair<std::string, TrackFormat>> files = {
      {"fssim/FSI.yaml", TrackFormat::kFssimYaml},
      {"pacsim/skidpad.yaml", TrackFormat::kPacsimYaml},
      {"eufs/acceleration.csv", TrackFormat::kEufsCsv},
      {"epfl/fsds_competition_1_cones.csv", TrackFormat::kEpflCsv}};
  const std::string noise = "-.,:[]{}\n #&*!0123456789eEnaif";
  int parsed = 0, refused = 0;
  for (const auto& [file, format] : files) {
    std::ifstream in(data(file), std::ios::binary);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    for (int trial = 0; trial < 40; ++trial) {
      std::string damaged = text;
      if (trial % 2 == 0) {
        damaged.resize(std::uniform_int_distribution<size_t>(0, text.size())(rng));
      } else {
        for (int k = 0; k < 3; ++k)
          damaged[std::uniform_int_distribution<size_t>(0, text.size() - 1)(rng)] =
              noise[std::uniform_int_distribution<size_t>(0, noise.size() - 1)(rng)];
      }
      try {
        parse_track(damaged, format, file);
        ++parsed;
      } catch (const InputError&) {
        ++refused;
      }
    }
  }
  EXPECT_GT(parsed, 0);
  EXPECT_GT(refused, 0);
}

}  // namespace
}  // namespace conesim::tracks
