#pragma once
// Numerical derivatives for the Jacobian tests of the SLAM back-ends.

#include <Eigen/Core>

namespace conesim::slam::testing {

/// Central differences of f (R^In -> R^Out) at x.
template <int In, int Out, typename F>
Eigen::Matrix<double, Out, In> numerical(const F& f, const Eigen::Matrix<double, In, 1>& x) {
  Eigen::Matrix<double, Out, In> j;
  const double h = 1e-6;
  for (int c = 0; c < In; ++c) {
    Eigen::Matrix<double, In, 1> a = x, b = x;
    a(c) += h;
    b(c) -= h;
    j.col(c) = (f(a) - f(b)) / (2 * h);
  }
  return j;
}

}  // namespace conesim::slam::testing
