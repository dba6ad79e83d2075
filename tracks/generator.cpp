#include "tracks/generator.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "core/rng.hpp"
#include "tracks/lanes.hpp"

namespace conesim::tracks {

namespace {

using core::Rng;
using core::uniform;
using core::uniform_int;

constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180.0;

// start zone: the start pose sits kStartLineM behind the start line on the start straight
constexpr double kStartLineM = 6.0;
constexpr double kBigConeHalfGapM = 1.3;   // big orange cones at the line +- this, along track
constexpr double kBigConeOutsideM = 0.7;   // and this far outside the boundary (as at FSG)
constexpr double kGatePostOutsideM = 1.2;  // photocell posts outside the boundary

// design limits, inside the handbook's with a margin
constexpr double kMaxStraightM = 75.0;  // rule: 80 m
constexpr double kLapMarginM = 10.0;    // kept from min_lap_m and max_lap_m
constexpr double kClearanceM = 2.0;     // between boundaries of non-adjacent track parts
constexpr double kAdjacentM = 20.0;     // track parts closer than this along the line
constexpr double kExtraWidthM = 0.8;    // sections are up to this much wider than width_m
constexpr double kWidthBlendM = 3.0;    // width changes ramp over +- this

// primitive geometry (centre-line radii); the hairpin's inner boundary stays >= 2.5 m
constexpr double kHairpinMinRadiusM = 5.0;
constexpr double kHairpinRadiusSpreadM = 2.0;
constexpr double kHairpinMinInnerRadiusM = 2.5;
constexpr double kCornerMinRadiusM = 8.0;
constexpr double kCornerMaxRadiusM = 12.0;
constexpr double kSweeperMinRadiusM = 10.0;
constexpr double kSweeperMaxRadiusM = 20.0;    // rule: turns up to 50 m diameter
constexpr double kSlalomMinHalfPeriodM = 8.5;  // rule: slalom cones 7.5 .. 12 m apart
constexpr double kSlalomMaxHalfPeriodM = 11.5;
constexpr double kSlalomMaxCurvature = 1.0 / 6.0;
constexpr std::array<double, 4> kClosingRadiiM{8.0, 11.0, 14.0, 18.0};
constexpr double kMaxClosingStraightM = 40.0;  // longer closures look like an afterthought

// cone spacing: cone_spacing_m on straights and wide sweepers, kTightSpacingM in hairpins
constexpr double kTightSpacingM = 3.0;
constexpr double kWideCurvature = 1.0 / 25.0;
constexpr double kTightCurvature = 1.0 / 7.0;

// sampling steps: the design integration, and the clearance checks
constexpr double kSampleStepM = 0.1;
constexpr double kCheckStepM = 0.5;

// the primitives the turtle lays, and how often each is drawn
enum class Primitive { kStraight, kSweeper, kCorner, kHairpin, kChicane, kSlalom };
constexpr std::array<std::pair<Primitive, double>, 6> kPrimitiveWeights{{
    {Primitive::kStraight, 0.20},
    {Primitive::kSweeper, 0.25},
    {Primitive::kCorner, 0.15},
    {Primitive::kHairpin, 0.15},
    {Primitive::kChicane, 0.15},
    {Primitive::kSlalom, 0.10},
}};

// minimum hairpins are drawn between GeneratorParams::hairpin_outer_diameter_m and this much more
constexpr double kMinHairpinDiameterSpreadM = 0.3;
// the longest straight of the straight-into-hairpin profiles, designed: the rule checker measures
// straights by their chord headings and finds about 2 m less, so this is 78 m by the rules
constexpr double kMaxHardStraightM = 80.0;
// cones of a minimum hairpin and its straights: closer along each boundary than the inner
// boundaries of the two legs are to each other (2.6-3.2 m), so that a reader that rebuilds the
// lanes from the cone colours chains them along the boundary, not across the hairpin
constexpr double kMinHairpinConeSpacingM = 2.0;
// a minimum hairpin is laid only where the guide turns at least this much ahead
constexpr double kMinHairpinWantedTurnRad = 60.0 * kDeg;
// a minimum hairpin's width: narrow, so that its inner boundary keeps 1.1-1.5 m of radius (wider,
// the inner cones bunch up into a point the lane order cannot follow)
constexpr double kMinHairpinWidthM = 3.2;
constexpr double kMinHairpinWidthSpreadM = 0.3;
// narrow lanes: the rule's 3 m and a little for the chords between cones in turns
constexpr double kNarrowWidthM = 3.05;
// in turns, cones are close enough that the chord between two of them cuts at most this much
// less than the width above the rule's minimum into the track (and at least this much)
constexpr double kMinSagittaAllowanceM = 0.04;
constexpr double kSagittaMarginM = 0.06;

// what a profile changes in the drawing of a layout
struct ProfileSettings {
  std::array<double, 6> weights{};  // in the order of kPrimitiveWeights
  double width_m = 0.0;             // narrowest width (0: the parameters' width_m)
  double extra_width_m = kExtraWidthM;
  bool minimum_hairpins = false;  // hairpins at the FSG minimum outside diameter
  bool long_straight_start = false;
  double max_straight_m = kMaxStraightM;
  int min_hairpins = 1;
  int min_chicanes = 0;
  int min_slaloms = 0;
  int max_slaloms = 1;
  double chicane_min_radius_m = 8.0;
  double chicane_max_radius_m = 13.0;
  double chicane_min_deg = 35.0;
  double chicane_max_deg = 75.0;
  int slalom_min_pairs = 2;  // half waves are twice this
  int slalom_max_pairs = 3;
  bool limit_sagitta = false;  // cones close enough in turns that the measured width holds
};

// the pieces of the profiles, combined by settings_of
void use_minimum_hairpins(ProfileSettings& p) {
  p.minimum_hairpins = true;
  p.extra_width_m = 0.5;
}
void use_tight_chicanes(ProfileSettings& p) {
  p.chicane_min_radius_m = 6.0;
  p.chicane_max_radius_m = 9.0;
  p.chicane_min_deg = 45.0;
  p.chicane_max_deg = 80.0;
}
void use_long_straight_into_hairpin(ProfileSettings& p) {
  use_minimum_hairpins(p);
  p.long_straight_start = true;
  p.max_straight_m = kMaxHardStraightM;
}

ProfileSettings settings_of(GeneratorProfile profile) {
  ProfileSettings p;
  for (size_t i = 0; i < p.weights.size(); ++i) p.weights[i] = kPrimitiveWeights[i].second;
  if (profile == GeneratorProfile::kStandard) return p;
  p.limit_sagitta = true;
  switch (profile) {
    case GeneratorProfile::kStandard:
      break;
    case GeneratorProfile::kHairpins:
      p.weights = {0.20, 0.15, 0.10, 0.35, 0.10, 0.10};
      use_minimum_hairpins(p);
      p.min_hairpins = 3;
      break;
    case GeneratorProfile::kSlalom:
      p.weights = {0.20, 0.20, 0.10, 0.10, 0.10, 0.30};
      p.min_slaloms = 2;
      p.max_slaloms = 3;
      p.slalom_max_pairs = 4;
      break;
    case GeneratorProfile::kChicanes:
      p.weights = {0.20, 0.15, 0.10, 0.10, 0.40, 0.05};
      use_tight_chicanes(p);
      p.min_chicanes = 3;
      break;
    case GeneratorProfile::kNarrow:
      p.width_m = kNarrowWidthM;
      p.extra_width_m = 0.0;
      break;
    case GeneratorProfile::kStraightIntoHairpin:
      use_long_straight_into_hairpin(p);
      break;
    case GeneratorProfile::kHard:
      p.weights = {0.15, 0.10, 0.10, 0.25, 0.25, 0.15};
      use_long_straight_into_hairpin(p);
      use_tight_chicanes(p);
      p.width_m = kNarrowWidthM;
      p.extra_width_m = 0.3;
      p.min_hairpins = 2;
      p.min_chicanes = 1;
      p.min_slaloms = 1;
      break;
  }
  return p;
}

// what a piece of centre line is part of (for the feature counts)
// (kHairpinLeg: the braking and exit straights of a minimum hairpin)
enum class Feature {
  kStraight,
  kSweeper,
  kCorner,
  kHairpin,
  kHairpinLeg,
  kChicane,
  kSlalom,
  kClosing
};

// one piece of centre line: a constant-curvature arc (curvature 0: a straight), or one half
// wave of a slalom whose curvature follows peak * sin(pi s / length)
struct Piece {
  Feature feature = Feature::kStraight;
  bool sine = false;
  double length_m = 0.0;
  double curvature = 0.0;  // signed, left positive; the peak value for a half wave
  double width_m = 0.0;
};

// a pose of the turtle that lays the pieces; heading is not wrapped (it counts the laps)
struct Turtle {
  Vec2 position = Vec2::Zero();
  double heading = 0.0;
  double s_m = 0.0;
};

// a point of the sampled centre line
struct Sample {
  Vec2 position = Vec2::Zero();
  double heading = 0.0;
  double curvature = 0.0;
  double width_m = 0.0;
  double s_m = 0.0;
  Feature feature = Feature::kStraight;
};

// heading change from the start of a piece to distance u into it
double heading_change(const Piece& piece, double u) {
  if (!piece.sine) return piece.curvature * u;
  const double k = kPi / piece.length_m;
  return piece.curvature / k * (1.0 - std::cos(k * u));
}

// curvature at distance u into a piece
double curvature_at(const Piece& piece, double u) {
  if (!piece.sine) return piece.curvature;
  return piece.curvature * std::sin(kPi * u / piece.length_m);
}

// displacement along a piece from distance u to u + h: the exact chord of an arc, Simpson's
// rule over eight intervals for a half wave
Vec2 displacement(const Piece& piece, double heading0, double u, double h) {
  if (!piece.sine) {
    const double turn = piece.curvature * h;
    const double mid = heading0 + heading_change(piece, u) + 0.5 * turn;
    const double chord = std::abs(turn) > 1e-12 ? h * std::sin(0.5 * turn) / (0.5 * turn) : h;
    return chord * Vec2(std::cos(mid), std::sin(mid));
  }
  constexpr int kIntervals = 8;
  Vec2 sum = Vec2::Zero();
  for (int i = 0; i <= kIntervals; ++i) {
    const double heading = heading0 + heading_change(piece, u + h * i / kIntervals);
    const double weight = (i == 0 || i == kIntervals) ? 1.0 : (i % 2 == 1 ? 4.0 : 2.0);
    sum += weight * Vec2(std::cos(heading), std::sin(heading));
  }
  return sum * (h / (3.0 * kIntervals));
}

// lays a piece from the turtle's pose: appends samples every <= step_m (the first point of the
// piece included, its end excluded) and moves the turtle to the piece's end
void lay_piece(const Piece& piece, double step_m, Turtle& turtle, std::vector<Sample>* out) {
  const int steps = std::max(1, static_cast<int>(std::ceil(piece.length_m / step_m - 1e-9)));
  const double h = piece.length_m / steps;
  const double heading0 = turtle.heading;
  for (int i = 0; i < steps; ++i) {
    const double u = i * h;
    if (out) {
      out->push_back({turtle.position, heading0 + heading_change(piece, u), curvature_at(piece, u),
                      piece.width_m, turtle.s_m, piece.feature});
    }
    turtle.position += displacement(piece, heading0, u, h);
    turtle.s_m += h;
  }
  turtle.heading = heading0 + heading_change(piece, piece.length_m);
}

// lays a list of pieces from a turtle pose
std::vector<Sample> lay_pieces(const std::vector<Piece>& pieces, double step_m, Turtle& turtle) {
  std::vector<Sample> out;
  for (const Piece& piece : pieces) lay_piece(piece, step_m, turtle, &out);
  return out;
}

// true when every sample of `fresh` keeps the clearance to every sample of `laid` that is not
// adjacent along the line (lap_m > 0: distances along the line wrap around the closed loop)
bool keeps_clearance(const std::vector<Sample>& laid, const std::vector<Sample>& fresh,
                     double lap_m) {
  for (const Sample& a : fresh) {
    for (const Sample& b : laid) {
      double gap = std::abs(a.s_m - b.s_m);
      if (lap_m > 0.0) gap = std::min(gap, lap_m - gap);
      if (gap < kAdjacentM) continue;
      const double need = 0.5 * (a.width_m + b.width_m) + kClearanceM;
      if ((a.position - b.position).squaredNorm() < need * need) return false;
    }
  }
  return true;
}

// a closed guide loop the turtle follows: a lobed, stretched circle through the start pose,
// tangent to +x there, of a given length (the track winds around it and comes out longer)
class Guide {
 public:
  Guide(Rng& rng, double length_m, double direction) {
    // the unit shape: a polar curve with two- and three-lobed terms, stretched along x
    constexpr int kPoints = 256;
    const double a2 = uniform(rng, 0.0, 0.3), p2 = uniform(rng, 0.0, 2.0 * kPi);
    const double a3 = uniform(rng, 0.0, 0.15), p3 = uniform(rng, 0.0, 2.0 * kPi);
    const double stretch = uniform(rng, 1.0, 1.8);
    std::vector<Vec2> unit(kPoints);
    for (int k = 0; k < kPoints; ++k) {
      const double phi = 2.0 * kPi * k / kPoints;
      const double r = 1.0 + a2 * std::cos(2.0 * phi + p2) + a3 * std::cos(3.0 * phi + p3);
      unit[k] = Vec2(stretch * r * std::cos(phi), direction * r * std::sin(phi));
    }

    // scaled to the length, started at a random point, moved to the start pose
    double perimeter = 0.0;
    for (int k = 0; k < kPoints; ++k) perimeter += (unit[(k + 1) % kPoints] - unit[k]).norm();
    const int k0 = static_cast<int>(uniform_int(rng, 0, kPoints - 1));
    const Vec2 tangent = unit[(k0 + 1) % kPoints] - unit[(k0 + kPoints - 1) % kPoints];
    const Pose2 frame{unit[k0].x(), unit[k0].y(), std::atan2(tangent.y(), tangent.x())};
    const double scale = length_m / perimeter;
    double s = 0.0;
    for (int k = 0; k <= kPoints; ++k) {
      const Vec2 p = scale * frame.inverse_transform(unit[(k0 + k) % kPoints]);
      if (k > 0) s += (p - points_.back()).norm();
      points_.push_back(p);
      s_.push_back(s);
    }
  }

  double length_m() const { return s_.back(); }

  // the guide point at distance s along the loop (wrapped)
  Vec2 at(double s) const {
    s = std::fmod(s, length_m());
    if (s < 0.0) s += length_m();
    const size_t i = static_cast<size_t>(std::upper_bound(s_.begin(), s_.end(), s) - s_.begin());
    const size_t i1 = std::min(i, s_.size() - 1), i0 = i1 - 1;
    const double f = (s - s_[i0]) / std::max(1e-9, s_[i1] - s_[i0]);
    return points_[i0] + f * (points_[i1] - points_[i0]);
  }

  // distance along the guide of its point nearest p, searched in [from_m, to_m]
  double project(const Vec2& p, double from_m, double to_m) const {
    double best_s = from_m, best_d2 = std::numeric_limits<double>::infinity();
    for (size_t i = 0; i < points_.size(); ++i) {
      if (s_[i] < from_m || s_[i] > to_m) continue;
      const double d2 = (points_[i] - p).squaredNorm();
      if (d2 < best_d2) {
        best_d2 = d2;
        best_s = s_[i];
      }
    }
    return best_s;
  }

 private:
  std::vector<Vec2> points_;
  std::vector<double> s_;
};

// the pieces of the open part of one layout: a turtle lays random primitives from the start
// pose, steering towards a point ahead on the guide loop, and stops short of closing the loop
class LayoutDrawer {
 public:
  LayoutDrawer(Rng& rng, const GeneratorParams& params, const ProfileSettings& settings)
      : rng_(rng),
        params_(params),
        settings_(settings),
        direction_(travel_direction(rng, params.direction)),
        guide_(rng, guide_length(rng, params), direction_),
        lead_m_(uniform(rng, 6.0, 12.0)),
        stop_before_m_(uniform(rng, 20.0, 35.0)) {}

  // draws the open part of the circuit from the start pose; nullopt when it painted itself in
  std::optional<std::vector<Piece>> draw_open_part() {
    // the lead-in of the closing straight is reserved so that the turtle stays clear of it
    Turtle lead{Vec2(-lead_m_, 0.0), 0.0, -lead_m_};
    laid_ = lay_pieces({straight(lead_m_, width())}, kCheckStepM, lead);

    // the start straight: long enough for the start zone and the feature mix; or, with the
    // lead-in and a hairpin's braking straight, nearly the longest straight allowed, into a
    // minimum hairpin
    if (settings_.long_straight_start) {
      const double run_m =
          uniform(rng_, settings_.max_straight_m - 3.0, settings_.max_straight_m - 0.5);
      const double w = hairpin_width();
      const double braking_m = uniform(rng_, 8.0, 14.0);
      add({straight(run_m - lead_m_ - braking_m, w)});
      if (!try_add(minimum_hairpin(wanted_turn(), w, braking_m))) return std::nullopt;
    } else {
      add({drawn_straight(32.0, 45.0)});
    }

    // primitives until the guide is nearly done, retrying a few draws when one runs into the
    // track laid so far; a turtle that wanders off makes too long a lap
    while (progress_m_ < guide_.length_m() - stop_before_m_) {
      bool placed = false;
      for (int attempt = 0; attempt < 12 && !placed; ++attempt) placed = try_add(draw_primitive());
      if (!placed || turtle_.s_m > params_.max_lap_m) return std::nullopt;
    }
    if (hairpins_ < settings_.min_hairpins || chicanes_ < settings_.min_chicanes ||
        slaloms_ < settings_.min_slaloms)
      return std::nullopt;
    return pieces_;
  }

  const Turtle& end() const { return turtle_; }
  const std::vector<Sample>& laid() const { return laid_; }
  double lead_m() const { return lead_m_; }
  double width() { return narrowest() + uniform(rng_, 0.0, settings_.extra_width_m); }
  // A straight of a drawn length and width. Every draw from the generator is a statement of its
  // own: the order of a call's arguments is left to the compiler, and gcc and clang differ,
  // which made the same seed give another track in each build. The orders written out here are
  // the ones gcc used, so that the layouts made before stay as they were.
  Piece drawn_straight(double min_length_m, double max_length_m) {
    const double w = width();
    return straight(uniform(rng_, min_length_m, max_length_m), w);
  }
  double direction() const { return direction_; }

 private:
  // +1 counter-clockwise, -1 clockwise; drawn from the seed even when the parameters fix it,
  // so that the rest of the layout is the same either way
  static double travel_direction(Rng& rng, TravelDirection wanted) {
    const double drawn = uniform(rng, 0.0, 1.0) < 0.5 ? 1.0 : -1.0;
    if (wanted == TravelDirection::kCounterClockwise) return 1.0;
    if (wanted == TravelDirection::kClockwise) return -1.0;
    return drawn;
  }

  double narrowest() const { return settings_.width_m > 0.0 ? settings_.width_m : params_.width_m; }

  // a minimum hairpin's width: narrow, so that its inner boundary keeps some radius
  double hairpin_width() {
    return std::min(narrowest(), kMinHairpinWidthM) + uniform(rng_, 0.0, kMinHairpinWidthSpreadM);
  }

  // the guide is shorter than the lap it leads to: the primitives wind around it
  static double guide_length(Rng& rng, const GeneratorParams& params) {
    const double lap_m = uniform(rng, params.min_lap_m + 40.0, params.max_lap_m - 60.0);
    return lap_m * uniform(rng, 0.55, 0.7);
  }

  static Piece straight(double length_m, double width_m) {
    return {Feature::kStraight, false, length_m, 0.0, width_m};
  }
  static Piece arc(Feature feature, double radius_m, double turn_rad, double width_m) {
    const double sign = turn_rad >= 0.0 ? 1.0 : -1.0;
    return {feature, false, radius_m * std::abs(turn_rad), sign / radius_m, width_m};
  }

  // the turn that points the turtle at the guide kLookAheadM beyond its own progress
  double wanted_turn() const {
    constexpr double kLookAheadM = 18.0;
    const Vec2 to = guide_.at(progress_m_ + kLookAheadM) - turtle_.position;
    return core::normalize_angle(std::atan2(to.y(), to.x()) - turtle_.heading);
  }

  // turn direction: the guide's, sometimes the other way when the guide asks for little
  double turn_sign(double wanted, double counter_limit_rad) {
    double sign = wanted >= 0.0 ? 1.0 : -1.0;
    if (std::abs(wanted) < counter_limit_rad && uniform(rng_, 0.0, 1.0) < 0.35) sign = -sign;
    return sign;
  }

  // a turn angle in [lo, hi]: close to what the guide wants when turning its way
  double turn_angle(double wanted, double sign, double lo, double hi) {
    if (sign * wanted <= 0.0) return uniform(rng_, lo, 0.5 * (lo + hi));
    return std::clamp(std::abs(wanted) * uniform(rng_, 0.8, 1.3), lo, hi);
  }

  bool last_is_straight() const {
    return !pieces_.empty() && !pieces_.back().sine && pieces_.back().curvature == 0.0;
  }

  // one primitive, drawn by kPrimitiveWeights; a hairpin when the guide turns sharply (half of
  // the time) and when the layout still lacks one past half way
  std::vector<Piece> draw_primitive() {
    const double wanted = wanted_turn();
    const double behind = settings_.min_hairpins > 1
                              ? static_cast<double>(hairpins_ + 1) / (settings_.min_hairpins + 1)
                              : 0.5;
    const bool force_hairpin = hairpins_ < settings_.min_hairpins &&
                               progress_m_ > behind * guide_.length_m() &&
                               std::abs(wanted) > kPi / 4;
    const bool sharp = std::abs(wanted) > 110.0 * kDeg && uniform(rng_, 0.0, 1.0) < 0.5;
    Primitive kind = Primitive::kHairpin;
    if (!force_hairpin && !sharp) {
      double pick = uniform(rng_, 0.0, 1.0);
      for (size_t i = 0; i < kPrimitiveWeights.size(); ++i) {
        kind = kPrimitiveWeights[i].first;
        if ((pick -= settings_.weights[i]) < 0.0) break;
      }
    }
    // no two straights in a row, at most max_slaloms slaloms
    if (kind == Primitive::kStraight && last_is_straight()) kind = Primitive::kSweeper;
    if (kind == Primitive::kSlalom && slaloms_ >= settings_.max_slaloms) kind = Primitive::kChicane;

    switch (kind) {
      case Primitive::kStraight:
        return {draw_straight()};
      case Primitive::kSweeper:
        return {draw_turn(Feature::kSweeper, kSweeperMinRadiusM, kSweeperMaxRadiusM, 25.0, 100.0,
                          wanted)};
      case Primitive::kCorner:
        return {
            draw_turn(Feature::kCorner, kCornerMinRadiusM, kCornerMaxRadiusM, 45.0, 120.0, wanted)};
      case Primitive::kHairpin:
        return draw_hairpin(wanted);
      case Primitive::kChicane:
        return draw_chicane();
      case Primitive::kSlalom:
        return draw_slalom();
    }
    return {};
  }

  // straight: mostly short, sometimes a long one
  Piece draw_straight() {
    const bool long_one = uniform(rng_, 0.0, 1.0) < 0.15;
    const double length = long_one ? uniform(rng_, 30.0, 45.0) : uniform(rng_, 8.0, 25.0);
    return straight(length, width());
  }

  // constant turn (sweeper or corner): radius and angle range given, degrees
  Piece draw_turn(Feature feature, double min_radius_m, double max_radius_m, double min_deg,
                  double max_deg, double wanted) {
    const double radius = uniform(rng_, min_radius_m, max_radius_m);
    const double sign = turn_sign(wanted, 45.0 * kDeg);
    const double angle = turn_angle(wanted, sign, min_deg * kDeg, max_deg * kDeg);
    return arc(feature, radius, sign * angle, width());
  }

  // hairpin: a braking straight, 150-200 degrees around a tight radius (the inner boundary
  // keeps kHairpinMinInnerRadiusM at the widest section width), a short exit straight
  std::vector<Piece> draw_hairpin(double wanted) {
    if (settings_.minimum_hairpins) {
      // a U-turn where the guide does not turn leaves the turtle heading the wrong way, beside
      // its own track: a corner instead
      if (std::abs(wanted) < kMinHairpinWantedTurnRad)
        return {
            draw_turn(Feature::kCorner, kCornerMinRadiusM, kCornerMaxRadiusM, 45.0, 120.0, wanted)};
      const double leg_m = uniform(rng_, 8.0, 20.0);
      return minimum_hairpin(wanted, hairpin_width(), leg_m);
    }
    std::vector<Piece> out;
    if (!last_is_straight()) out.push_back(drawn_straight(8.0, 20.0));
    const double sign =
        std::abs(wanted) > kPi / 4 ? (wanted > 0 ? 1.0 : -1.0) : turn_sign(wanted, kPi);
    const double min_radius = std::max(
        kHairpinMinRadiusM, 0.5 * (params_.width_m + kExtraWidthM) + kHairpinMinInnerRadiusM);
    const double radius = uniform(rng_, min_radius, min_radius + kHairpinRadiusSpreadM);
    const double w = width();
    out.push_back(arc(Feature::kHairpin, radius, sign * uniform(rng_, 150.0, 200.0) * kDeg, w));
    out.push_back(drawn_straight(6.0, 14.0));
    return out;
  }

  // a hairpin at the FSG minimum: a braking straight, 160-200 degrees around a centre-line
  // radius that puts the outer boundary at hairpin_outer_diameter_m (+ up to the spread)
  // across, an exit straight; all three of one width, so that no width ramp bends the outer
  // boundary tighter than designed
  std::vector<Piece> minimum_hairpin(double wanted, double w, double braking_m) {
    const double sign =
        std::abs(wanted) > kPi / 4 ? (wanted > 0 ? 1.0 : -1.0) : turn_sign(wanted, kPi);
    const double outer_diameter =
        params_.hairpin_outer_diameter_m + uniform(rng_, 0.0, kMinHairpinDiameterSpreadM);
    const double radius = 0.5 * outer_diameter - 0.5 * w;
    const Piece braking{Feature::kHairpinLeg, false, braking_m, 0.0, w};
    const Piece turn = arc(Feature::kHairpin, radius, sign * uniform(rng_, 160.0, 200.0) * kDeg, w);
    const Piece exit{Feature::kHairpinLeg, false, uniform(rng_, 6.0, 14.0), 0.0, w};
    return {braking, turn, exit};
  }

  // chicane: an S-bend that leaves the heading nearly unchanged
  std::vector<Piece> draw_chicane() {
    std::vector<Piece> out;
    const ProfileSettings& p = settings_;
    const double sign = uniform(rng_, 0.0, 1.0) < 0.5 ? 1.0 : -1.0;
    const double angle = uniform(rng_, p.chicane_min_deg, p.chicane_max_deg) * kDeg;
    const double w = width();
    out.push_back(arc(Feature::kChicane,
                      uniform(rng_, p.chicane_min_radius_m, p.chicane_max_radius_m), sign * angle,
                      w));
    const double between = uniform(rng_, 0.0, 5.0);
    if (between > 1.0) out.push_back({Feature::kChicane, false, between, 0.0, w});
    const double scale = uniform(rng_, 0.7, 1.3);
    const double radius = uniform(rng_, p.chicane_min_radius_m, p.chicane_max_radius_m);
    out.push_back(arc(Feature::kChicane, radius, -sign * angle * scale, w));
    return out;
  }

  // slalom: the line weaves around a row of cones with inflections one half period apart;
  // half-amplitude first and last half waves keep the heading centred on the row
  std::vector<Piece> draw_slalom() {
    std::vector<Piece> out;
    if (!last_is_straight()) out.push_back(drawn_straight(6.0, 12.0));
    const int half_waves = 2 * static_cast<int>(uniform_int(rng_, settings_.slalom_min_pairs,
                                                            settings_.slalom_max_pairs));
    const double half_period = uniform(rng_, kSlalomMinHalfPeriodM, kSlalomMaxHalfPeriodM);
    const double peak = uniform(rng_, 0.8, 1.0) * kSlalomMaxCurvature;
    const double sign = uniform(rng_, 0.0, 1.0) < 0.5 ? 1.0 : -1.0;
    const double w = width();
    for (int i = 0; i < half_waves; ++i) {
      const double scale = (i == 0 || i + 1 == half_waves) ? 0.5 : 1.0;
      const double alternate = i % 2 == 0 ? sign : -sign;
      out.push_back({Feature::kSlalom, true, half_period, alternate * scale * peak, w});
    }
    out.push_back(drawn_straight(6.0, 12.0));
    return out;
  }

  // lays a primitive when it keeps clear of the track laid so far
  bool try_add(const std::vector<Piece>& primitive) {
    Turtle next = turtle_;
    const std::vector<Sample> fresh = lay_pieces(primitive, kCheckStepM, next);
    if (!keeps_clearance(laid_, fresh, 0.0)) return false;
    add_laid(primitive, fresh, next);
    return true;
  }

  // lays a primitive without checks (the start straight)
  void add(const std::vector<Piece>& primitive) {
    Turtle next = turtle_;
    const std::vector<Sample> fresh = lay_pieces(primitive, kCheckStepM, next);
    add_laid(primitive, fresh, next);
  }

  // takes a laid primitive: pieces, samples, turtle pose, feature counts and guide progress
  void add_laid(const std::vector<Piece>& primitive, const std::vector<Sample>& fresh,
                const Turtle& next) {
    for (size_t i = 0; i < primitive.size(); ++i) {
      const Piece& p = primitive[i];
      if (p.feature == Feature::kHairpin) ++hairpins_;
      if (p.feature == Feature::kSlalom && (i == 0 || primitive[i - 1].feature != Feature::kSlalom))
        ++slaloms_;
      if (p.feature == Feature::kChicane && i == 0) ++chicanes_;
    }
    pieces_.insert(pieces_.end(), primitive.begin(), primitive.end());
    laid_.insert(laid_.end(), fresh.begin(), fresh.end());
    turtle_ = next;
    progress_m_ = std::max(progress_m_,
                           guide_.project(turtle_.position, progress_m_ - 5.0, progress_m_ + 60.0));
  }

  Rng& rng_;
  const GeneratorParams& params_;
  const ProfileSettings& settings_;
  double direction_;
  Guide guide_;
  double lead_m_;
  double stop_before_m_;
  Turtle turtle_;
  double progress_m_ = 0.0;
  std::vector<Piece> pieces_;
  std::vector<Sample> laid_;
  int hairpins_ = 0;
  int slaloms_ = 0;
  int chicanes_ = 0;
};

// angle wrapped to [0, 2 pi)
double wrap_positive(double a) {
  a = std::fmod(a, 2.0 * kPi);
  return a < 0.0 ? a + 2.0 * kPi : a;
}

// one Dubins path of type CSC: turn, straight, turn (turns signed, left positive)
struct DubinsCsc {
  double radius_m = 0.0;
  double turn1 = 0.0;
  double straight_m = 0.0;
  double turn2 = 0.0;
  double length_m() const { return radius_m * (std::abs(turn1) + std::abs(turn2)) + straight_m; }
};

// the four CSC Dubins paths (LSL, RSR, LSR, RSL) from one pose to another
std::vector<DubinsCsc> dubins_csc(const Vec2& p0, double heading0, const Vec2& p1, double heading1,
                                  double r) {
  const auto centre = [r](const Vec2& p, double heading, double side) {
    return Vec2(p + side * r * Vec2(-std::sin(heading), std::cos(heading)));
  };
  std::vector<DubinsCsc> out;
  for (const double s0 : {1.0, -1.0}) {
    for (const double s1 : {1.0, -1.0}) {
      const Vec2 v = centre(p1, heading1, s1) - centre(p0, heading0, s0);
      const double d = v.norm();
      const double psi = std::atan2(v.y(), v.x());
      double straight_m = d;
      double phi = psi;
      // crossing tangents need room for both circles
      if (s0 != s1) {
        if (d < 2.0 * r) continue;
        straight_m = std::sqrt(d * d - 4.0 * r * r);
        phi = psi + s0 * std::atan2(2.0 * r, straight_m);
      }
      const double turn1 = s0 * wrap_positive(s0 * (phi - heading0));
      const double turn2 = s1 * wrap_positive(s1 * (heading1 - phi));
      out.push_back({r, turn1, straight_m, turn2});
    }
  }
  return out;
}

// the pieces of a Dubins path (zero-length parts dropped)
std::vector<Piece> closing_pieces(const DubinsCsc& path, double width1, double width2,
                                  double width3) {
  std::vector<Piece> out;
  const auto add_arc = [&](double turn, double w) {
    if (std::abs(turn) * path.radius_m < 0.05) return;
    out.push_back({Feature::kClosing, false, std::abs(turn) * path.radius_m,
                   (turn > 0.0 ? 1.0 : -1.0) / path.radius_m, w});
  };
  add_arc(path.turn1, width1);
  if (path.straight_m > 0.05)
    out.push_back({Feature::kStraight, false, path.straight_m, 0.0, width2});
  add_arc(path.turn2, width3);
  return out;
}

// true for a piece the rule checker sees as part of a straight (it turns by less than 6 deg)
bool is_straightish(const Piece& p) {
  return !p.sine && std::abs(p.curvature) * p.length_m < 6.0 * kDeg;
}

// longest run of straight pieces around the closed loop
double longest_straight(const std::vector<Piece>& pieces) {
  const size_t n = pieces.size();
  double best = 0.0;
  for (size_t start = 0; start < n; ++start) {
    if (is_straightish(pieces[(start + n - 1) % n])) continue;  // not the start of a run
    double run = 0.0;
    for (size_t k = 0; k < n && is_straightish(pieces[(start + k) % n]); ++k)
      run += pieces[(start + k) % n].length_m;
    best = std::max(best, run);
  }
  return best;
}

// closes the open part back to the start pose; the pieces of the whole lap when one of the
// closing paths keeps the rules and the clearance
std::optional<std::vector<Piece>> close_loop(LayoutDrawer& drawer, std::vector<Piece> open,
                                             const GeneratorParams& params,
                                             const ProfileSettings& settings) {
  // candidate closing paths, shortest first
  const Turtle& end = drawer.end();
  const Vec2 lead_start(-drawer.lead_m(), 0.0);
  std::vector<DubinsCsc> candidates;
  for (double r : kClosingRadiiM) {
    for (const DubinsCsc& c : dubins_csc(end.position, end.heading, lead_start, 0.0, r)) {
      if (std::abs(c.turn1) < 1.5 * kPi && std::abs(c.turn2) < 1.5 * kPi &&
          c.straight_m <= kMaxClosingStraightM)
        candidates.push_back(c);
    }
  }
  std::sort(candidates.begin(), candidates.end(),
            [](const DubinsCsc& a, const DubinsCsc& b) { return a.length_m() < b.length_m(); });

  // the open part's samples without the reserved lead-in (it is laid again below)
  std::vector<Sample> laid;
  for (const Sample& s : drawer.laid())
    if (s.s_m >= 0.0) laid.push_back(s);

  const double w1 = drawer.width(), w2 = drawer.width(), w3 = drawer.width();
  const double lead_w = open.front().width_m;
  for (const DubinsCsc& c : candidates) {
    // lap length and straights first: they are cheap
    const double lap_m = end.s_m + c.length_m() + drawer.lead_m();
    if (lap_m < params.min_lap_m + kLapMarginM || lap_m > params.max_lap_m - kLapMarginM) continue;
    std::vector<Piece> closing = closing_pieces(c, w1, w2, w3);
    closing.push_back({Feature::kStraight, false, drawer.lead_m(), 0.0, lead_w});
    std::vector<Piece> lap = open;
    lap.insert(lap.end(), closing.begin(), closing.end());
    if (longest_straight(lap) > settings.max_straight_m) continue;

    // the closing path must keep clear of the rest and end on the start pose
    Turtle t = end;
    const std::vector<Sample> fresh = lay_pieces(closing, kCheckStepM, t);
    if (t.position.norm() > 1e-4 || std::abs(core::normalize_angle(t.heading)) > 1e-6) continue;
    if (!keeps_clearance(laid, fresh, t.s_m)) continue;
    return lap;
  }
  return std::nullopt;
}

// the sampled centre line of a lap with widths blended at the joins between pieces
std::vector<Sample> sample_lap(const std::vector<Piece>& lap) {
  Turtle t;
  std::vector<Sample> samples = lay_pieces(lap, kSampleStepM, t);
  const size_t n = samples.size();

  // moving average of the width over +- kWidthBlendM (piecewise constant -> linear ramps)
  std::vector<double> w(n);
  const int half = static_cast<int>(std::round(kWidthBlendM / kSampleStepM));
  double sum = 0.0;
  for (int k = -half; k <= half; ++k) sum += samples[(k + n) % n].width_m;
  for (size_t i = 0; i < n; ++i) {
    w[i] = sum / (2 * half + 1);
    sum += samples[(i + half + 1) % n].width_m - samples[(i + n - half) % n].width_m;
  }
  for (size_t i = 0; i < n; ++i) samples[i].width_m = w[i];
  return samples;
}

// the centre-line sample interpolated at distance s (wrapped around the lap)
Sample sample_at(const std::vector<Sample>& samples, double lap_m, double s) {
  s = std::fmod(s, lap_m);
  if (s < 0.0) s += lap_m;
  const auto it = std::upper_bound(samples.begin(), samples.end(), s,
                                   [](double v, const Sample& x) { return v < x.s_m; });
  const size_t i1 = static_cast<size_t>(it - samples.begin());
  const size_t i0 = i1 - 1;
  const Sample& a = samples[i0];
  const Sample& b = samples[i1 % samples.size()];
  const double s1 = i1 < samples.size() ? b.s_m : lap_m;
  const double f = s1 > a.s_m ? (s - a.s_m) / (s1 - a.s_m) : 0.0;
  Sample out = a;
  out.position = a.position + f * (b.position - a.position);
  out.width_m = a.width_m + f * (b.width_m - a.width_m);
  out.s_m = s;
  return out;
}

// left normal of a heading
Vec2 left_normal(double heading) {
  return {-std::sin(heading), std::cos(heading)};
}

// cone spacing wanted where the centre line has this curvature
double spacing_for(double curvature, double straight_spacing_m) {
  const double k = std::abs(curvature);
  const double f = std::clamp((k - kWideCurvature) / (kTightCurvature - kWideCurvature), 0.0, 1.0);
  return straight_spacing_m +
         f * (std::min(kTightSpacingM, straight_spacing_m) - straight_spacing_m);
}

// with limit_sagitta, the spacing in a turn is also capped so that the chord between two cones
// of the outer boundary cuts into the track by no more than the width has above the rule's
// minimum (kMinSagittaAllowanceM at least): the rule checker measures the width from each cone
// to the other boundary's polyline
double spacing_at(const Sample& c, double straight_spacing_m, bool limit_sagitta) {
  double spacing = spacing_for(c.curvature, straight_spacing_m);
  if (limit_sagitta && (c.feature == Feature::kHairpin || c.feature == Feature::kHairpinLeg))
    spacing = std::min(spacing, kMinHairpinConeSpacingM);
  if (!limit_sagitta || std::abs(c.curvature) < 1e-6) return spacing;
  const double outer_radius = 1.0 / std::abs(c.curvature) + 0.5 * c.width_m;
  const double allowance =
      std::max(kMinSagittaAllowanceM, c.width_m - RuleLimits{}.min_width_m - kSagittaMarginM);
  return std::min(spacing, 2.0 * std::sqrt(2.0 * outer_radius * allowance));
}

// cone positions along one boundary (side +1 left, -1 right): the boundary is walked from the
// start line, and cones are put at equal steps of the integral of 1 / spacing so that no gap
// along the boundary exceeds the local spacing
std::vector<Vec2> place_boundary_cones(const std::vector<Sample>& samples, double start_s,
                                       double side, double straight_spacing_m, bool limit_sagitta) {
  // the boundary from the start line around the lap
  const size_t n = samples.size();
  size_t first = 0;
  while (first < n && samples[first].s_m < start_s) ++first;
  std::vector<Vec2> pts;
  std::vector<double> density;  // cumulative cones per metre of boundary
  pts.reserve(n + 1);
  density.reserve(n + 1);
  for (size_t k = 0; k <= n; ++k) {
    const Sample& c = samples[(first + k) % n];
    const Vec2 p = c.position + side * 0.5 * c.width_m * left_normal(c.heading);
    if (pts.empty()) {
      density.push_back(0.0);
    } else {
      const double step = (p - pts.back()).norm();
      density.push_back(density.back() + step / spacing_at(c, straight_spacing_m, limit_sagitta));
    }
    pts.push_back(p);
  }

  // equal steps of the cumulative density, rounded up to a whole number of cones
  const int cones = static_cast<int>(std::ceil(density.back() - 1e-9));
  const double per_cone = density.back() / cones;
  std::vector<Vec2> out;
  out.reserve(cones);
  size_t j = 0;
  for (int i = 0; i < cones; ++i) {
    const double target = i * per_cone;
    while (j + 1 < density.size() && density[j + 1] < target) ++j;
    const double span = density[j + 1] - density[j];
    const double f = span > 0.0 ? std::clamp((target - density[j]) / span, 0.0, 1.0) : 0.0;
    out.push_back(pts[j] + f * (pts[j + 1] - pts[j]));
  }
  return out;
}

// the Track of a lap: cones, lanes, start zone and the designed centre line
Track build_track(const std::vector<Sample>& samples, double lap_m, uint64_t seed,
                  const GeneratorParams& params, const ProfileSettings& settings) {
  Track track;
  track.name =
      params.profile == GeneratorProfile::kStandard
          ? "generated-" + std::to_string(seed)
          : "generated-" + std::string(to_string(params.profile)) + "-" + std::to_string(seed);
  track.closed = true;
  track.event = params.event;
  track.start = Pose2{0.0, 0.0, 0.0};

  // boundary cones, blue on the left and yellow on the right, in driving order from the line
  for (const double side : {1.0, -1.0}) {
    const ConeClass cls = side > 0.0 ? ConeClass::kBlue : ConeClass::kYellow;
    std::vector<int>& lane = side > 0.0 ? track.left_lane : track.right_lane;
    for (const Vec2& p : place_boundary_cones(samples, kStartLineM, side, params.cone_spacing_m,
                                              settings.limit_sagitta)) {
      const int id = static_cast<int>(track.cones.size());
      track.cones.push_back({id, cls, p, std::nullopt});
      lane.push_back(id);
    }
  }

  // big orange cones either side of the start line, just outside the boundaries
  for (const double along : {-kBigConeHalfGapM, kBigConeHalfGapM}) {
    const Sample c = sample_at(samples, lap_m, kStartLineM + along);
    for (const double side : {1.0, -1.0}) {
      const Vec2 p =
          c.position + side * (0.5 * c.width_m + kBigConeOutsideM) * left_normal(c.heading);
      track.cones.push_back(
          {static_cast<int>(track.cones.size()), ConeClass::kOrangeBig, p, std::nullopt});
    }
  }

  // the time-keeping gate on the start line
  const Sample line = sample_at(samples, lap_m, kStartLineM);
  const Vec2 post = (0.5 * line.width_m + kGatePostOutsideM) * left_normal(line.heading);
  track.timing_gates.push_back({line.position + post, line.position - post});

  // the designed centre line every ~1 m from the start line
  const int points = std::max(3, static_cast<int>(std::round(lap_m)));
  track.centre_line.reserve(points);
  for (int i = 0; i < points; ++i)
    track.centre_line.push_back(
        sample_at(samples, lap_m, kStartLineM + i * lap_m / points).position);
  return track;
}

// true when the lanes rebuilt from the cone colours and the start pose, as a reader of a format
// without lanes (EUFS CSV) rebuilds them, are the designed ones
bool lanes_survive_reading(const Track& track) {
  Track copy = track;
  copy.left_lane.clear();
  copy.right_lane.clear();
  rebuild_lanes(copy);
  // the same cones in the same cyclic order (the rebuilt lanes begin near the start pose)
  const auto same_loop = [](const std::vector<int>& a, const std::vector<int>& b) {
    if (a.size() != b.size() || a.empty()) return false;
    const auto first = std::find(a.begin(), a.end(), b.front());
    if (first == a.end()) return false;
    std::vector<int> rotated(first, a.end());
    rotated.insert(rotated.end(), a.begin(), first);
    return rotated == b;
  };
  return copy.closed && same_loop(copy.left_lane, track.left_lane) &&
         same_loop(copy.right_lane, track.right_lane);
}

// counts the primitives of a lap into the report
void count_features(const std::vector<Piece>& lap, GenerationReport& report) {
  int chicane_arcs = 0;
  for (size_t i = 0; i < lap.size(); ++i) {
    const Piece& p = lap[i];
    if (p.feature == Feature::kHairpin) ++report.hairpins;
    if (p.feature == Feature::kSweeper) ++report.sweepers;
    if (p.feature == Feature::kCorner) ++report.corners;
    if (p.feature == Feature::kChicane && p.curvature != 0.0) ++chicane_arcs;
    if (p.feature == Feature::kSlalom && (i == 0 || lap[i - 1].feature != Feature::kSlalom))
      ++report.slaloms;
  }
  report.chicanes = chicane_arcs / 2;

  // direction of travel, the tightest hairpin's outside diameter, the longest straight
  double turned = 0.0;
  report.min_hairpin_outer_diameter_m = 0.0;
  for (const Piece& p : lap) {
    turned += heading_change(p, p.length_m);
    if (p.feature != Feature::kHairpin) continue;
    const double d = 2.0 / std::abs(p.curvature) + p.width_m;
    if (report.min_hairpin_outer_diameter_m == 0.0 || d < report.min_hairpin_outer_diameter_m)
      report.min_hairpin_outer_diameter_m = d;
  }
  report.clockwise = turned < 0.0;
  report.longest_straight_m = longest_straight(lap);
}

// checks the parameters; throws std::invalid_argument on a layout the rules cannot allow
void validate(const GeneratorParams& params) {
  const RuleLimits limits;
  std::string error;
  if (params.width_m < limits.min_width_m) error = "width_m below the 3 m minimum";
  if (params.cone_spacing_m <= 0.0 || params.cone_spacing_m > limits.max_cone_spacing_m)
    error = "cone_spacing_m must be in (0, 5] m";
  if (params.max_lap_m - params.min_lap_m < 150.0 || params.min_lap_m < 100.0)
    error = "lap range must span at least 150 m from at least 100 m";
  if (params.event != EventType::kAutocross && params.event != EventType::kTrackdrive)
    error = "the generator makes autocross and trackdrive circuits only";
  if (params.max_attempts < 1) error = "max_attempts must be at least 1";
  if (!(params.hairpin_outer_diameter_m >= limits.min_hairpin_outer_diameter_m + 0.2 - 1e-9 &&
        params.hairpin_outer_diameter_m <= 20.0))
    error = "hairpin_outer_diameter_m must be in [9.2, 20] m";
  if (!error.empty()) throw std::invalid_argument("generate_circuit: " + error);
}

}  // namespace

std::string_view to_string(GeneratorProfile profile) {
  switch (profile) {
    case GeneratorProfile::kStandard:
      return "standard";
    case GeneratorProfile::kHairpins:
      return "hairpins";
    case GeneratorProfile::kSlalom:
      return "slalom";
    case GeneratorProfile::kChicanes:
      return "chicanes";
    case GeneratorProfile::kNarrow:
      return "narrow";
    case GeneratorProfile::kStraightIntoHairpin:
      return "straight-into-hairpin";
    case GeneratorProfile::kHard:
      return "hard";
  }
  return "standard";
}

std::optional<GeneratorProfile> profile_from_string(std::string_view name) {
  if (name == "mixed") return GeneratorProfile::kHard;
  for (GeneratorProfile p : all_profiles())
    if (to_string(p) == name) return p;
  return std::nullopt;
}

std::vector<GeneratorProfile> all_profiles() {
  return {GeneratorProfile::kStandard, GeneratorProfile::kHairpins,
          GeneratorProfile::kSlalom,   GeneratorProfile::kChicanes,
          GeneratorProfile::kNarrow,   GeneratorProfile::kStraightIntoHairpin,
          GeneratorProfile::kHard};
}

Track generate_circuit(uint64_t seed, const GeneratorParams& params) {
  return generate_circuit(seed, params, nullptr);
}

Track generate_circuit(uint64_t seed, const GeneratorParams& params, GenerationReport* report) {
  validate(params);
  const ProfileSettings settings = settings_of(params.profile);
  GenerationReport local;
  GenerationReport& r = report ? *report : local;
  r = {};
  for (int attempt = 0; attempt < params.max_attempts; ++attempt) {
    ++r.attempts;
    Rng rng(core::derive_seed(seed, static_cast<uint64_t>(attempt)));

    // draw the open part, close it, and sample the lap
    LayoutDrawer drawer(rng, params, settings);
    std::optional<std::vector<Piece>> open = drawer.draw_open_part();
    std::optional<std::vector<Piece>> lap;
    if (open) lap = close_loop(drawer, std::move(*open), params, settings);
    if (!lap) {
      ++r.rejected_geometry;
      continue;
    }
    const std::vector<Sample> samples = sample_lap(*lap);
    double lap_m = 0.0;
    for (const Piece& p : *lap) lap_m += p.length_m;

    // cones and the rest, then the rule checker as the final gate
    Track track = build_track(samples, lap_m, seed, params, settings);
    if (!is_compliant(check_rules(track, params.event)) ||
        (params.profile != GeneratorProfile::kStandard && !lanes_survive_reading(track))) {
      ++r.rejected_rules;
      continue;
    }
    count_features(*lap, r);
    r.lap_m = lap_m;
    return track;
  }
  throw std::runtime_error("generate_circuit: no compliant layout for seed " +
                           std::to_string(seed) + " in " + std::to_string(params.max_attempts) +
                           " attempts");
}

}  // namespace conesim::tracks
