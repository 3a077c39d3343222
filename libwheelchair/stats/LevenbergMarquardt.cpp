#include "libwheelchair/stats/LevenbergMarquardt.h"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>

namespace wheelchair::stats {
namespace {

// r and J at x; J by forward differences when the residual function leaves it empty.
void residualsAndJacobian(const LmResiduals& f, const Eigen::VectorXd& x, double h,
                          Eigen::VectorXd& r, Eigen::MatrixXd& J) {
  J.resize(0, 0);
  f(x, r, &J);
  if (J.size() != 0) return;
  J.resize(r.size(), x.size());
  Eigen::VectorXd rh;
  for (Eigen::Index j = 0; j < x.size(); ++j) {
    Eigen::VectorXd xh = x;
    xh(j) += h;
    f(xh, rh, nullptr);
    J.col(j) = (rh - r) / h;
  }
}

}  // namespace

LmResult levenbergMarquardt(const LmResiduals& f, const Eigen::VectorXd& x0, const LmOptions& o,
                            const LmAdmissible& admissible) {
  LmResult res;
  res.x = x0;
  Eigen::MatrixXd J;
  residualsAndJacobian(f, res.x, o.difference_step, res.r, J);
  res.cost = res.r.squaredNorm();
  double lambda = o.lambda0;
  for (int it = 0; it < o.max_iterations; ++it) {
    res.iterations = it + 1;
    if (it > 0) residualsAndJacobian(f, res.x, o.difference_step, res.r, J);
    const Eigen::MatrixXd JtJ = J.transpose() * J;
    const Eigen::VectorXd Jtr = J.transpose() * res.r;
    bool improved = false, small_decrease = false;
    Eigen::VectorXd step = Eigen::VectorXd::Zero(res.x.size());
    for (int k = 0; k < o.max_tries && !improved; ++k) {
      Eigen::MatrixXd M = JtJ;
      M.diagonal() += lambda * JtJ.diagonal().cwiseMax(o.min_diagonal);
      step = M.ldlt().solve(-Jtr);
      const Eigen::VectorXd x_new = res.x + step;
      if (admissible && !admissible(x_new)) {
        lambda *= o.lambda_up;
        continue;
      }
      Eigen::VectorXd r_new;
      f(x_new, r_new, nullptr);
      const double c_new = r_new.squaredNorm();
      if (std::isfinite(c_new) && c_new < res.cost) {
        small_decrease = (res.cost - c_new) / std::max(1e-300, res.cost) < o.min_relative_decrease;
        res.x = x_new, res.r = r_new, res.cost = c_new;
        lambda = std::max(o.lambda_min, lambda * o.lambda_down);
        improved = true;
      } else {
        lambda *= o.lambda_up;
      }
    }
    if (!improved || small_decrease || step.norm() < o.min_step_norm) {
      res.converged = true;
      break;
    }
  }
  return res;
}

}  // namespace wheelchair::stats
