// stats::levenbergMarquardt on problems with known minima: analytic and numerical Jacobians,
// an admissibility bound, and the convergence flags.
#include "libwheelchair/stats/LevenbergMarquardt.h"

#include <gtest/gtest.h>

#include <cmath>

namespace wheelchair::stats {
namespace {

// Rosenbrock as least squares: r = (1 - x, 10 (y - x^2)); minimum 0 at (1, 1).
void rosenbrock(const Eigen::VectorXd& x, Eigen::VectorXd& r, Eigen::MatrixXd* J) {
  r = Eigen::Vector2d(1 - x(0), 10 * (x(1) - x(0) * x(0)));
  if (J) {
    J->resize(2, 2);
    *J << -1, 0, -20 * x(0), 10;
  }
}

TEST(LevenbergMarquardt, RosenbrockFromTheClassicStartWithAnalyticJacobian) {
  LmOptions o;
  o.max_iterations = 500;
  o.min_step_norm = 1e-12;
  const LmResult s = levenbergMarquardt(rosenbrock, Eigen::Vector2d(-1.2, 1.0), o);
  EXPECT_TRUE(s.converged);
  EXPECT_NEAR(s.x(0), 1.0, 1e-8);
  EXPECT_NEAR(s.x(1), 1.0, 1e-8);
  EXPECT_LT(s.cost, 1e-16);
  EXPECT_GT(s.iterations, 1);
}

TEST(LevenbergMarquardt, ExponentialDecayWithNumericalJacobianRecoversTheParameters) {
  // y = a exp(-b t) sampled without noise at a = 2.5, b = 0.7.
  Eigen::VectorXd t = Eigen::VectorXd::LinSpaced(40, 0.0, 6.0);
  const Eigen::VectorXd y = (2.5 * (-0.7 * t.array()).exp()).matrix();
  auto f = [&](const Eigen::VectorXd& x, Eigen::VectorXd& r, Eigen::MatrixXd*) {
    r = (x(0) * (-x(1) * t.array()).exp()).matrix() - y;  // J left empty: numerical
  };
  LmOptions o;
  o.min_relative_decrease = 1e-14;
  const LmResult s = levenbergMarquardt(f, Eigen::Vector2d(1.0, 0.1), o);
  EXPECT_NEAR(s.x(0), 2.5, 1e-5);
  EXPECT_NEAR(s.x(1), 0.7, 1e-5);
  EXPECT_NEAR(s.r.squaredNorm(), s.cost, 1e-15);
}

TEST(LevenbergMarquardt, InadmissibleTrialPointsAreNeverEvaluated) {
  // Minimum of (x - 3)^2 at 3, but only x <= 2 is admissible: the fit stops at the bound.
  int outside = 0;
  auto f = [&](const Eigen::VectorXd& x, Eigen::VectorXd& r, Eigen::MatrixXd* J) {
    if (x(0) > 2.0 && !J) ++outside;
    r = Eigen::VectorXd::Constant(1, x(0) - 3.0);
    if (J) *J = Eigen::MatrixXd::Constant(1, 1, 1.0);
  };
  auto admissible = [](const Eigen::VectorXd& x) { return x(0) <= 2.0; };
  const LmResult s = levenbergMarquardt(f, Eigen::VectorXd::Zero(1), {}, admissible);
  EXPECT_EQ(outside, 0);
  EXPECT_LE(s.x(0), 2.0);
  EXPECT_GT(s.x(0), 1.9);
  EXPECT_TRUE(s.converged);  // stopped because no admissible try lowered the cost
}

TEST(LevenbergMarquardt, AtTheMinimumNoStepIsAcceptedAndTheStartIsReturned) {
  const LmResult s = levenbergMarquardt(rosenbrock, Eigen::Vector2d(1.0, 1.0));
  EXPECT_TRUE(s.converged);
  EXPECT_EQ(s.iterations, 1);
  EXPECT_EQ(s.x, Eigen::Vector2d(1.0, 1.0));
  EXPECT_EQ(s.cost, 0.0);
}

}  // namespace
}  // namespace wheelchair::stats
