// Central numerical differentiation for the model tests.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>

namespace wheelchair::model::testing {

/// d fn / d x at x by central differences, fn: Eigen vector (N) -> Eigen vector (M).
template <int M, int N, typename Fn>
Eigen::Matrix<double, M, N> numericJacobian(Fn fn, const Eigen::Matrix<double, N, 1>& x) {
  Eigen::Matrix<double, M, N> J;
  for (int k = 0; k < N; ++k) {
    const double h = 1e-6 * std::max(1.0, std::abs(x(k)));
    Eigen::Matrix<double, N, 1> xp = x, xm = x;
    xp(k) += h;
    xm(k) -= h;
    const Eigen::Matrix<double, M, 1> fp = fn(xp), fm = fn(xm);
    J.col(k) = (fp - fm) / (xp(k) - xm(k));
  }
  return J;
}

/// Relative difference of two Jacobians, scaled by the larger norm (at least 1).
template <typename A, typename B>
double relativeError(const A& analytic, const B& numeric) {
  const double scale = std::max({1.0, analytic.norm(), numeric.norm()});
  return (analytic - numeric).norm() / scale;
}

}  // namespace wheelchair::model::testing
