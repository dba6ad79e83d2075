#include "sim/slam_figures.hpp"

#include <array>
#include <cmath>
#include <fstream>

#include "sim/gnuplot.hpp"

namespace conesim::sim {

namespace {

// the classes of the per-class figures, in the order of MapErrorSnapshot::rmse_m (after "all")
constexpr std::array<core::ConeClass, 4> kScoredClasses = {
    core::ConeClass::kBlue, core::ConeClass::kYellow, core::ConeClass::kOrangeSmall,
    core::ConeClass::kOrangeBig};

}  // namespace

void write_slam_figures(const SlamScorer& scorer, const tracks::Track& track,
                        const core::Estimate& final_estimate, const std::filesystem::path& dir,
                        const std::string& prefix, const std::string& csv_prefix) {
  // map.csv: every estimated cone with the true cone it stands for
  const std::vector<SlamScorer::MapMatch> matches = scorer.match_map(final_estimate.map);
  {
    std::ofstream csv(dir / (csv_prefix + "map.csv"));
    csv << "id,class,x_m,y_m,var_x_m2,cov_xy_m2,var_y_m2,true_cone_id,error_m\n";
    for (const SlamScorer::MapMatch& m : matches) {
      const auto& c = m.estimate;
      csv << c.id << "," << core::to_string(c.cls) << "," << c.position.x() << "," << c.position.y()
          << "," << c.covariance(0, 0) << "," << c.covariance(0, 1) << "," << c.covariance(1, 1)
          << ","
          << (m.true_cone_id < 0 ? std::string("-1")
                                 : std::to_string(track.file_id(m.true_cone_id)))
          << "," << m.error_m << "\n";
    }
  }

  // the map over ground truth, with the wrong associations marked
  PlotData truth{"truth", {}}, mapped{"mapped", {}}, spurious{"spurious", {}}, wrong{"wrong", {}};
  for (const auto& c : track.cones) truth.rows.push_back({c.position.x(), c.position.y()});
  for (const SlamScorer::MapMatch& m : matches)
    (m.true_cone_id >= 0 ? mapped : spurious)
        .rows.push_back({m.estimate.position.x(), m.estimate.position.y()});
  for (const auto& p : scorer.wrong_association_places()) wrong.rows.push_back({p.x(), p.y()});
  for (PlotData* d : {&truth, &mapped, &spurious, &wrong})
    if (d->rows.empty()) d->rows.push_back({NAN, NAN});
  const std::string header =
      "set size ratio -1\nset grid\nset key outside right top\n"
      "set xlabel 'x [m]'\nset ylabel 'y [m]'\n";
  render_png(
      header +
          "set title 'map over ground truth (no alignment)'\n"
          "plot $truth using 1:2 with points pt 6 ps 1.2 lc rgb '#808080' title 'true cones', "
          "$mapped using 1:2 with points pt 7 ps 0.6 lc rgb '#1f4fd8' title 'mapped', "
          "$spurious using 1:2 with points pt 2 ps 1.5 lc rgb '#d62728' title 'spurious', "
          "$wrong using 1:2 with points pt 4 ps 1.5 lc rgb '#ff7f0e' title 'wrong association (" +
          std::to_string(scorer.wrong_association_places().size()) + ")'\n",
      {truth, mapped, spurious, wrong}, dir / (prefix + "map.png"));

  // the map error per class over distance driven: a table and its figure
  {
    std::ofstream csv(dir / (csv_prefix + "map_error.csv"));
    csv << "distance_m,matched,rmse_m";
    for (core::ConeClass c : kScoredClasses) csv << ",rmse_" << core::to_string(c) << "_m";
    csv << "\n";
    for (const SlamScorer::MapErrorSnapshot& row : scorer.map_error_over_distance()) {
      csv << row.distance_m << "," << row.matched;
      for (double r : row.rmse_m) {
        csv << ",";
        if (!std::isnan(r)) csv << r;
      }
      csv << "\n";
    }
  }
  PlotData map_error{"map_error", {}};
  for (const SlamScorer::MapErrorSnapshot& row : scorer.map_error_over_distance()) {
    map_error.rows.push_back({row.distance_m});
    map_error.rows.back().insert(map_error.rows.back().end(), row.rmse_m.begin(), row.rmse_m.end());
  }
  if (map_error.rows.empty()) map_error.rows.push_back({NAN, NAN, NAN, NAN, NAN, NAN});
  render_png(
      "set datafile missing 'nan'\nset grid\nset key outside right top\n"
      "set xlabel 'distance driven [m]'\nset ylabel 'map RMSE [m]'\nset yrange [0:*]\n" +
          ranges_if_nothing_to_plot({map_error}) +
          "set title 'map error per class over distance (observed cones, no alignment)'\n"
          "plot $map_error using 1:2 with lines lw 2 dt 2 lc rgb '#000000' title 'all', "
          "$map_error using 1:3 with lines lw 1.5 lc rgb '#1f4fd8' title 'blue', "
          "$map_error using 1:4 with lines lw 1.5 lc rgb '#e6b800' title 'yellow', "
          "$map_error using 1:5 with lines lw 1.5 lc rgb '#ff7f0e' title 'orange small', "
          "$map_error using 1:6 with lines lw 1.5 lc rgb '#d62728' title 'orange big'\n",
      {map_error}, dir / (prefix + "map_error.png"), 1000, 500);

  // the trajectory and its error along the run
  PlotData paths{"paths", {}}, error{"error", {}};
  for (size_t i = 0; i < scorer.true_path().size(); ++i) {
    paths.rows.push_back({scorer.true_path()[i].x, scorer.true_path()[i].y,
                          scorer.estimated_path()[i].x, scorer.estimated_path()[i].y});
    error.rows.push_back(
        {scorer.true_odometer()[i],
         (scorer.estimated_path()[i].position() - scorer.true_path()[i].position()).norm()});
  }
  if (paths.rows.empty()) paths.rows.push_back({NAN, NAN, NAN, NAN});
  if (error.rows.empty()) error.rows.push_back({NAN, NAN});
  render_png(header + ranges_if_nothing_to_plot({paths}) +
                 "set title 'trajectory: truth and estimate'\n"
                 "plot $paths using 1:2 with lines lw 2 lc rgb '#808080' title 'true', "
                 "$paths using 3:4 with lines lw 1 lc rgb '#d62728' title 'estimated'\n",
             {paths}, dir / (prefix + "trajectory.png"));
  render_png("set grid\nset xlabel 'distance driven [m]'\nset ylabel 'position error [m]'\n" +
                 ranges_if_nothing_to_plot({error}) +
                 "set title 'position error of the estimate over distance (no alignment)'\n"
                 "plot $error using 1:2 with lines lw 1.5 lc rgb '#d62728' notitle\n",
             {error}, dir / (prefix + "error.png"), 1000, 500);
}

void write_lanes_figures(const std::vector<LaneFigures>& lanes, const tracks::Track& track,
                         const std::filesystem::path& dir) {
  // every lane's map error over distance on one plot, one colour each
  std::vector<PlotData> data;
  std::string plot = "plot ";
  static const char* kColours[] = {"#1f4fd8", "#d62728", "#2ca02c", "#9467bd",
                                   "#ff7f0e", "#8c564b", "#e377c2", "#17becf"};
  for (size_t k = 0; k < lanes.size(); ++k) {
    PlotData d{"lane" + std::to_string(k), {}};
    for (const auto& row : lanes[k].scorer->map_error_over_distance())
      d.rows.push_back({row.distance_m, row.rmse_m[0]});
    if (d.rows.empty()) d.rows.push_back({NAN, NAN});
    plot += std::string(k ? ", " : "") + "$" + d.name + " using 1:2 with lines lw 1.5 lc rgb '" +
            kColours[k % 8] + "' title '" + lanes[k].name + (lanes[k].driving ? " (drives)" : "") +
            "'";
    data.push_back(std::move(d));
  }
  render_png(
      "set datafile missing 'nan'\nset grid\nset key outside right top\n"
      "set xlabel 'distance driven [m]'\nset ylabel 'map RMSE [m]'\nset yrange [0:*]\n" +
          ranges_if_nothing_to_plot(data) +
          "set title 'map error over distance, every back-end (no alignment)'\n" + plot + "\n",
      data, dir / "slam_lanes.png", 1000, 500);

  // every lane's final map over the true cones, one colour each
  std::vector<PlotData> maps{{"truth", {}}};
  for (const tracks::Cone& c : track.cones)
    maps[0].rows.push_back({c.position.x(), c.position.y()});
  std::string map_plot =
      "plot $truth using 1:2 with points pt 6 ps 1.4 lc rgb '#808080' title 'true cones'";
  for (size_t k = 0; k < lanes.size(); ++k) {
    PlotData d{"map" + std::to_string(k), {}};
    for (const core::MapCone& c : lanes[k].estimate->map)
      d.rows.push_back({c.position.x(), c.position.y()});
    if (d.rows.empty()) d.rows.push_back({NAN, NAN});
    map_plot += ", $" + d.name + " using 1:2 with points pt 7 ps 0.5 lc rgb '" + kColours[k % 8] +
                "' title '" + lanes[k].name + "'";
    maps.push_back(std::move(d));
  }
  if (maps[0].rows.empty()) maps[0].rows.push_back({NAN, NAN});
  render_png(
      "set size ratio -1\nset grid\nset key outside right top\n"
      "set xlabel 'x [m]'\nset ylabel 'y [m]'\n"
      "set title \"every back-end's map over the true cones (no alignment)\"\n" +
          map_plot + "\n",
      maps, dir / "slam_lanes_map.png");
}

}  // namespace conesim::sim
