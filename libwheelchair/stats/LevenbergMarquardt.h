// Levenberg-Marquardt for small nonlinear least-squares problems: minimise
//   C(x) = |r(x)|^2,  r: R^p -> R^n,
// by the damped Gauss-Newton step
//   (J'J + lambda diag(max(J'J, min_diagonal))) dx = -J'r,   J = dr/dx at x,
// (Marquardt's scaling: each parameter damped in its own units). A step is taken only when it
// lowers C; then lambda *= lambda_down (at least lambda_min), else lambda *= lambda_up and
// the step is solved again, at most max_tries times per iteration. The iteration stops when
// no try lowers C, when an accepted step is shorter than min_step_norm, or when C drops by
// less than min_relative_decrease of itself; each of these counts as converged.
//
// An optional `admissible(x)` test rejects trial points (e.g. outside the physical range)
// before r is evaluated there; a rejected point counts as a failed try. J comes from the
// residual function when it fills it, otherwise from forward differences with step
// `difference_step` in each coordinate.
//
// Used by sensors::fitZenerSoftKnee (analytic J) and identification::trajectoryCalibration
// (numerical J, bounded parameters).
//
// Example (fit y = a exp(-b t)):
//   auto f = [&](const Eigen::VectorXd& x, Eigen::VectorXd& r, Eigen::MatrixXd* J) {
//     r = (x(0) * (-x(1) * t.array()).exp()).matrix() - y;  // J left empty: numerical
//   };
//   LmResult fit = levenbergMarquardt(f, Eigen::Vector2d(1, 1));   // fit.x = (a, b)
#pragma once

#include <Eigen/Core>

#include <functional>

namespace wheelchair::stats {

/// r(x) into `r`; if `J` is not null the function may fill it with dr/dx (n x p) or leave it
/// empty (size 0) for forward differences.
using LmResiduals =
    std::function<void(const Eigen::VectorXd& x, Eigen::VectorXd& r, Eigen::MatrixXd* J)>;
/// Whether a trial point may be evaluated (empty: every point).
using LmAdmissible = std::function<bool(const Eigen::VectorXd& x)>;

struct LmOptions {
  int max_iterations = 100;
  int max_tries = 10;                ///< damping increases per iteration before it stops
  double lambda0 = 1e-3;             ///< initial damping (relative to diag(J'J))
  double lambda_up = 10;             ///< factor after a failed try
  double lambda_down = 0.1;          ///< factor after an accepted step
  double lambda_min = 1e-9;          ///< floor of the damping after accepted steps
  double min_diagonal = 1e-12;       ///< floor of diag(J'J) in the damping term
  double min_step_norm = 0;          ///< converged when an accepted |dx| is below this
  double min_relative_decrease = 0;  ///< converged when (C - C_new) / C is below this
  double difference_step = 1e-6;     ///< forward-difference step when J is numerical
};

struct LmResult {
  Eigen::VectorXd x;  ///< the last accepted point (x0 if no step was accepted)
  Eigen::VectorXd r;  ///< the residuals at x
  double cost = 0;    ///< |r|^2
  int iterations = 0;
  bool converged = false;
};

/// Minimises |r(x)|^2 from x0 (x0 itself is not tested for admissibility).
LmResult levenbergMarquardt(const LmResiduals& residuals, const Eigen::VectorXd& x0,
                            const LmOptions& options = {}, const LmAdmissible& admissible = {});

}  // namespace wheelchair::stats
