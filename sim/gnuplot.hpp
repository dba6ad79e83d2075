#pragma once
// Running gnuplot as a child process to draw figures (track plots, report plots).

#include <filesystem>
#include <string>
#include <vector>

namespace conesim::sim {

/// One inline data block handed to gnuplot as `$name`, rows of whitespace-separated numbers.
struct PlotData {
  std::string name;
  std::vector<std::vector<double>> rows;
};

/// Renders `script` (gnuplot commands that plot the given data blocks) to a PNG at `out_png`.
/// The terminal and output are set here; the image appears only when gnuplot succeeded, so a
/// failed plot never leaves a file that looks complete. Throws std::runtime_error with
/// gnuplot's own message on failure.
/// Ranges that let gnuplot draw empty axes ("set xrange [0:10]", "set yrange [0:1]") when no
/// row of `data` has a finite first column and another finite one: gnuplot refuses a plot
/// without a single point. Empty when there is something to plot.
std::string ranges_if_nothing_to_plot(const std::vector<PlotData>& data);

void render_png(const std::string& script, const std::vector<PlotData>& data,
                const std::filesystem::path& out_png, int width_px = 1000, int height_px = 1000);

}  // namespace conesim::sim
