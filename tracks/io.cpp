#include "tracks/io.hpp"

#include <yaml-cpp/depthguard.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <string_view>
#include <system_error>
#include <unordered_map>
#include <utility>
#include <vector>

#include "core/error.hpp"
#include "tracks/fsg_layouts.hpp"
#include "tracks/lanes.hpp"
#include "tracks/rules.hpp"
#include "tracks/spatial_index.hpp"

namespace conesim::tracks {

namespace {

using core::InputError;

// a start pose guessed from the first gate is moved this far behind it (the front wing starts
// behind the time-keeping line), metres
constexpr double kStartBehindGateM = 6.0;
// two cones of one class whose bases would overlap by more than this (centres closer than the
// base width less it) cannot both stand there: one cone listed twice (PacSim's FSCZ24 lists
// seven cones twice, 0.10-0.14 m apart), metres
constexpr double kOverlapToleranceM = 0.02;
/// Largest coordinate accepted, metres: room for UTM northings, and distances stay finite.
constexpr double kMaxCoordinateM = 1e7;

constexpr std::array<std::string_view, 7> kEufsColumns{
    "tag", "x", "y", "direction", "x_variance", "y_variance", "xy_covariance"};
constexpr std::string_view kEufsHeader = "tag,x,y,direction,x_variance,y_variance,xy_covariance";
constexpr std::array<std::string_view, 9> kEpflColumns{
    "cone_type", "X", "Y", "Z", "std_X", "std_Y", "std_Z", "right", "left"};
constexpr std::string_view kEpflHeader = "cone_type,X,Y,Z,std_X,std_Y,std_Z,right,left";

// ---------------------------------------------------------------------------------------------
// text helpers

std::string_view trim(std::string_view s) {
  const auto space = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; };
  while (!s.empty() && space(s.front())) s.remove_prefix(1);
  while (!s.empty() && space(s.back())) s.remove_suffix(1);
  return s;
}

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

enum class NumberParse { kOk, kNotNumber, kNotFinite };

// strict decimal parse of the whole field; nan, inf and overflow are not finite
NumberParse parse_double(std::string_view s, double& out) {
  s = trim(s);
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty()) return NumberParse::kNotNumber;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  if (ec == std::errc::result_out_of_range) return NumberParse::kNotFinite;
  if (ec == std::errc() && end == s.data() + s.size())
    return std::isfinite(out) ? NumberParse::kOk : NumberParse::kNotFinite;
  // yaml spells them .nan and .inf
  std::string word = lower(s);
  std::erase_if(word, [](char c) { return c == '.' || c == '-' || c == '+'; });
  return word == "nan" || word == "inf" || word == "infinity" ? NumberParse::kNotFinite
                                                              : NumberParse::kNotNumber;
}

// a finite number, or an InputError naming the field
double number_or_throw(std::string_view s, const std::string& file, int line,
                       std::string_view what) {
  double v = 0.0;
  switch (parse_double(s, v)) {
    case NumberParse::kOk:
      return v;
    case NumberParse::kNotFinite:
      throw InputError(
          file, line,
          std::string(what) + ": expected a finite number, found '" + std::string(trim(s)) + "'");
    case NumberParse::kNotNumber:
      break;
  }
  throw InputError(file, line,
                   std::string(what) + ": expected a number, found '" + std::string(trim(s)) + "'");
}

// a coordinate: a finite number of sensible size
double coordinate_or_throw(std::string_view s, const std::string& file, int line,
                           std::string_view what) {
  const double v = number_or_throw(s, file, line, what);
  if (std::abs(v) > kMaxCoordinateM)
    throw InputError(file, line,
                     std::string(what) + ": expected a coordinate within +-1e7 m, found '" +
                         std::string(trim(s)) + "'");
  return v;
}

// shortest text that reads back to the same double
std::string format_number(double v) {
  std::array<char, 64> buf{};
  const auto [end, ec] = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  std::string s(buf.data(), ec == std::errc() ? end : buf.data());
  // keep a decimal point so that every reader sees a float
  if (s.find_first_of(".eEn") == std::string::npos) s += ".0";
  return s;
}

std::string format_point(const Vec2& p) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "(%.3f, %.3f)", p.x(), p.y());
  return buf;
}

std::vector<std::string_view> split_fields(std::string_view line) {
  std::vector<std::string_view> fields;
  size_t begin = 0;
  while (true) {
    const size_t comma = line.find(',', begin);
    fields.push_back(trim(line.substr(begin, comma - begin)));
    if (comma == std::string_view::npos) break;
    begin = comma + 1;
  }
  return fields;
}

// the non-empty lines of a text with their 1-based numbers
std::vector<std::pair<int, std::string_view>> content_lines(const std::string& text) {
  std::vector<std::pair<int, std::string_view>> lines;
  std::string_view rest(text);
  int number = 0;
  while (!rest.empty()) {
    const size_t nl = rest.find('\n');
    const std::string_view line = rest.substr(0, nl);
    ++number;
    if (!trim(line).empty()) lines.emplace_back(number, line);
    if (nl == std::string_view::npos) break;
    rest.remove_prefix(nl + 1);
  }
  return lines;
}

// ---------------------------------------------------------------------------------------------
// collecting cones

/// Adds cones in file order, drops a cone listed twice (with a warning) and gives ids.
class ConeSink {
 public:
  ConeSink(Track& track, const std::string& file) : track_(track), file_(file) {}

  /// Adds a cone with the next id in file order; nullopt when it repeats one already read.
  std::optional<int> add_in_order(ConeClass cls, const Vec2& p, int line,
                                  std::optional<Eigen::Matrix2d> covariance = std::nullopt) {
    if (!push(cls, p, line, covariance)) return std::nullopt;
    track_.cones.back().id = next_id_++;
    return track_.cones.back().id;
  }

  /// Adds a cone whose file gives it an id (nullopt: none given, finish() gives it one after
  /// the largest); the cone's own id is the next in file order. Returns that id, nullopt when
  /// the cone repeats one already read.
  std::optional<int> add_with_file_id(ConeClass cls, const Vec2& p, int line,
                                      std::optional<Eigen::Matrix2d> covariance,
                                      std::optional<uint64_t> file_id) {
    // an explicit id must be unique
    if (file_id) {
      const auto [it, fresh] = id_lines_.emplace(*file_id, line);
      if (!fresh)
        throw InputError(file_, line,
                         "id: " + std::to_string(*file_id) + " is already used on line " +
                             std::to_string(it->second));
    }
    const std::optional<int> id = add_in_order(cls, p, line, covariance);
    if (!id) return std::nullopt;
    if (file_id)
      track_.file_ids.emplace(*id, *file_id);
    else
      without_file_id_.push_back(*id);
    return id;
  }

  /// Gives cones read without a file id the free ids after the largest one (when the file gave
  /// any); throws when there are no cones.
  void finish() {
    if (track_.cones.empty()) throw InputError(file_, 0, "expected at least one cone, found none");
    if (id_lines_.empty()) return;
    uint64_t next = id_lines_.rbegin()->first;
    for (int id : without_file_id_) {
      do ++next;  // wraps past 2^64 - 1 to 0: the set holds at most kMaxTrackCones ids
      while (id_lines_.count(next) > 0);
      track_.file_ids.emplace(id, next);
    }
  }

 private:
  // appends the cone unless it repeats one of its class
  bool push(ConeClass cls, const Vec2& p, int line, std::optional<Eigen::Matrix2d> covariance) {
    // refuse layouts far beyond any real one
    if (track_.cones.size() >= kMaxTrackCones)
      throw InputError(file_, line, "more than " + std::to_string(kMaxTrackCones) + " cones");

    // the same cone listed twice (exactly, or where the two would overlap): keep the first.
    // The cones read so far are looked up in a grid of cells as wide as the largest base, so
    // that the check costs the same for every cone whatever the layout's size
    const double overlap_m = core::cone_size(cls).base_m - kOverlapToleranceM;
    const auto cell_of = [](double v) { return static_cast<int64_t>(std::floor(v / kCellM)); };
    const int64_t cx = cell_of(p.x()), cy = cell_of(p.y());
    const Cone* repeated = nullptr;  // the first read of those it repeats
    for (int64_t dx = -1; dx <= 1; ++dx)
      for (int64_t dy = -1; dy <= 1; ++dy) {
        const auto it = grid_.find(cell_key(cx + dx, cy + dy));
        if (it == grid_.end()) continue;
        for (size_t k : it->second) {
          const Cone& c = track_.cones[k];
          if (c.cls != cls || (c.position - p).norm() > overlap_m) continue;
          if (!repeated || &c < repeated) repeated = &c;
        }
      }
    if (repeated) {
      const Cone& c = *repeated;
      const double apart = (c.position - p).norm();
      std::string what = file_ + ":" + std::to_string(line) + ": repeats the " +
                         std::string(core::to_string(cls)) + " cone at " + format_point(c.position);
      if (apart > 0.01) {
        char buf[64];
        std::snprintf(buf, sizeof buf, " (%.2f m apart: their bases would overlap)", apart);
        what += buf;
      }
      track_.warnings.push_back(what + "; copy dropped");
      return false;
    }
    grid_[cell_key(cx, cy)].push_back(track_.cones.size());
    track_.cones.push_back({-1, cls, p, covariance});
    return true;
  }

  static uint64_t cell_key(int64_t cx, int64_t cy) {
    return (static_cast<uint64_t>(cx) << 32) ^ static_cast<uint32_t>(cy);
  }

  // a grid cell's width: at least the largest cone base, metres
  static constexpr double kCellM = 0.3;
  std::unordered_map<uint64_t, std::vector<size_t>> grid_;

  Track& track_;
  const std::string& file_;
  int next_id_ = 0;
  // the file's ids and their lines
  std::map<uint64_t, int> id_lines_;
  std::vector<int> without_file_id_;
};

// ---------------------------------------------------------------------------------------------
// YAML helpers

int line_of(const YAML::Node& node) {
  if (!node.IsDefined()) return 0;
  const YAML::Mark mark = node.Mark();
  return mark.line >= 0 ? mark.line + 1 : 0;
}

// a key given twice in one map: a warning with both lines (yaml-cpp keeps both entries, and
// the readers take them in file order, so lists given twice are read one after the other)
void warn_repeated_key(const YAML::Node& key, std::map<std::string, int>& first_lines,
                       const std::string& file, const std::string& where, Track& track) {
  const auto [it, fresh] = first_lines.emplace(key.Scalar(), line_of(key));
  if (!fresh)
    track.warnings.push_back(file + ":" + std::to_string(line_of(key)) + ": " + where +
                             key.Scalar() + ": given again (also on line " +
                             std::to_string(it->second) + "); both are read");
}

// the value of a key that must be there (missing keys are zombie nodes in yaml-cpp)
YAML::Node required(const YAML::Node& map, const std::string& key, const std::string& file,
                    const std::string& what) {
  const YAML::Node value = map[key];
  if (!value.IsDefined() || value.IsNull())
    throw InputError(file, line_of(map), what + ": " + key + ": missing");
  return value;
}

double yaml_number(const YAML::Node& node, const std::string& file, const std::string& what) {
  if (!node.IsDefined() || !node.IsScalar())
    throw InputError(file, line_of(node), what + ": expected a number");
  return number_or_throw(node.Scalar(), file, line_of(node), what);
}

// [x, y] or [x, y, z]
Vec2 yaml_position(const YAML::Node& node, const std::string& file, const std::string& what) {
  if (!node.IsDefined() || !node.IsSequence() || node.size() < 2 || node.size() > 3)
    throw InputError(file, line_of(node), what + ": expected a position [x, y] or [x, y, z]");
  const Vec2 p(yaml_number(node[0], file, what + " x"), yaml_number(node[1], file, what + " y"));
  if (p.cwiseAbs().maxCoeff() > kMaxCoordinateM)
    throw InputError(file, line_of(node), what + ": expected coordinates within +-1e7 m");
  return p;
}

// a list of exactly n numbers
std::vector<double> yaml_numbers(const YAML::Node& node, size_t n, const std::string& file,
                                 const std::string& what) {
  if (!node.IsDefined() || !node.IsSequence() || node.size() != n)
    throw InputError(file, line_of(node),
                     what + ": expected a list of " + std::to_string(n) + " numbers");
  std::vector<double> out;
  for (size_t i = 0; i < n; ++i) out.push_back(yaml_number(node[i], file, what));
  return out;
}

// a list (an empty key counts as an empty list)
const YAML::Node& yaml_list(const YAML::Node& node, const std::string& file,
                            const std::string& what) {
  if (!node.IsSequence() && !node.IsNull())
    throw InputError(file, line_of(node), what + ": expected a list");
  return node;
}

YAML::Node load_yaml(const std::string& text, const std::string& file) {
  try {
    return YAML::Load(text);
  } catch (const YAML::DeepRecursion& e) {
    // yaml-cpp's message for it is "bad file"
    throw InputError(file, e.mark.line >= 0 ? e.mark.line + 1 : 0,
                     "malformed YAML: nested " + std::to_string(e.depth()) +
                         " levels deep, more than any layout");
  } catch (const YAML::Exception& e) {
    throw InputError(file, e.mark.line >= 0 ? e.mark.line + 1 : 0, "malformed YAML: " + e.msg);
  }
}

// pairs consecutive posts into gates (left/right is sorted out once the lanes are known)
void add_gates(Track& track, const std::vector<Vec2>& posts, const std::string& file,
               const std::string& what) {
  for (size_t i = 0; i + 1 < posts.size(); i += 2)
    track.timing_gates.push_back({posts[i], posts[i + 1]});
  if (posts.size() % 2 == 1)
    track.warnings.push_back(file + ": " + what + ": odd number of gate posts; the last one " +
                             "has no partner and is ignored");
}

// ---------------------------------------------------------------------------------------------
// finishing: lanes, start pose, gates, centre line

/// What the format gave; the rest is recovered.
struct Given {
  bool lanes = false;
  std::optional<bool> closed;
  bool start = false;
  bool gates = false;
};

// position along the track: arc length on a circuit's centre line, else distance along the start
class AlongTrack {
 public:
  explicit AlongTrack(const Track& track)
      : track_(track), index_(track.centre_line, true), s_(track.centre_line.size() + 1, 0.0) {
    const std::vector<Vec2>& line = track.centre_line;
    for (size_t i = 0; i < line.size(); ++i)
      s_[i + 1] = s_[i] + (line[(i + 1) % line.size()] - line[i]).norm();
  }

  double at(const Vec2& p) const {
    const std::vector<Vec2>& line = track_.centre_line;
    if (!track_.closed || line.size() < 2)
      return (p - track_.start.position()).dot(track_.start.heading());
    const PolylineIndex::Nearest n = index_.nearest(p);
    return s_[n.segment] + n.t * (s_[n.segment + 1] - s_[n.segment]);
  }

 private:
  const Track& track_;
  PolylineIndex index_;
  std::vector<double> s_;
};

// direction of the centre line at its point nearest p
std::optional<double> centre_line_yaw(const Track& track, const Vec2& p) {
  const std::vector<Vec2>& line = track.centre_line;
  if (line.size() < 2) return std::nullopt;
  size_t best = 0;
  for (size_t i = 1; i < line.size(); ++i)
    if ((line[i] - p).squaredNorm() < (line[best] - p).squaredNorm()) best = i;
  const size_t n = line.size();
  const size_t next = track.closed ? (best + 1) % n : std::min(best + 1, n - 1);
  const size_t prev = next == best ? best - 1 : best;
  const Vec2 d = line[next] - line[prev];
  return std::atan2(d.y(), d.x());
}

void finish(Track& track, const Given& given) {
  // gates made of big orange cones where the format has no time keeping
  if (!given.gates) track.timing_gates = gates_from_big_orange(track);

  // a start pose when the file has none
  if (!given.start) guess_start_pose(track);

  // lanes: given ones are put in driving order, missing ones rebuilt from the cone colours
  const bool have_lanes = !track.left_lane.empty() || !track.right_lane.empty();
  if (given.lanes && have_lanes) {
    track.closed =
        given.closed ? *given.closed
                     : lane_closes(track, track.left_lane) && lane_closes(track, track.right_lane);
    extend_open_lanes_with_orange(track);
    orient_lanes(track);
  } else {
    rebuild_lanes(track);
  }

  // big orange gates again, now that the lanes tell left from right across each group (before,
  // only the nearest blue and yellow cones could, and those may stand round a corner)
  if (!given.gates) track.timing_gates = gates_from_big_orange(track);

  // the centre line (none along absurdly long lanes), and a guessed start facing along it
  track.centre_line = derive_centre_line(track);
  if (track.centre_line.empty() && !track.left_lane.empty() && !track.right_lane.empty())
    track.warnings.push_back("the lanes run over " +
                             std::to_string(static_cast<int>(kMaxCentreLineM / 1e3)) +
                             " km; no centre line derived");

  // a start guessed without a gate may stand off the track (the middle of the cones of a U or a
  // loop is its infield): the car starts on the centre line, at the beginning of an open one
  if (!given.start && track.timing_gates.empty() && track.centre_line.size() >= 2) {
    const std::vector<Vec2>& line = track.centre_line;
    size_t at = 0;
    if (track.closed)
      for (size_t i = 1; i < line.size(); ++i)
        if ((line[i] - track.start.position()).squaredNorm() <
            (line[at] - track.start.position()).squaredNorm())
          at = i;
    if ((line[at] - track.start.position()).norm() > 0.5) {
      track.start.x = line[at].x();
      track.start.y = line[at].y();
      track.warnings.push_back("the guessed start moved onto the centre line at " +
                               format_point(line[at]));
      if (track.closed) {
        orient_lanes(track);
        track.centre_line = derive_centre_line(track);
      }
    }
  }
  if (!given.start) {
    if (const std::optional<double> yaw = centre_line_yaw(track, track.start.position()))
      track.start.yaw = *yaw;
    // a start guessed on the timing line moves behind it, as cars start behind the line
    if (!track.timing_gates.empty()) {
      const Gate& first = track.timing_gates.front();
      const Vec2 middle = 0.5 * (first.left + first.right);
      if ((track.start.position() - middle).norm() < 0.5) {
        track.start = track.start.compose({-kStartBehindGateM, 0.0, 0.0});
        track.warnings.push_back("the guessed start stands " + std::to_string(kStartBehindGateM) +
                                 " m behind the first timing gate");
        // lanes and centre line begin near the start
        orient_lanes(track);
        track.centre_line = derive_centre_line(track);
      }
    }
  }

  // gates: left post on the left of travel, made gates in the order they are passed
  std::vector<Vec2> middles;
  for (const Gate& gate : track.timing_gates) middles.push_back(0.5 * (gate.left + gate.right));
  const std::vector<Vec2> lefts = left_directions_at(track, middles);
  for (size_t i = 0; i < track.timing_gates.size(); ++i) {
    Gate& gate = track.timing_gates[i];
    if ((gate.left - gate.right).dot(lefts[i]) < 0.0) std::swap(gate.left, gate.right);
  }
  if (!given.gates) {
    const AlongTrack along(track);
    std::vector<std::pair<double, Gate>> keyed;
    for (const Gate& g : track.timing_gates)
      keyed.emplace_back(along.at(0.5 * (g.left + g.right)), g);
    std::stable_sort(keyed.begin(), keyed.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    for (size_t i = 0; i < keyed.size(); ++i) track.timing_gates[i] = keyed[i].second;
  }

  // the event, when the name says it
  const std::string name = lower(track.name);
  if (name.find("skidpad") != std::string::npos)
    track.event = EventType::kSkidpad;
  else if (name.find("accel") != std::string::npos)
    track.event = EventType::kAcceleration;

  // a skidpad's driving line is the figure eight through its timing line, not a line between
  // lanes (its lanes are only the outer envelope)
  if (track.event.value_or(infer_event(track)) == EventType::kSkidpad &&
      !track.timing_gates.empty()) {
    const Gate& g = track.timing_gates.front();
    const Vec2 across = g.left - g.right;  // right post to left post: forward is its right turn
    if (across.norm() > 0.0) {
      // crossed the way the car starts (the referee orients the gate the same way)
      Vec2 forward(across.y(), -across.x());
      if (forward.dot(track.start.heading()) < 0.0) forward = -forward;
      track.centre_line =
          skidpad_driving_path(0.5 * (g.left + g.right), forward, track.start.position());
    }
  }
}

// ---------------------------------------------------------------------------------------------
// fssim YAML

Track parse_fssim(const YAML::Node& root, const std::string& file, Track track) {
  ConeSink sink(track, file);
  Given given;
  given.lanes = true;
  bool have_left = false, have_right = false;
  std::vector<Vec2> posts;

  // walk the keys in file order so that ids follow the file
  std::map<std::string, int> key_lines;
  for (const auto& entry : root) {
    const std::string key = entry.first.Scalar();
    warn_repeated_key(entry.first, key_lines, file, "", track);
    const YAML::Node& value = entry.second;
    const auto read_cones = [&](ConeClass cls, std::vector<int>* lane) {
      for (const YAML::Node& item : yaml_list(value, file, key)) {
        const std::optional<int> id =
            sink.add_in_order(cls, yaml_position(item, file, key), line_of(item));
        if (id && lane) lane->push_back(*id);
      }
    };
    if (key == "cones_left") {
      read_cones(ConeClass::kBlue, &track.left_lane);
      have_left = true;
    } else if (key == "cones_right") {
      read_cones(ConeClass::kYellow, &track.right_lane);
      have_right = true;
    } else if (key == "cones_orange") {
      read_cones(ConeClass::kOrangeSmall, nullptr);
    } else if (key == "cones_orange_big") {
      read_cones(ConeClass::kOrangeBig, nullptr);
    } else if (key == "tk_device") {
      for (const YAML::Node& item : yaml_list(value, file, key))
        posts.push_back(yaml_position(item, file, key));
      given.gates = true;
    } else if (key == "starting_pose_front_wing") {
      const std::vector<double> pose = yaml_numbers(value, 3, file, key + " [x, y, yaw]");
      if (std::max(std::abs(pose[0]), std::abs(pose[1])) > kMaxCoordinateM)
        throw InputError(file, line_of(value), key + ": expected coordinates within +-1e7 m");
      track.start = {pose[0], pose[1], core::normalize_angle(pose[2])};
      given.start = true;
    } else {
      track.warnings.push_back(file + ": " + key + ": unknown key ignored");
    }
  }
  if (!have_left) throw InputError(file, "cones_left", "missing (expected a list of [x, y])");
  if (!have_right) throw InputError(file, "cones_right", "missing (expected a list of [x, y])");
  add_gates(track, posts, file, "tk_device");
  sink.finish();
  finish(track, given);
  return track;
}

// ---------------------------------------------------------------------------------------------
// PacSim YAML

// each format's names of the cone classes, looked up both ways
using ClassNames = std::array<std::pair<ConeClass, std::string_view>, 5>;

std::optional<ConeClass> class_named(const ClassNames& names, std::string_view name) {
  for (const auto& [cls, n] : names)
    if (n == name) return cls;
  return std::nullopt;
}

std::string_view name_of(const ClassNames& names, ConeClass cls) {
  for (const auto& [c, n] : names)
    if (c == cls) return n;
  return "unknown";
}

constexpr ClassNames kPacsimNames{{{ConeClass::kBlue, "blue"},
                                   {ConeClass::kYellow, "yellow"},
                                   {ConeClass::kOrangeSmall, "small-orange"},
                                   {ConeClass::kOrangeBig, "big-orange"},
                                   {ConeClass::kUnknown, "unknown"}}};

std::optional<ConeClass> pacsim_class(std::string_view name) {
  return class_named(kPacsimNames, name);
}

std::string_view pacsim_name(ConeClass cls) {
  return name_of(kPacsimNames, cls);
}

bool yaml_bool(const YAML::Node& node, const std::string& file, const std::string& what) {
  const std::string v = node.IsScalar() ? lower(node.Scalar()) : "";
  if (v == "true" || v == "yes" || v == "on") return true;
  if (v == "false" || v == "no" || v == "off") return false;
  throw InputError(file, line_of(node), what + ": expected true or false");
}

Track parse_pacsim(const YAML::Node& root, const std::string& file, Track track) {
  const YAML::Node layout = required(root, "track", file, "PacSim layout");
  if (!layout.IsMap()) throw InputError(file, line_of(layout), "track: expected a mapping");
  ConeSink sink(track, file);
  Given given;
  given.lanes = true;
  bool have_left = false, have_right = false;
  int not_cones = 0;
  std::vector<Vec2> posts;

  // one cone entry: {position: [x, y, z], class: name}
  const auto read_entry = [&](const YAML::Node& item, const std::string& key,
                              std::vector<int>* lane) {
    if (!item.IsMap()) throw InputError(file, line_of(item), key + ": expected {position, class}");
    const YAML::Node cls_node = required(item, "class", file, key);
    if (!cls_node.IsScalar())
      throw InputError(file, line_of(cls_node), key + ": class: expected a name");
    const Vec2 p = yaml_position(required(item, "position", file, key), file, key + ": position");
    const std::string name = cls_node.Scalar();
    if (name == "invisible" || name == "timekeeping") {
      ++not_cones;
      return;
    }
    const std::optional<ConeClass> cls = pacsim_class(name);
    if (!cls)
      throw InputError(file, line_of(cls_node),
                       key + ": unknown cone class '" + name +
                           "' (expected blue, yellow, small-orange, big-orange, timekeeping, "
                           "invisible or unknown)");
    const std::optional<int> id = sink.add_in_order(*cls, p, line_of(item));
    if (id && lane) lane->push_back(*id);
  };

  // walk the keys in file order so that ids follow the file
  std::map<std::string, int> key_lines;
  for (const auto& entry : layout) {
    const std::string key = entry.first.Scalar();
    warn_repeated_key(entry.first, key_lines, file, "track.", track);
    const YAML::Node& value = entry.second;
    if (key == "left" || key == "right" || key == "unknown") {
      std::vector<int>* lane =
          key == "left" ? &track.left_lane : (key == "right" ? &track.right_lane : nullptr);
      for (const YAML::Node& item : yaml_list(value, file, key)) read_entry(item, key, lane);
      if (key == "left") have_left = true;
      if (key == "right") have_right = true;
    } else if (key == "time_keeping") {
      // every entry is a gate post, whatever its class (as PacSim reads them)
      for (const YAML::Node& item : yaml_list(value, file, key)) {
        if (!item.IsMap()) throw InputError(file, line_of(item), key + ": expected {position}");
        posts.push_back(
            yaml_position(required(item, "position", file, key), file, key + ": position"));
      }
      given.gates = true;
    } else if (key == "start") {
      if (!value.IsMap())
        throw InputError(file, line_of(value), "start: expected {position, orientation}");
      const Vec2 p =
          yaml_position(required(value, "position", file, "start"), file, "start: position");
      const double yaw = value["orientation"].IsDefined()
                             ? yaml_numbers(value["orientation"], 3, file,
                                            "start: orientation [roll, pitch, yaw]")[2]
                             : 0.0;
      track.start = {p.x(), p.y(), core::normalize_angle(yaw)};
      given.start = true;
    } else if (key == "earthToTrack") {
      // the geodetic origin of the track frame (for GNSS); positions are already in the track frame
      if (!value.IsMap())
        throw InputError(file, line_of(value), "earthToTrack: expected {position, orientation}");
      bool identity = true;
      for (const char* part : {"position", "orientation"})
        if (value[part].IsDefined())
          for (double v : yaml_numbers(value[part], 3, file, std::string("earthToTrack: ") + part))
            identity = identity && v == 0.0;
      if (!identity)
        track.warnings.push_back(file +
                                 ": earthToTrack (the geodetic origin of the track frame) "
                                 "ignored: cone positions are in the track frame already");
    } else if (key == "lanesFirstWithLastConnected") {
      given.closed = yaml_bool(value, file, key);
    } else if (key != "version") {
      track.warnings.push_back(file + ": track." + key + ": unknown key ignored");
    }
  }
  if (!have_left) throw InputError(file, "track.left", "missing (expected a list of cones)");
  if (!have_right) throw InputError(file, "track.right", "missing (expected a list of cones)");
  if (not_cones > 0)
    track.warnings.push_back(file + ": skipped " + std::to_string(not_cones) +
                             " invisible or timekeeping entries outside time_keeping (not cones)");
  add_gates(track, posts, file, "time_keeping");
  sink.finish();
  finish(track, given);
  return track;
}

Track parse_yaml(const std::string& text, std::optional<TrackFormat> format,
                 const std::string& file, Track track) {
  const YAML::Node root = load_yaml(text, file);
  if (!root.IsMap())
    throw InputError(file, line_of(root),
                     "expected a mapping with track: (PacSim) or cones_left: (fssim)");
  if (!format) {
    if (root["track"].IsDefined())
      format = TrackFormat::kPacsimYaml;
    else if (root["cones_left"].IsDefined())
      format = TrackFormat::kFssimYaml;
    else
      throw InputError(file, line_of(root),
                       "expected a mapping with track: (PacSim) or cones_left: (fssim)");
  }
  try {
    if (*format == TrackFormat::kPacsimYaml) {
      if (!root["track"].IsDefined()) throw InputError(file, "track", "missing (PacSim layout)");
      return parse_pacsim(root, file, std::move(track));
    }
    return parse_fssim(root, file, std::move(track));
  } catch (const YAML::Exception& e) {
    // anything the typed accessors did not anticipate still names its line
    throw InputError(file, e.mark.line >= 0 ? e.mark.line + 1 : 0, "unexpected YAML: " + e.msg);
  }
}

// ---------------------------------------------------------------------------------------------
// CSV

constexpr ClassNames kEufsNames{{{ConeClass::kBlue, "blue"},
                                 {ConeClass::kYellow, "yellow"},
                                 {ConeClass::kOrangeSmall, "orange"},
                                 {ConeClass::kOrangeBig, "big_orange"},
                                 {ConeClass::kUnknown, "unknown"}}};

std::optional<ConeClass> eufs_class(std::string_view tag) {
  return class_named(kEufsNames, tag);
}

std::string_view eufs_tag(ConeClass cls) {
  return name_of(kEufsNames, cls);
}

std::optional<ConeClass> epfl_class(std::string_view type) {
  if (type == "small_orange" || type == "orange") return ConeClass::kOrangeSmall;
  return eufs_class(type);
}

void check_columns(const std::vector<std::string_view>& fields, size_t expected,
                   std::string_view header, const std::string& file, int line) {
  if (fields.size() != expected)
    throw InputError(file, line,
                     "expected " + std::to_string(expected) + " columns (" + std::string(header) +
                         "), found " + std::to_string(fields.size()));
}

double variance_or_throw(std::string_view s, const std::string& file, int line,
                         std::string_view what) {
  const double v = number_or_throw(s, file, line, what);
  if (v < 0.0) throw InputError(file, line, std::string(what) + ": expected a value >= 0");
  return v;
}

Track parse_eufs(const std::string& text, const std::string& file, Track track) {
  ConeSink sink(track, file);
  const auto lines = content_lines(text);

  // an optional header, with conesim's id column
  // conesim's own files add id, and lane (left or right, in driving order; on the car_start
  // row: closed or open), so that its lanes read back as written
  size_t columns = kEufsColumns.size();
  bool has_id = false;
  bool has_lane = false;
  size_t first_row = 0;
  if (!lines.empty() && split_fields(lines[0].second).front() == "tag") {
    const std::vector<std::string_view> header = split_fields(lines[0].second);
    has_id = header.size() > columns && header[columns] == "id";
    has_lane = has_id && header.size() == columns + 2 && header.back() == "lane";
    const bool known = std::equal(kEufsColumns.begin(), kEufsColumns.end(), header.begin(),
                                  header.begin() + std::min(header.size(), columns));
    if (!known ||
        !(header.size() == columns || (has_id && header.size() == columns + 1) || has_lane))
      throw InputError(
          file, lines[0].first,
          "expected the header " + std::string(kEufsHeader) + " (optionally ,id or ,id,lane)");
    columns = header.size();
    first_row = 1;
  }
  Given given;
  std::vector<int>* lanes[2] = {&track.left_lane, &track.right_lane};

  std::optional<int> start_line;
  for (size_t r = first_row; r < lines.size(); ++r) {
    const auto& [line, text_line] = lines[r];
    const std::vector<std::string_view> f = split_fields(text_line);
    check_columns(f, columns,
                  std::string(kEufsHeader) + (has_lane ? ",id,lane"
                                              : has_id ? ",id"
                                                       : ""),
                  file, line);

    // the numbers of the row
    const double x = coordinate_or_throw(f[1], file, line, "x");
    const double y = coordinate_or_throw(f[2], file, line, "y");
    const double direction = number_or_throw(f[3], file, line, "direction");
    const double var_x = variance_or_throw(f[4], file, line, "x_variance");
    const double var_y = variance_or_throw(f[5], file, line, "y_variance");
    const double cov_xy = number_or_throw(f[6], file, line, "xy_covariance");

    // the start pose and rows that are not cones
    const std::string_view tag = f[0];
    if (tag == "car_start") {
      if (start_line)
        throw InputError(
            file, line,
            "a second car_start row (the first is on line " + std::to_string(*start_line) + ")");
      start_line = line;
      track.start = {x, y, core::normalize_angle(direction)};
      if (has_lane && (f[8] == "closed" || f[8] == "open")) given.closed = f[8] == "closed";
      continue;
    }
    if (tag == "midpoint" || tag == "inactive_noise") continue;
    const std::optional<ConeClass> cls = eufs_class(tag);
    if (!cls)
      throw InputError(file, line,
                       "tag: unknown tag '" + std::string(tag) +
                           "' (expected blue, yellow, orange, big_orange, unknown, car_start, "
                           "midpoint or inactive_noise)");

    // the cone, with its covariance and id when the file gives them
    std::optional<Eigen::Matrix2d> covariance;
    if (var_x != 0.0 || var_y != 0.0 || cov_xy != 0.0) {
      covariance = Eigen::Matrix2d();
      *covariance << var_x, cov_xy, cov_xy, var_y;
    }
    if (!has_id) {
      sink.add_in_order(*cls, {x, y}, line, covariance);
      continue;
    }
    std::optional<uint64_t> file_id;
    const std::string_view id_text = f[7];
    if (!id_text.empty()) {
      uint64_t value = 0;
      const auto [end, ec] =
          std::from_chars(id_text.data(), id_text.data() + id_text.size(), value);
      if (ec != std::errc() || end != id_text.data() + id_text.size())
        throw InputError(file, line,
                         "id: expected an integer from 0 to 18446744073709551615, found '" +
                             std::string(id_text) + "'");
      file_id = value;
    }
    const std::optional<int> id = sink.add_with_file_id(*cls, {x, y}, line, covariance, file_id);

    // the lane the cone belongs to, in file order (a cone dropped as a repeat is in none)
    if (has_lane && !f[8].empty()) {
      if (f[8] != "left" && f[8] != "right")
        throw InputError(
            file, line, "lane: expected left, right or nothing, found '" + std::string(f[8]) + "'");
      if (!file_id) throw InputError(file, line, "lane: a cone in a lane needs its id");
      if (id) lanes[f[8] == "left" ? 0 : 1]->push_back(*id);
      given.lanes = true;
    }
  }
  sink.finish();
  given.start = start_line.has_value();
  finish(track, given);
  return track;
}

Track parse_epfl(const std::string& text, const std::string& file, Track track) {
  ConeSink sink(track, file);
  const auto lines = content_lines(text);

  // the header is required
  const std::vector<std::string_view> header =
      lines.empty() ? std::vector<std::string_view>{} : split_fields(lines[0].second);
  if (header.size() != kEpflColumns.size() ||
      !std::equal(header.begin(), header.end(), kEpflColumns.begin()))
    throw InputError(file, lines.empty() ? 0 : lines[0].first,
                     "expected the header " + std::string(kEpflHeader));

  for (size_t r = 1; r < lines.size(); ++r) {
    const auto& [line, text_line] = lines[r];
    const std::vector<std::string_view> f = split_fields(text_line);
    check_columns(f, kEpflColumns.size(), kEpflHeader, file, line);

    // class, position and standard deviations; the side columns are checked but not needed
    const std::optional<ConeClass> cls = epfl_class(f[0]);
    if (!cls)
      throw InputError(
          file, line,
          "cone_type: unknown type '" + std::string(f[0]) +
              "' (expected blue, yellow, small_orange, orange, big_orange or unknown)");
    const double x = coordinate_or_throw(f[1], file, line, "X");
    const double y = coordinate_or_throw(f[2], file, line, "Y");
    number_or_throw(f[3], file, line, "Z");
    const double std_x = variance_or_throw(f[4], file, line, "std_X");
    const double std_y = variance_or_throw(f[5], file, line, "std_Y");
    variance_or_throw(f[6], file, line, "std_Z");
    number_or_throw(f[7], file, line, "right");
    number_or_throw(f[8], file, line, "left");

    std::optional<Eigen::Matrix2d> covariance;
    if (std_x != 0.0 || std_y != 0.0) {
      covariance = Eigen::Matrix2d::Zero();
      (*covariance)(0, 0) = std_x * std_x;
      (*covariance)(1, 1) = std_y * std_y;
    }
    sink.add_in_order(*cls, {x, y}, line, covariance);
  }
  sink.finish();
  finish(track, Given{});
  return track;
}

// ---------------------------------------------------------------------------------------------
// detection and writing helpers

bool is_epfl_csv(const std::string& text) {
  const auto lines = content_lines(text);
  return !lines.empty() && split_fields(lines[0].second).front() == "cone_type";
}

Track new_track(const std::string& name) {
  Track track;
  track.name = std::filesystem::path(name).stem().string();
  return track;
}

void write_text(const std::string& text, const std::filesystem::path& file) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  if (!out) throw InputError(file.string(), 0, "cannot open for writing");
  out << text;
  out.close();
  if (!out) throw InputError(file.string(), 0, "write failed");
}

// the text without a UTF-8 byte-order mark (editors on Windows write one; it is no data)
std::string_view without_bom(std::string_view text) {
  if (text.starts_with("\xEF\xBB\xBF")) text.remove_prefix(3);
  return text;
}

}  // namespace

Track parse_track(const std::string& text_with_bom, TrackFormat format, const std::string& name) {
  const std::string text(without_bom(text_with_bom));
  // refuse what cannot be a layout before parsing
  if (text.size() > kMaxTrackFileBytes)
    throw InputError(name, 0,
                     "larger than the limit of " + std::to_string(kMaxTrackFileBytes) + " bytes");
  if (trim(text).empty()) throw InputError(name, 0, "the file is empty");

  Track track = new_track(name);
  switch (format) {
    case TrackFormat::kFssimYaml:
    case TrackFormat::kPacsimYaml:
      return parse_yaml(text, format, name, std::move(track));
    case TrackFormat::kEufsCsv:
      return parse_eufs(text, name, std::move(track));
    case TrackFormat::kEpflCsv:
      return parse_epfl(text, name, std::move(track));
  }
  throw InputError(name, 0, "unknown track format");
}

Track read_track(const std::filesystem::path& file) {
  const std::string name = file.string();

  // a regular file of a sensible size
  std::error_code ec;
  const std::filesystem::file_status status = std::filesystem::status(file, ec);
  if (ec || !std::filesystem::exists(status))
    throw InputError(name, 0, "cannot open: no such file");
  if (!std::filesystem::is_regular_file(status)) throw InputError(name, 0, "not a regular file");
  const std::uintmax_t size = std::filesystem::file_size(file, ec);
  if (ec) throw InputError(name, 0, "cannot read its size: " + ec.message());
  if (size > kMaxTrackFileBytes)
    throw InputError(name, 0,
                     "is " + std::to_string(size) + " bytes, larger than the limit of " +
                         std::to_string(kMaxTrackFileBytes));

  // read it whole
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(name, 0, "cannot open for reading");
  std::string text(static_cast<size_t>(size), '\0');
  in.read(text.data(), static_cast<std::streamsize>(size));
  text.resize(static_cast<size_t>(in.gcount()));
  text = std::string(without_bom(text));

  // the format from the extension and the content
  const std::string ext = lower(file.extension().string());
  if (ext == ".yaml" || ext == ".yml") {
    if (trim(text).empty()) throw InputError(name, 0, "the file is empty");
    return parse_yaml(text, std::nullopt, name, new_track(name));
  }
  if (ext == ".csv")
    return parse_track(text, is_epfl_csv(text) ? TrackFormat::kEpflCsv : TrackFormat::kEufsCsv,
                       name);
  throw InputError(name, 0, "unknown extension '" + ext + "' (expected .yaml, .yml or .csv)");
}

std::string pacsim_yaml_text(const Track& track) {
  std::ostringstream out;
  const auto point = [](const Vec2& p) {
    std::string s = "[";
    s.append(format_number(p.x())).append(", ").append(format_number(p.y())).append(", 0.0]");
    return s;
  };
  const auto cone_list = [&](const char* key, const std::vector<const Cone*>& cones) {
    out << "  " << key << ":" << (cones.empty() ? " []\n" : "\n");
    for (const Cone* c : cones)
      out << "  - position: " << point(c->position) << "\n    class: " << pacsim_name(c->cls)
          << "\n";
  };

  // header, start and an identity earthToTrack
  out << "track:\n  version: 1.0\n  lanesFirstWithLastConnected: "
      << (track.closed ? "true" : "false") << "\n";
  out << "  start:\n    position: " << point(track.start.position())
      << "\n    orientation: [0.0, 0.0, " << format_number(track.start.yaw) << "]\n";
  out << "  earthToTrack:\n    position: [0.0, 0.0, 0.0]\n    orientation: [0.0, 0.0, 0.0]\n";

  // lanes in driving order, then every other cone as unknown (with its class)
  std::vector<const Cone*> left, right, others;
  for (int id : track.left_lane) left.push_back(&track.cone(id));
  for (int id : track.right_lane) right.push_back(&track.cone(id));
  std::set<int> in_lanes(track.left_lane.begin(), track.left_lane.end());
  in_lanes.insert(track.right_lane.begin(), track.right_lane.end());
  for (const Cone& c : track.cones)
    if (in_lanes.count(c.id) == 0) others.push_back(&c);
  cone_list("left", left);
  cone_list("right", right);

  // gates as pairs of time-keeping posts, left post first
  out << "  time_keeping:" << (track.timing_gates.empty() ? " []\n" : "\n");
  for (const Gate& g : track.timing_gates)
    for (const Vec2& post : {g.left, g.right})
      out << "  - position: " << point(post) << "\n    class: timekeeping\n";
  cone_list("unknown", others);
  return out.str();
}

void write_pacsim_yaml(const Track& track, const std::filesystem::path& file) {
  write_text(pacsim_yaml_text(track), file);
}

std::string eufs_csv_text(const Track& track) {
  std::ostringstream out;
  out << kEufsHeader << ",id,lane\n";

  // the start pose, its yaw in the direction column, and whether the lanes close
  out << "car_start," << format_number(track.start.x) << "," << format_number(track.start.y) << ","
      << format_number(track.start.yaw) << ",0.0,0.0,0.0,," << (track.closed ? "closed" : "open")
      << "\n";

  // a row per cone with the id its file gave it: the lanes in driving order first, then the
  // rest by id
  const auto row = [&out, &track](const Cone& c, const char* lane) {
    const Eigen::Matrix2d cov = c.covariance.value_or(Eigen::Matrix2d::Zero());
    out << eufs_tag(c.cls) << "," << format_number(c.position.x()) << ","
        << format_number(c.position.y()) << ",0.0," << format_number(cov(0, 0)) << ","
        << format_number(cov(1, 1)) << "," << format_number(cov(0, 1)) << "," << track.file_id(c.id)
        << "," << lane << "\n";
  };
  std::unordered_map<int, size_t> index_of_id;
  for (size_t i = 0; i < track.cones.size(); ++i) index_of_id.emplace(track.cones[i].id, i);
  std::vector<bool> written(track.cones.size(), false);
  const auto write_lane = [&](const std::vector<int>& lane, const char* name) {
    for (int id : lane)
      if (const auto it = index_of_id.find(id); it != index_of_id.end() && !written[it->second]) {
        row(track.cones[it->second], name);
        written[it->second] = true;
      }
  };
  write_lane(track.left_lane, "left");
  write_lane(track.right_lane, "right");
  std::vector<const Cone*> rest;
  for (size_t i = 0; i < track.cones.size(); ++i)
    if (!written[i]) rest.push_back(&track.cones[i]);
  std::sort(rest.begin(), rest.end(), [&track](const Cone* a, const Cone* b) {
    return track.file_id(a->id) < track.file_id(b->id);
  });
  for (const Cone* c : rest) row(*c, "");
  return out.str();
}

void write_eufs_csv(const Track& track, const std::filesystem::path& file) {
  write_text(eufs_csv_text(track), file);
}

void write_track(const Track& track, const std::filesystem::path& file) {
  const std::string ext = lower(file.extension().string());
  if (ext == ".yaml" || ext == ".yml") return write_pacsim_yaml(track, file);
  if (ext == ".csv") return write_eufs_csv(track, file);
  throw InputError(file.string(), 0,
                   "unknown extension '" + ext + "' for writing (expected .yaml, .yml or .csv)");
}

}  // namespace conesim::tracks
