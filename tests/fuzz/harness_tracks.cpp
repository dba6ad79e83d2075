#include <cmath>
#include <exception>
#include <filesystem>
#include <set>
#include <stdexcept>
#include <typeinfo>

#include "tests/fuzz/harness.hpp"
#include "tracks/io.hpp"

namespace conesim::fuzz {

using core::InputError;

std::string describe(const std::exception& e) {
  return std::string(typeid(e).name()) + ": " + e.what();
}

std::string check_names(const InputError& e, const std::string& name) {
  const std::string what = e.what();
  if (what.starts_with(name) || what.starts_with("--set")) return "";
  // an error inside another file the input names (a scenario's vehicle file) names that file
  std::error_code ec;
  if (!e.file().empty() && std::filesystem::is_regular_file(e.file(), ec)) return "";
  return "the error does not name the file " + name + ": " + what;
}

namespace {

// what is wrong with an accepted track: unique ids, lanes and positions that exist
std::string track_problem(const tracks::Track& t) {
  std::set<long long> ids;
  for (const tracks::Cone& c : t.cones) {
    if (!ids.insert(static_cast<long long>(c.id)).second)
      return "cone id " + std::to_string(c.id) + " given twice";
    if (!c.position.allFinite()) return "a cone position is not finite";
  }
  for (const auto* lane : {&t.left_lane, &t.right_lane})
    for (const auto id : *lane)
      if (!ids.contains(static_cast<long long>(id)))
        return "a lane names cone " + std::to_string(id) + ", which does not exist";
  if (!std::isfinite(t.start.x) || !std::isfinite(t.start.y) || !std::isfinite(t.start.yaw))
    return "the start pose is not finite";
  for (const core::Vec2& p : t.centre_line)
    if (!p.allFinite()) return "a centre line point is not finite";
  return "";
}

// a track reader: the input as a file of `format`, then back through the two writers
std::string track_target(std::string_view input, tracks::TrackFormat format,
                         const std::string& name) {
  tracks::Track track;
  try {
    track = tracks::parse_track(std::string(input), format, name);
  } catch (const InputError& e) {
    return check_names(e, name);
  } catch (const std::exception& e) {
    return "reading threw " + describe(e);
  }
  if (std::string p = track_problem(track); !p.empty()) return "accepted, but " + p;

  // what conesim writes, it reads back with every cone
  const std::pair<tracks::TrackFormat, std::string> writers[] = {
      {tracks::TrackFormat::kEufsCsv, tracks::eufs_csv_text(track)},
      {tracks::TrackFormat::kPacsimYaml, tracks::pacsim_yaml_text(track)}};
  for (const auto& [written_format, text] : writers) {
    const std::string again =
        written_format == tracks::TrackFormat::kEufsCsv ? "again.csv" : "again.yaml";
    try {
      const tracks::Track back = tracks::parse_track(text, written_format, again);
      if (back.cones.size() != track.cones.size())
        return "written as " + again + " and read back with " + std::to_string(back.cones.size()) +
               " cones instead of " + std::to_string(track.cones.size());
    } catch (const std::exception& e) {
      return "written as " + again + ", it cannot be read back: " + e.what();
    }
  }
  return "";
}

}  // namespace

std::string run_track_target(const std::string& name, std::string_view input) {
  if (name == "fssim_yaml") return track_target(input, tracks::TrackFormat::kFssimYaml, "in.yaml");
  if (name == "pacsim_yaml")
    return track_target(input, tracks::TrackFormat::kPacsimYaml, "in.yaml");
  if (name == "eufs_csv") return track_target(input, tracks::TrackFormat::kEufsCsv, "in.csv");
  if (name == "epfl_csv") return track_target(input, tracks::TrackFormat::kEpflCsv, "in.csv");
  throw std::invalid_argument("no track fuzz target '" + name + "'");
}

}  // namespace conesim::fuzz
