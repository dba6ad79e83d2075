#include "core/assignment.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

namespace conesim::core {

namespace {

// a pair may be assigned when its cost is a finite number within the cut-off
bool allowed(double c, double cutoff) {
  return std::isfinite(c) && c <= cutoff;
}

// dense Hungarian (shortest augmenting paths with potentials) for rows <= cols; every entry
// finite. Returns for each row its column.
std::vector<int> hungarian_dense(const Eigen::MatrixXd& a) {
  const int n = static_cast<int>(a.rows()), m = static_cast<int>(a.cols());
  const double inf = std::numeric_limits<double>::infinity();
  // 1-based: column 0 is the virtual start of each augmenting path
  std::vector<double> u(n + 1, 0.0), v(m + 1, 0.0);
  std::vector<int> p(m + 1, 0), way(m + 1, 0);
  for (int i = 1; i <= n; ++i) {
    // grow a shortest-path tree from row i until it reaches a free column
    p[0] = i;
    int j0 = 0;
    std::vector<double> minv(m + 1, inf);
    std::vector<char> used(m + 1, 0);
    do {
      used[j0] = 1;
      const int i0 = p[j0];
      double delta = inf;
      int j1 = 0;
      for (int j = 1; j <= m; ++j) {
        if (used[j]) continue;
        const double cur = a(i0 - 1, j - 1) - u[i0] - v[j];
        if (cur < minv[j]) minv[j] = cur, way[j] = j0;
        if (minv[j] < delta) delta = minv[j], j1 = j;
      }
      for (int j = 0; j <= m; ++j) {
        if (used[j]) {
          u[p[j]] += delta;
          v[j] -= delta;
        } else {
          minv[j] -= delta;
        }
      }
      j0 = j1;
    } while (p[j0] != 0);
    // flip the path
    do {
      const int j1 = way[j0];
      p[j0] = p[j1];
      j0 = j1;
    } while (j0 != 0);
  }
  std::vector<int> row_to_col(n, -1);
  for (int j = 1; j <= m; ++j)
    if (p[j] > 0) row_to_col[p[j] - 1] = j - 1;
  return row_to_col;
}

int find_root(std::vector<int>& parent, int x) {
  while (parent[x] != x) x = parent[x] = parent[parent[x]];
  return x;
}

}  // namespace

std::vector<int> hungarian_assign(const Eigen::MatrixXd& cost, double cutoff) {
  const int n = static_cast<int>(cost.rows()), m = static_cast<int>(cost.cols());
  std::vector<int> assignment(n, -1);

  // group rows and columns linked by allowed pairs (columns are nodes n..n+m-1): groups are
  // independent problems
  std::vector<int> parent(n + m);
  std::iota(parent.begin(), parent.end(), 0);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j)
      if (allowed(cost(i, j), cutoff)) parent[find_root(parent, i)] = find_root(parent, n + j);
  // each group's rows and columns in increasing order, packed by group (no allocation per
  // group: most rows and columns of a frame stand alone)
  std::vector<int> root(n + m), first(n + m + 1, 0), members(n + m);
  for (int k = 0; k < n + m; ++k) ++first[(root[k] = find_root(parent, k)) + 1];
  for (int g = 0; g < n + m; ++g) first[g + 1] += first[g];
  std::vector<int> next = first;
  for (int k = 0; k < n + m; ++k) members[next[root[k]]++] = k;
  std::vector<int> rows, cols;

  for (int g = 0; g < n + m; ++g) {
    // a group of one is a row or a column without an allowed pair
    if (first[g + 1] - first[g] < 2) continue;
    rows.clear();
    cols.clear();
    for (int k = first[g]; k < first[g + 1]; ++k)
      (members[k] < n ? rows : cols).push_back(members[k] < n ? members[k] : members[k] - n);
    if (rows.empty() || cols.empty()) continue;
    // forbidden pairs cost more than any set of allowed ones, so the optimum pairs as many
    // rows as it can within the cut-off first and minimises the cost second
    double max_abs = 0.0;
    for (int i : rows)
      for (int j : cols)
        if (allowed(cost(i, j), cutoff)) max_abs = std::max(max_abs, std::abs(cost(i, j)));
    const double k = static_cast<double>(std::min(rows.size(), cols.size()));
    const double forbidden = 2.0 * (k + 1.0) * (max_abs + 1.0);
    const bool transpose = rows.size() > cols.size();
    const auto& r = transpose ? cols : rows;
    const auto& c = transpose ? rows : cols;
    Eigen::MatrixXd sub(r.size(), c.size());
    for (size_t a = 0; a < r.size(); ++a)
      for (size_t b = 0; b < c.size(); ++b) {
        const double x = transpose ? cost(c[b], r[a]) : cost(r[a], c[b]);
        sub(a, b) = allowed(x, cutoff) ? x : forbidden;
      }
    // solve, keep only the allowed pairs
    const std::vector<int> sub_assignment = hungarian_dense(sub);
    for (size_t a = 0; a < r.size(); ++a) {
      if (sub_assignment[a] < 0) continue;
      const int row = transpose ? c[sub_assignment[a]] : r[a];
      const int col = transpose ? r[a] : c[sub_assignment[a]];
      if (allowed(cost(row, col), cutoff)) assignment[row] = col;
    }
  }
  return assignment;
}

}  // namespace conesim::core
