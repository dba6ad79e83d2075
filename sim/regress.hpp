#pragma once
// The regression: shipped scenarios over several seeds, in parallel processes, one table row
// per run.

#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

namespace conesim::sim {

/// One run of the regression.
struct RegressionRun {
  std::string scenario;
  unsigned long long seed = 1;
};

/// The default set: every shipped event over several seeds.
std::vector<RegressionRun> default_regression(const std::vector<std::string>& scenarios = {});

/// Runs each as `<self> run SCENARIO --seed N --out DIR/<scenario>-s<N>` with at most `jobs`
/// processes at once, prints the table to `out` and returns the number of runs that did not
/// pass (a run that crashed or wrote no metrics.json counts as failed).
int run_regression(const std::filesystem::path& self, const std::vector<RegressionRun>& runs,
                   int jobs, const std::filesystem::path& out_dir, std::ostream& out);

/// A fresh run directory under `parent` named <name>-<UTC stamp>, made unique with a suffix.
std::filesystem::path make_run_dir(const std::filesystem::path& parent, const std::string& name);

}  // namespace conesim::sim
