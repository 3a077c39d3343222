// The numerics of stats/LeastSquares.h: rank detection on a structurally rank-deficient
// regressor, estimability of linear functionals, HAC standard errors that cover the truth
// under strongly autocorrelated residuals where the iid ones do not, and the sandwich itself
// against an independent closed-form computation.
#include "libwheelchair/stats/LeastSquares.h"

#include <Eigen/Dense>

#include <gtest/gtest.h>

#include <cmath>
#include <random>

using namespace wheelchair;
using stats::LsInput;
using stats::solveLeastSquares;

TEST(LeastSquares, DetectsProportionalColumnsAndEstimableFunctionals) {
  std::mt19937 rng(1);
  std::normal_distribution<double> N(0, 1);
  const int n = 400;
  LsInput in;
  in.X.resize(n, 3);
  in.y.resize(n);
  for (int i = 0; i < n; ++i) {
    const double a = N(rng), b = N(rng);
    in.X.row(i) << a, 1e4 * a, b;  // column 1 = 1e4 * column 0
    in.y(i) = 2 * a + 3 * b + 0.01 * N(rng);
    in.time_index.push_back(i);
    in.block.push_back(0);
  }
  const auto s = solveLeastSquares(in);
  EXPECT_EQ(s.rank, 2);
  EXPECT_FALSE(std::isfinite(s.condition_number) && s.condition_number < 1e8);
  EXPECT_LT(s.condition_number_identifiable, 10);
  Eigen::Vector3d e0(1, 0, 0), e2(0, 0, 1), combo(1, 1e4, 0);
  EXPECT_FALSE(s.isEstimable(e0));
  EXPECT_TRUE(s.isEstimable(e2));
  EXPECT_TRUE(s.isEstimable(combo));
  EXPECT_NEAR(s.estimate(combo), 2.0, 5e-3);
  EXPECT_NEAR(s.estimate(e2), 3.0, 5e-3);
  const Eigen::MatrixXd N0 = s.nullDirections();
  ASSERT_EQ(N0.cols(), 1);
  EXPECT_LT((in.X * N0).norm() / in.X.norm(), 1e-9);
}

// y = b x + AR(1)-filtered noise with a slowly varying regressor: the iid standard error is
// several times too small, the HAC one covers at about its nominal rate.
TEST(LeastSquares, HacStandardErrorsCoverUnderAutocorrelation) {
  std::mt19937 rng(7);
  std::normal_distribution<double> N(0, 1);
  const int n = 3000, reps = 200;
  int cover_hac = 0, cover_iid = 0;
  double ratio = 0;
  for (int r = 0; r < reps; ++r) {
    LsInput in;
    in.X.resize(n, 1);
    in.y.resize(n);
    double e = 0, x = 0;
    for (int i = 0; i < n; ++i) {
      e = 0.95 * e + N(rng);
      x = 0.95 * x + N(rng);
      in.X(i, 0) = x;
      in.y(i) = 1.5 * x + e;
      in.time_index.push_back(i);
      in.block.push_back(0);
    }
    stats::LsOptions opt;
    opt.hac_lags = 150;
    const auto s = solveLeastSquares(in, opt);
    Eigen::VectorXd w(1);
    w << 1;
    const double err = std::abs(s.estimate(w) - 1.5);
    cover_hac += err < 1.96 * s.standardError(w);
    cover_iid += err < 1.96 * s.standardErrorNaive(w);
    ratio += s.standardError(w) / s.standardErrorNaive(w) / reps;
  }
  const double f_hac = double(cover_hac) / reps, f_iid = double(cover_iid) / reps;
  std::printf("AR(1) 0.95: coverage of +-1.96 se: HAC %.3f, iid %.3f; se ratio %.2f\n", f_hac,
              f_iid, ratio);
  EXPECT_GT(f_hac, 0.88);
  EXPECT_LT(f_iid, 0.6);
  EXPECT_GT(ratio, 3.0);
}

// The HAC sandwich against a direct evaluation of its definition: normal equations for beta,
// S = sum_{t,s in one group, |t-s| <= L} (1 - |t-s|/(L+1)) x_t e_t e_s x_s', and
// Cov = n/(n-p) (X'X)^-1 S (X'X)^-1; two groups (no lag crosses their boundary) and rows
// outside every group (independent). The same numbers through solveLeastSquares with rows
// grouped by time step: two rows per step count as one score.
TEST(LeastSquares, HacCovarianceEqualsItsDefinition) {
  std::mt19937 rng(5);
  std::normal_distribution<double> N(0, 1);
  const int n = 60, p = 3, L = 4;
  Eigen::MatrixXd X(n, p);
  Eigen::VectorXd y(n);
  double e = 0;
  for (int i = 0; i < n; ++i) {
    X.row(i) << 1.0, N(rng), 100 * N(rng);
    e = 0.6 * e + N(rng);
    y(i) = 0.5 - 2 * X(i, 1) + 0.01 * X(i, 2) + e;
  }
  const stats::Groups groups{{0, 25}, {25, 55}};  // rows 55..59: no group
  const Eigen::MatrixXd XtX = X.transpose() * X;
  const Eigen::VectorXd beta = XtX.ldlt().solve(X.transpose() * y);
  const Eigen::VectorXd r = y - X * beta;
  std::vector<int> grp(n, -1);
  for (std::size_t g = 0; g < groups.size(); ++g)
    for (int i = groups[g].first; i < groups[g].second; ++i) grp[i] = static_cast<int>(g);
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(p, p);
  for (int t = 0; t < n; ++t)
    for (int s = 0; s < n; ++s) {
      const int lag = std::abs(t - s);
      const bool same = t == s || (grp[t] >= 0 && grp[t] == grp[s]);
      if (!same || lag > L) continue;
      S += (1.0 - double(lag) / (L + 1)) * r(t) * r(s) * X.row(t).transpose() * X.row(s);
    }
  const Eigen::MatrixXd XtXi = XtX.inverse();
  const Eigen::MatrixXd cov = double(n) / (n - p) * XtXi * S * XtXi;

  const stats::LinearFit f = stats::fitLinear(X, y, groups, L);
  ASSERT_TRUE(f.ok);
  EXPECT_EQ(f.rank, p);
  EXPECT_LT((f.beta - beta).norm(), 1e-10 * beta.norm());
  EXPECT_NEAR(f.rss, r.squaredNorm(), 1e-10 * r.squaredNorm());
  EXPECT_LT((f.cov - cov).norm(), 1e-9 * cov.norm());

  // Two rows per time step (each row of the series twice): the
  // per-step score is 2 x_t e_t, so S is 4 S and X'X is 2 X'X.
  LsInput in;
  in.X.resize(2 * n, p);
  in.y.resize(2 * n);
  for (int i = 0; i < n; ++i) {
    in.X.row(2 * i) = X.row(i), in.X.row(2 * i + 1) = X.row(i);
    in.y(2 * i) = y(i), in.y(2 * i + 1) = y(i);
    in.time_index.insert(in.time_index.end(), {long(i), long(i)});
    const int b = grp[i] >= 0 ? grp[i] : 100 + i;
    in.block.insert(in.block.end(), {b, b});
  }
  stats::LsOptions o;
  o.hac_lags = L;
  const auto s2 = solveLeastSquares(in, o);
  // X2'X2 = 2 X'X, per-step score 2 x_t e_t: Cov = 2n/(2n-p) (2X'X)^-1 4 S (2X'X)^-1.
  const Eigen::MatrixXd cov2 = double(2 * n) / (2 * n - p) * XtXi * S * XtXi;
  EXPECT_LT((s2.beta - beta).norm(), 1e-10 * beta.norm());
  EXPECT_LT((s2.cov - cov2).norm(), 1e-9 * cov2.norm());
}

// fitLinear works block of rows by block (blocked QR, HAC scores summed per block; memory of
// diagnose on long drives): on a temporary or a kept design the same result bit for bit, the
// kept design untouched, and the result that of the unblocked SVD solver (solveLeastSquares)
// up to rounding, with groups and lag windows that straddle the 2048-row blocks and rows in
// no group.
TEST(LeastSquares, FitLinearBlockedEqualsTheUnblockedSolver) {
  std::mt19937 rng(7);
  std::normal_distribution<double> N(0, 1);
  const int n = 7001, p = 5;  // odd n: columns start unaligned in the matrix
  Eigen::MatrixXd X(n, p);
  Eigen::VectorXd y(n);
  double e = 0;
  for (int i = 0; i < n; ++i) {
    X.row(i) << 1.0, N(rng), 1e3 * N(rng), 1e-3 * N(rng), std::sin(0.01 * i);
    e = 0.9 * e + N(rng);  // autocorrelated noise: the HAC part matters
    y(i) = 0.5 + 2 * X(i, 1) - 0.001 * X(i, 2) + 300 * X(i, 3) + e;
  }
  // group edges inside blocks, a group across two block edges, rows 4500..4599 alone
  const stats::Groups groups{{0, 1000}, {1000, 4500}, {4600, n}};
  const int lags = 30;
  const Eigen::MatrixXd kept = X;
  const stats::LinearFit a = stats::fitLinear(X, y, groups, lags);
  const stats::LinearFit b = stats::fitLinear(Eigen::MatrixXd(X), y, groups, lags);
  EXPECT_EQ(X, kept);
  ASSERT_TRUE(a.ok);
  ASSERT_TRUE(b.ok);
  EXPECT_EQ(a.beta, b.beta);
  EXPECT_EQ(a.cov, b.cov);
  EXPECT_EQ(a.residual, b.residual);
  EXPECT_EQ(a.rss, b.rss);
  EXPECT_NEAR(a.beta(1), 2.0, 0.2);
  stats::LsInput in{X, y, std::vector<long>(n), std::vector<int>(n)};
  for (int i = 0; i < n; ++i) {
    int g = 0;
    while (g < 3 && !(i >= groups[g].first && i < groups[g].second)) ++g;
    in.time_index[i] = g < 3 ? i - groups[g].first : 0;
    in.block[i] = g < 3 ? g : -1 - i;
  }
  stats::LsOptions lo;
  lo.hac_lags = lags;
  lo.rank_tol = 1e-10;
  const auto s = stats::solveLeastSquares(in, lo);
  for (int k = 0; k < p; ++k) {
    EXPECT_NEAR(a.beta(k), s.beta(k), 1e-11 * std::abs(s.beta(k))) << k;
    for (int j = 0; j < p; ++j)
      EXPECT_NEAR(a.cov(k, j), s.cov(k, j), 1e-10 * std::sqrt(s.cov(k, k) * s.cov(j, j)));
  }
  EXPECT_NEAR(a.rss, s.residuals.squaredNorm(), 1e-12 * a.rss);
  EXPECT_LT((a.residual - s.residuals).norm(), 1e-10 * a.residual.norm());
  // rank deficient (a duplicated column): not ok, beta 0, residual y
  Eigen::MatrixXd Xd(n, p + 1);
  Xd << X, X.col(1);
  const stats::LinearFit d = stats::fitLinear(Xd, y, groups, lags);
  EXPECT_FALSE(d.ok);
  EXPECT_EQ(d.rank, p);
  EXPECT_EQ(d.residual, y);
}
