#include "slam/association/methods.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

#include "core/measurements.hpp"

namespace conesim::slam {

namespace {

struct Named {
  AssociationMethod method;
  std::string_view name;
};
constexpr Named kNames[] = {
    {AssociationMethod::kNearestNeighbour, "nn"},
    {AssociationMethod::kMaximumLikelihood, "ml"},
    {AssociationMethod::kScnn, "scnn"},
    {AssociationMethod::kJcbb, "jcbb"},
    {AssociationMethod::kTrackingAided, "tracking"},
    {AssociationMethod::kIdeal, "ideal"},
    {AssociationMethod::kNone, "none"},
};

// a pairing that passed the individual gate
struct Pairing {
  int observation = 0;
  int candidate = 0;
  double d2 = 0.0;
  double cost = 0.0;
};

// every individually compatible, allowed pairing
std::vector<Pairing> compatible_pairings(const AssociationProblem& p, double gate_chi2) {
  std::vector<Pairing> out;
  for (int i = 0; i < p.observations(); ++i) {
    for (int j = 0; j < p.candidates(); ++j) {
      if (!p.allowed(i, j)) continue;
      const Eigen::Vector2d v = p.innovation(i, j);
      const Eigen::Matrix2d s = p.innovation_covariance(i, j, i, j);
      const double d2 = v.dot(s.ldlt().solve(v));
      if (!(d2 < gate_chi2)) continue;
      out.push_back({i, j, d2, d2 + std::log(s.determinant())});
    }
  }
  return out;
}

// greedy with mutual exclusion over pairings in the given order
void greedy(const std::vector<Pairing>& ordered, std::vector<int>& pairing_of,
            std::vector<char>& taken) {
  for (const Pairing& p : ordered) {
    if (pairing_of[p.observation] >= 0 || taken[p.candidate]) continue;
    pairing_of[p.observation] = p.candidate;
    taken[p.candidate] = 1;
  }
}

// The joint test kept incrementally: the Cholesky factor L of the joint innovation covariance
// of the pairings so far and y = L^-1 nu, so that the joint distance is |y|^2 and adding one
// pairing costs O(k^2) (a block of the factor and two triangular solves).
struct JointState {
  std::vector<std::pair<int, int>> pairs;
  Eigen::MatrixXd l;
  Eigen::VectorXd y;
  double d2 = 0.0;

  // the state with (i, j) added, or nullopt when the joint covariance is not positive definite
  std::optional<JointState> with(const AssociationProblem& p, int i, int j) const {
    const int k = static_cast<int>(pairs.size());
    Eigen::MatrixXd b(2 * k, 2);
    for (int a = 0; a < k; ++a)
      b.block<2, 2>(2 * a, 0) = p.innovation_covariance(pairs[a].first, pairs[a].second, i, j);
    const Eigen::Matrix2d c = p.innovation_covariance(i, j, i, j);
    const Eigen::Vector2d v = p.innovation(i, j);
    Eigen::MatrixXd x = b;
    if (k > 0) l.triangularView<Eigen::Lower>().solveInPlace(x);
    const Eigen::Matrix2d schur = c - x.transpose() * x;
    const Eigen::LLT<Eigen::Matrix2d> llt(schur);
    if (llt.info() != Eigen::Success) return std::nullopt;
    const Eigen::Matrix2d l22 = llt.matrixL();
    Eigen::Vector2d rhs =
        v - (k > 0 ? Eigen::Vector2d(x.transpose() * y) : Eigen::Vector2d::Zero());
    const Eigen::Vector2d y2 = l22.triangularView<Eigen::Lower>().solve(rhs);
    JointState next;
    next.pairs = pairs;
    next.pairs.emplace_back(i, j);
    next.l = Eigen::MatrixXd::Zero(2 * k + 2, 2 * k + 2);
    if (k > 0) {
      next.l.topLeftCorner(2 * k, 2 * k) = l;
      next.l.bottomLeftCorner(2, 2 * k) = x.transpose();
    }
    next.l.bottomRightCorner<2, 2>() = l22;
    next.y.resize(2 * k + 2);
    if (k > 0) next.y.head(2 * k) = y;
    next.y.tail<2>() = y2;
    next.d2 = d2 + y2.squaredNorm();
    return next;
  }
};

// the joint gate for 2k degrees of freedom, k = 0..n
std::vector<double> joint_gates(double probability, int n) {
  std::vector<double> gates(n + 1, 0.0);
  for (int k = 1; k <= n; ++k) gates[k] = chi2_quantile(probability, 2 * k);
  return gates;
}

struct Jcbb {
  const AssociationProblem& p;
  const AssociationParams& params;
  std::vector<double> gates;
  // the individually compatible candidates of each observation, likeliest first
  std::vector<std::vector<Pairing>> options;
  std::vector<char> used;
  JointState best;
  int nodes = 0;

  bool jointly_compatible(const JointState& s) const { return s.d2 < gates[s.pairs.size()]; }

  void search(int i, const JointState& h) {
    if (++nodes > params.jcbb_max_nodes) return;
    const int n = static_cast<int>(options.size());
    if (i == n) {
      if (h.pairs.size() > best.pairs.size() ||
          (h.pairs.size() == best.pairs.size() && h.d2 < best.d2))
        best = h;
      return;
    }
    for (const Pairing& o : options[i]) {
      if (used[o.candidate]) continue;
      const std::optional<JointState> next = h.with(p, o.observation, o.candidate);
      if (!next || !jointly_compatible(*next)) continue;
      used[o.candidate] = 1;
      search(i + 1, *next);
      used[o.candidate] = 0;
    }
    // leave observation i unpaired while that can still beat the best
    if (h.pairs.size() + (n - i - 1) >= best.pairs.size()) search(i + 1, h);
  }
};

}  // namespace

std::string_view to_string(AssociationMethod method) {
  for (const Named& n : kNames)
    if (n.method == method) return n.name;
  return "?";
}

std::optional<AssociationMethod> association_from_string(std::string_view name) {
  for (const Named& n : kNames)
    if (n.name == name) return n.method;
  return std::nullopt;
}

std::string association_names() {
  std::string out;
  for (const Named& n : kNames) out += (out.empty() ? "" : ", ") + std::string(n.name);
  return out;
}

double chi2_quantile(double p, int dof) {
  // the standard normal quantile z of p by bisection on the normal distribution function,
  // then Wilson-Hilferty: (X/k)^(1/3) is nearly normal with mean 1 - 2/(9k), variance 2/(9k)
  double lo = -10.0, hi = 10.0;
  for (int it = 0; it < 80; ++it) {
    const double mid = 0.5 * (lo + hi);
    (0.5 * std::erfc(-mid / std::sqrt(2.0)) < p ? lo : hi) = mid;
  }
  const double z = 0.5 * (lo + hi);
  const double k = dof;
  const double a = 2.0 / (9.0 * k);
  const double base = 1.0 - a + z * std::sqrt(a);
  return k * base * base * base;
}

double joint_mahalanobis2(const AssociationProblem& problem,
                          const std::vector<std::pair<int, int>>& pairings) {
  const int k = static_cast<int>(pairings.size());
  if (k == 0) return 0.0;
  Eigen::MatrixXd s(2 * k, 2 * k);
  Eigen::VectorXd v(2 * k);
  for (int a = 0; a < k; ++a) {
    v.segment<2>(2 * a) = problem.innovation(pairings[a].first, pairings[a].second);
    for (int b = 0; b < k; ++b)
      s.block<2, 2>(2 * a, 2 * b) = problem.innovation_covariance(
          pairings[a].first, pairings[a].second, pairings[b].first, pairings[b].second);
  }
  return v.dot(s.ldlt().solve(v));
}

std::vector<int> associate(const AssociationParams& params, const AssociationProblem& p,
                           const TrackBindings* tracks, std::vector<int>* evidence) {
  const int n = p.observations();
  std::vector<int> pairing_of(n, -1);
  std::vector<char> taken(p.candidates(), 0);
  const auto by_cost = [](const Pairing& a, const Pairing& b) {
    return a.cost < b.cost ||
           (a.cost == b.cost && (a.observation < b.observation ||
                                 (a.observation == b.observation && a.candidate < b.candidate)));
  };

  switch (params.method) {
    case AssociationMethod::kNone:
      // every observation unpaired: each starts a landmark
      return pairing_of;
    case AssociationMethod::kNearestNeighbour: {
      std::vector<Pairing> near;
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < p.candidates(); ++j) {
          if (!p.allowed(i, j)) continue;
          const double d = (p.observation_in_map(i) - p.candidate_position(j)).norm();
          if (d < params.nn_radius_m) near.push_back({i, j, d, d});
        }
      std::sort(near.begin(), near.end(), by_cost);
      greedy(near, pairing_of, taken);
      return pairing_of;
    }
    case AssociationMethod::kIdeal: {
      // the landmark of the observation's true cone (or off-track cone), when one is in reach
      for (int i = 0; i < n; ++i) {
        const int label = p.observation_label(i);
        if (label < 0 && !core::ObservationLabels::is_off_track_cone(label)) continue;
        for (int j = 0; j < p.candidates(); ++j) {
          if (taken[j] || p.candidate_label(j) != label) continue;
          pairing_of[i] = j;
          taken[j] = 1;
          break;
        }
      }
      return pairing_of;
    }
    case AssociationMethod::kMaximumLikelihood: {
      std::vector<Pairing> ic = compatible_pairings(p, params.gate_chi2);
      std::sort(ic.begin(), ic.end(), by_cost);
      greedy(ic, pairing_of, taken);
      return pairing_of;
    }
    case AssociationMethod::kTrackingAided: {
      // the frame's own evidence: maximum likelihood without the tracks
      std::vector<Pairing> ic = compatible_pairings(p, params.gate_chi2);
      std::sort(ic.begin(), ic.end(), by_cost);
      if (evidence) {
        evidence->assign(n, -1);
        std::vector<char> evidence_taken(p.candidates(), 0);
        greedy(ic, *evidence, evidence_taken);
      }
      // then the same with each pairing's cost less its track's prior
      if (tracks) {
        for (Pairing& q : ic)
          q.cost -=
              tracks->bonus(p.observation_track(q.observation), p.candidate_landmark(q.candidate));
        std::sort(ic.begin(), ic.end(), by_cost);
      }
      greedy(ic, pairing_of, taken);
      if (tracks) {
        // an ambiguous observation of a track waits for a later frame; the landmark it held goes
        // back to the others
        std::vector<char> waits = ambiguous_observations(ic, pairing_of, params.ambiguity_margin);
        for (int i = 0; i < n; ++i)
          if (p.observation_track(i) < 0) waits[i] = 0;
        if (std::find(waits.begin(), waits.end(), 1) != waits.end()) {
          std::erase_if(ic, [&](const Pairing& q) { return waits[q.observation] != 0; });
          std::fill(pairing_of.begin(), pairing_of.end(), -1);
          std::fill(taken.begin(), taken.end(), 0);
          greedy(ic, pairing_of, taken);
        }
      }
      return pairing_of;
    }
    case AssociationMethod::kScnn: {
      // observation by observation, the likeliest candidate that keeps the set compatible
      std::vector<Pairing> ic = compatible_pairings(p, params.gate_chi2);
      std::sort(ic.begin(), ic.end(), by_cost);
      const std::vector<double> gates = joint_gates(params.joint_probability, n);
      JointState h;
      for (int i = 0; i < n; ++i) {
        for (const Pairing& q : ic) {
          if (q.observation != i || taken[q.candidate]) continue;
          const std::optional<JointState> next = h.with(p, q.observation, q.candidate);
          if (!next || !(next->d2 < gates[next->pairs.size()])) continue;
          h = *next;
          pairing_of[i] = q.candidate;
          taken[q.candidate] = 1;
          break;
        }
      }
      return pairing_of;
    }
    case AssociationMethod::kJcbb: {
      std::vector<Pairing> ic = compatible_pairings(p, params.gate_chi2);
      std::sort(ic.begin(), ic.end(), by_cost);
      Jcbb search{p,
                  params,
                  joint_gates(params.joint_probability, n),
                  std::vector<std::vector<Pairing>>(n),
                  std::vector<char>(p.candidates(), 0),
                  {},
                  0};
      for (const Pairing& q : ic) search.options[q.observation].push_back(q);
      // observations with fewer options first: the tree's upper levels branch least
      std::vector<int> order(n);
      for (int i = 0; i < n; ++i) order[i] = i;
      std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
        const size_t na = search.options[a].size(), nb = search.options[b].size();
        if ((na == 0) != (nb == 0)) return na > nb;  // the unpaired ones last
        return na < nb;
      });
      std::vector<std::vector<Pairing>> ordered;
      for (int i : order)
        if (!search.options[i].empty()) ordered.push_back(search.options[i]);
      search.options = std::move(ordered);
      search.search(0, JointState{});
      for (const auto& [i, j] : search.best.pairs) pairing_of[i] = j;
      return pairing_of;
    }
  }
  return pairing_of;
}

}  // namespace conesim::slam
