// Every input a fuzz target found a problem with (tests/data/fuzz/<target>/, each fixed at its
// cause), and the seeds of the targets' corpora, replayed through the same harness as the fuzz
// targets: each is read, or refused as bad input should be.

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "tests/fuzz/harness.hpp"

namespace conesim::fuzz {
namespace {

namespace fs = std::filesystem;

std::string read_file(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// the regular files of a folder, sorted (none when it does not exist)
std::vector<fs::path> files_in(const fs::path& dir) {
  std::vector<fs::path> files;
  if (fs::is_directory(dir))
    for (const auto& e : fs::directory_iterator(dir))
      if (e.is_regular_file()) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  return files;
}

const fs::path kFindings = fs::path(CONESIM_TEST_DATA) / "fuzz";

// tests/fuzz/targets.txt: each target's seed folders, relative to the source tree
std::map<std::string, std::vector<std::string>> seed_dirs() {
  std::map<std::string, std::vector<std::string>> dirs;
  std::ifstream in(fs::path(CONESIM_SOURCE_DIR) / "tests/fuzz/targets.txt");
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream words(line);
    std::string name, dir;
    words >> name;
    auto& list = dirs[name];
    while (words >> dir) list.push_back(dir);
  }
  return dirs;
}

class FuzzTarget : public ::testing::TestWithParam<std::string> {};

// the inputs a fuzzer found: each one crashed, hung or misread before its fix
TEST_P(FuzzTarget, FindingsAreReadOrRefused) {
  const std::vector<fs::path> files = files_in(kFindings / GetParam());
  if (files.empty()) GTEST_SKIP() << "no findings of " << GetParam();
  for (const fs::path& f : files) EXPECT_EQ(run_target(GetParam(), read_file(f)), "") << f;
}

// the seeds of the corpus: the shipped layouts and scenarios, and the hand-written seeds
TEST_P(FuzzTarget, SeedsAreReadOrRefused) {
  const auto all = seed_dirs();
  const auto it = all.find(GetParam());
  ASSERT_NE(it, all.end()) << GetParam() << " is not in tests/fuzz/targets.txt";
  std::vector<fs::path> dirs = {fs::path(CONESIM_SOURCE_DIR) / "tests/fuzz/seeds" / GetParam()};
  for (const std::string& d : it->second) dirs.push_back(fs::path(CONESIM_SOURCE_DIR) / d);
  size_t count = 0;
  for (const fs::path& dir : dirs)
    for (const fs::path& f : files_in(dir)) {
      EXPECT_EQ(run_target(GetParam(), read_file(f)), "") << f;
      ++count;
    }
  EXPECT_GT(count, 0u) << "no seeds for " << GetParam();
}

INSTANTIATE_TEST_SUITE_P(Targets, FuzzTarget, ::testing::ValuesIn(targets()),
                         [](const auto& info) { return info.param; });

// every folder of findings belongs to a target (a misspelt one would never be replayed)
TEST(FuzzFindings, EveryFolderIsATarget) {
  const std::vector<std::string>& names = targets();
  if (!fs::is_directory(kFindings)) return;
  for (const auto& e : fs::directory_iterator(kFindings))
    EXPECT_NE(std::find(names.begin(), names.end(), e.path().filename().string()), names.end())
        << e.path();
}

// targets.txt, which the fuzz runner reads, lists exactly the harness's targets
TEST(FuzzFindings, TargetListMatchesTheHarness) {
  std::vector<std::string> listed;
  for (const auto& [name, dirs] : seed_dirs()) listed.push_back(name);
  std::vector<std::string> names = targets();
  std::sort(names.begin(), names.end());
  EXPECT_EQ(listed, names);
}

// the harness reports what a user would notice: an input that reads is "", and a target that
// does not exist is an error rather than a silent pass
TEST(FuzzHarness, ReadsAGoodLayoutAndKnowsItsTargets) {
  const std::string csv =
      "tag,x,y,direction,x_variance,y_variance,xy_covariance\n"
      "car_start,0,0,0,0,0,0\nblue,5,2,0,0,0,0\nyellow,5,-2,0,0,0,0\n";
  EXPECT_EQ(run_target("eufs_csv", csv), "");
  EXPECT_THROW(run_target("no_such_target", csv), std::invalid_argument);
}

}  // namespace
}  // namespace conesim::fuzz
