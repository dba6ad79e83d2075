#include "sim/regress.hpp"

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <ostream>

namespace conesim::sim {

namespace fs = std::filesystem;

namespace {

// starts `argv` with stdout and stderr into log_file; returns the child's pid
pid_t spawn(const std::vector<std::string>& argv, const fs::path& log_file) {
  const pid_t pid = fork();
  if (pid < 0) return -1;
  if (pid == 0) {
    const int fd = open(log_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
      dup2(fd, STDOUT_FILENO);
      dup2(fd, STDERR_FILENO);
      close(fd);
    }
    std::vector<char*> args;
    for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    execv(args[0], args.data());
    _exit(127);
  }
  return pid;
}

std::string format_row(const std::vector<std::string>& cells, const std::vector<int>& widths) {
  std::string row;
  for (size_t i = 0; i < cells.size(); ++i) {
    std::string c = cells[i];
    if (static_cast<int>(c.size()) < widths[i]) c.resize(widths[i], ' ');
    row += (i ? "  " : "") + c;
  }
  while (!row.empty() && row.back() == ' ') row.pop_back();
  return row;
}

}  // namespace

std::vector<RegressionRun> default_regression(const std::vector<std::string>& scenarios) {
  // circuits vary with the seed; the FSG layouts do not, so one seed each
  const std::map<std::string, std::vector<unsigned long long>> seeds = {
      {"skidpad", {1}}, {"acceleration", {1}}, {"autocross", {1, 2, 3}}, {"trackdrive", {1, 2}}};
  std::vector<std::string> names = scenarios;
  if (names.empty()) names = {"skidpad", "acceleration", "autocross", "trackdrive"};
  std::vector<RegressionRun> runs;
  for (const std::string& n : names) {
    const auto it = seeds.find(n);
    if (it == seeds.end()) {
      runs.push_back({n, 1});
      continue;
    }
    for (unsigned long long seed : it->second) runs.push_back({n, seed});
  }
  return runs;
}

fs::path make_run_dir(const fs::path& parent, const std::string& name) {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char stamp[32];
  std::strftime(stamp, sizeof(stamp), "%Y%m%d-%H%M%S", &utc);
  fs::create_directories(parent);
  for (int i = 1;; ++i) {
    std::string leaf = name;
    leaf.append("-").append(stamp);
    if (i > 1) leaf.append("-").append(std::to_string(i));
    const fs::path dir = parent / leaf;
    if (fs::create_directory(dir)) return dir;
  }
}

int run_regression(const fs::path& self, const std::vector<RegressionRun>& runs, int jobs,
                   const fs::path& out_dir, std::ostream& out) {
  fs::create_directories(out_dir);
  std::vector<fs::path> dirs;
  for (const auto& r : runs)
    dirs.push_back(out_dir / (fs::path(r.scenario).stem().string() + "-s" + std::to_string(r.seed)));

  // run them, at most `jobs` at once
  std::map<pid_t, size_t> running;
  std::vector<int> exit_codes(runs.size(), -1);
  size_t next = 0;
  while (next < runs.size() || !running.empty()) {
    while (next < runs.size() && static_cast<int>(running.size()) < std::max(jobs, 1)) {
      fs::create_directories(dirs[next]);
      const pid_t pid = spawn({self.string(), "run", runs[next].scenario, "--seed",
                               std::to_string(runs[next].seed), "--out", dirs[next].string()},
                              dirs[next] / "log.txt");
      if (pid > 0) running[pid] = next;
      ++next;
    }
    int status = 0;
    const pid_t done = wait(&status);
    if (done < 0) break;
    const auto it = running.find(done);
    if (it == running.end()) continue;
    exit_codes[it->second] = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    running.erase(it);
  }

  // the table
  const std::vector<int> widths = {12, 22, 4, 9, 9, 9, 6, 7, 4};
  out << format_row({"event", "track", "seed", "completed", "time_s", "cones_hit", "off", "rtf",
                     "pass"},
                    widths)
      << "\n";
  int failed = 0;
  for (size_t i = 0; i < runs.size(); ++i) {
    nlohmann::json m;
    std::ifstream in(dirs[i] / "metrics.json");
    bool ok = false;
    if (in) {
      try {
        in >> m;
        ok = true;
      } catch (const std::exception&) {
      }
    }
    if (!ok) {
      out << format_row({runs[i].scenario, "-", std::to_string(runs[i].seed), "crashed", "-", "-",
                         "-", "-", "FAIL"},
                        widths)
          << "   (exit " << exit_codes[i] << ", see " << (dirs[i] / "log.txt").string() << ")\n";
      ++failed;
      continue;
    }
    const bool passed = m.value("passed", false) && exit_codes[i] == 0;
    char time_s[32], rtf[32];
    std::snprintf(time_s, sizeof(time_s), "%.2f", m.value("final_time_s", 0.0));
    std::snprintf(rtf, sizeof(rtf), "%.0fx", m.value("real_time_factor", 0.0));
    out << format_row({m.value("event", ""), m.value("track", ""), std::to_string(runs[i].seed),
                       m.value("completed", false) ? "yes" : "DNF", time_s,
                       std::to_string(m["penalties"].value("cones_hit", 0)),
                       std::to_string(m["penalties"].value("off_course", 0)), rtf,
                       passed ? "ok" : "FAIL"},
                      widths);
    if (!m.value("dnf_reason", std::string()).empty()) out << "   " << m.value("dnf_reason", "");
    out << "\n";
    if (!passed) ++failed;
  }
  out << runs.size() - failed << " passed, " << failed << " failed\n";
  return failed;
}

}  // namespace conesim::sim
