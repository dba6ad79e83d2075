#include "sim/gnuplot.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <system_error>

namespace conesim::sim {

namespace {

// runs argv without a shell, returns the exit status and what it wrote to stderr
int run_process(const std::vector<std::string>& argv, const std::filesystem::path& stderr_file) {
  const pid_t pid = fork();
  if (pid < 0) throw std::system_error(errno, std::generic_category(), "fork");
  if (pid == 0) {
    FILE* err = std::fopen(stderr_file.c_str(), "w");
    if (err) dup2(fileno(err), STDERR_FILENO);
    std::vector<char*> args;
    for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    execvp(args[0], args.data());
    _exit(127);
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) throw std::system_error(errno, std::generic_category(), "waitpid");
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128;
}

}  // namespace

std::string ranges_if_nothing_to_plot(const std::vector<PlotData>& data) {
  for (const PlotData& d : data)
    for (const auto& row : d.rows)
      for (size_t k = 1; k < row.size(); ++k)
        if (std::isfinite(row[0]) && std::isfinite(row[k])) return "";
  return "set xrange [0:10]\nset yrange [0:1]\n";
}

void render_png(const std::string& script, const std::vector<PlotData>& data,
                const std::filesystem::path& out_png, int width_px, int height_px) {
  namespace fs = std::filesystem;
  const fs::path partial = out_png.string() + ".partial";
  const fs::path script_file = out_png.string() + ".gp";
  const fs::path err_file = out_png.string() + ".err";

  // the script: terminal, inline data blocks, then the caller's plot commands
  {
    std::ofstream gp(script_file);
    if (!gp) throw std::runtime_error(script_file.string() + ": cannot write the plot script");
    gp << "set terminal pngcairo size " << width_px << "," << height_px
       << " noenhanced font 'sans,10'\n";
    gp << "set output '" << partial.string() << "'\n";
    gp.precision(10);
    for (const PlotData& d : data) {
      gp << "$" << d.name << " << EOD\n";
      for (const auto& row : d.rows) {
        for (size_t i = 0; i < row.size(); ++i) gp << (i ? " " : "") << row[i];
        gp << "\n";
      }
      gp << "EOD\n";
    }
    gp << script << "\nunset output\n";
  }

  // run it; keep the image only when gnuplot succeeded
  const int status = run_process({"gnuplot", script_file.string()}, err_file);
  std::ifstream err_in(err_file);
  std::stringstream err;
  err << err_in.rdbuf();
  std::error_code ec;
  fs::remove(script_file, ec);
  fs::remove(err_file, ec);
  if (status != 0 || !fs::exists(partial)) {
    fs::remove(partial, ec);
    throw std::runtime_error("gnuplot failed (exit " + std::to_string(status) +
                             (status == 127 ? ", is gnuplot-nox installed?" : "") +
                             "): " + err.str());
  }
  fs::rename(partial, out_png);
}

}  // namespace conesim::sim
