#include "tests/fuzz/harness.hpp"

#include <unistd.h>

#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "sim/regress.hpp"
#include "sim/scenario.hpp"

namespace conesim::fuzz {
namespace {

namespace fs = std::filesystem;
using core::InputError;

const fs::path& scratch_dir() {
  static const fs::path dir = [] {
    const fs::path d = fs::temp_directory_path() / ("conesim-fuzz-" + std::to_string(::getpid()));
    fs::create_directories(d);
    // gone again when the fuzzer exits normally (after -runs or -max_total_time)
    std::atexit([] {
      std::error_code ec;
      fs::remove_all(fs::temp_directory_path(ec) / ("conesim-fuzz-" + std::to_string(::getpid())), ec);
    });
    return d;
  }();
  return dir;
}

// the scenario loader: the YAML text, then after a line "#--set" one --set override a line (a
// YAML comment, so that the shipped scenarios are seeds as they are)
std::string scenario_target(std::string_view input) {
  const std::string marker = "\n#--set\n";
  const size_t at = input.find(marker);
  const std::string yaml(input.substr(0, at));
  std::vector<std::string> overrides;
  if (at != std::string_view::npos) {
    std::string_view rest = input.substr(at + marker.size());
    while (!rest.empty()) {
      const size_t nl = rest.find('\n');
      if (std::string_view line = rest.substr(0, nl); !line.empty()) overrides.emplace_back(line);
      if (nl == std::string_view::npos) break;
      rest.remove_prefix(nl + 1);
    }
  }
  const fs::path file = scratch_dir() / "fuzz.yaml";
  {
    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    out << yaml;
  }
  try {
    sim::load_scenario(file, overrides);
  } catch (const InputError& e) {
    return check_names(e, file.string());
  } catch (const std::exception& e) {
    return "load_scenario threw " + describe(e);
  }
  return "";
}

// a regress baseline (summary.json) and a run's metrics.json, as regress reads them
std::string regress_json_target(std::string_view input) {
  const std::string name = "summary.json";
  const std::string text(input);

  // as a baseline: compared with itself, then the summaries written from it
  try {
    std::vector<sim::RunRow> baseline = sim::parse_baseline(text, name);
    std::vector<sim::RunRow> rows = baseline;
    const sim::BaselineComparison c = sim::compare_to_baseline(rows, baseline);
    sim::junit_xml(rows, 1.0, &c);
    for (const sim::RunRow& r : rows) sim::row_to_json(r).dump();
  } catch (const InputError& e) {
    if (std::string p = check_names(e, name); !p.empty()) return p;
  } catch (const std::exception& e) {
    return "a baseline threw " + describe(e);
  }

  // as a run's metrics.json (regress reads any JSON there and gives the run a row)
  const nlohmann::json metrics = nlohmann::json::parse(text, nullptr, false);
  if (metrics.is_discarded()) return "";
  try {
    sim::RegressionRun run;
    run.scenario = "trackdrive";
    sim::row_to_json(sim::make_row(run, metrics, 0)).dump();
  } catch (const std::exception& e) {
    return "a metrics.json threw " + describe(e);
  }
  return "";
}

}  // namespace

const std::vector<std::string>& targets() {
  static const std::vector<std::string> all = {"fssim_yaml", "pacsim_yaml", "eufs_csv",
                                               "epfl_csv",   "scenario",    "regress_json"};
  return all;
}

std::string run_target(const std::string& name, std::string_view input) {
  if (name == "scenario") return scenario_target(input);
  if (name == "regress_json") return regress_json_target(input);
  return run_track_target(name, input);
}

}  // namespace conesim::fuzz
