// The numerics of stats/LeastSquares.h: rank detection on a structurally rank-deficient
// regressor, estimability of linear functionals, HAC standard errors that cover the truth
// under strongly autocorrelated residuals where the iid ones do not, and the sandwich itself
// against an independent closed-form computation.
#include "libwheelchair/stats/BlockedLeastSquares.h"
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

// fitLinear on a design made block by block (DesignRows: diagnose's library and catalogue fits
// never store their designs) gives fitLinear on the stored design up to rounding (the column
// norms summed by blocks), with groups straddling the 2048-row blocks and rows in no group;
// a rank-deficient made design is refused the same way.
TEST(LeastSquares, FitLinearOnMadeRowsEqualsTheStoredDesign) {
  std::mt19937 rng(11);
  std::normal_distribution<double> N(0, 1);
  const int n = 9001, p = 4;
  Eigen::MatrixXd X(n, p);
  Eigen::VectorXd y(n);
  double e = 0;
  for (int i = 0; i < n; ++i) {
    X.row(i) << 1.0, N(rng), 1e3 * std::cos(0.003 * i), 1e-3 * N(rng);
    e = 0.8 * e + N(rng);
    y(i) = -1 + 0.7 * X(i, 1) + 2e-3 * X(i, 2) + 100 * X(i, 3) + e;
  }
  const stats::Groups groups{{0, 3000}, {3000, 8000}, {8100, n}};
  const int lags = 25;
  int calls = 0;
  const stats::DesignRows rows = [&](long r0, long nb, Eigen::MatrixXd& out) {
    ASSERT_LE(nb, 2048);
    out = X.middleRows(r0, nb);
    ++calls;
  };
  const stats::LinearFit a = stats::fitLinear(X, y, groups, lags);
  const stats::LinearFit b = stats::fitLinear(rows, p, y, groups, lags);
  ASSERT_TRUE(a.ok);
  ASSERT_TRUE(b.ok);
  EXPECT_GT(calls, 4 * (n / 2048));  // never the whole design at once
  EXPECT_EQ(b.rank, a.rank);
  for (int k = 0; k < p; ++k) {
    EXPECT_NEAR(b.beta(k), a.beta(k), 1e-12 * std::abs(a.beta(k))) << k;
    for (int j = 0; j < p; ++j)
      EXPECT_NEAR(b.cov(k, j), a.cov(k, j), 1e-11 * std::sqrt(a.cov(k, k) * a.cov(j, j)));
  }
  EXPECT_NEAR(b.rss, a.rss, 1e-12 * a.rss);
  EXPECT_LT((b.residual - a.residual).norm(), 1e-11 * a.residual.norm());
  Eigen::MatrixXd Xd(n, p + 1);
  Xd << X, 2 * X.col(1);
  const stats::LinearFit d =
      stats::fitLinear([&](long r0, long nb, Eigen::MatrixXd& out) { out = Xd.middleRows(r0, nb); },
                       p + 1, y, groups, lags);
  EXPECT_FALSE(d.ok);
  EXPECT_EQ(d.rank, p);
  EXPECT_EQ(d.residual, y);
  EXPECT_THROW(stats::fitLinear(rows, p + 1, y, groups, lags), std::invalid_argument);
}

// solveLeastSquaresBlocked (identify on long drives): the LsSolution of solveLeastSquares up to
// rounding, on a rank-deficient design with two rows per time step (as identify's theta
// regression), time steps without rows, several blocks (one longer than the HAC window of 2048
// steps), fed in uneven row blocks.
TEST(LeastSquares, BlockedSolverEqualsTheInMemorySolver) {
  std::mt19937 rng(3);
  std::normal_distribution<double> N(0, 1);
  const int p = 4;
  LsInput in;
  std::vector<int> lens{5000, 300, 2600};
  std::vector<Eigen::RowVectorXd> xs;
  std::vector<double> ys;
  double e = 0;
  for (int b = 0; b < 3; ++b)
    for (long t = 0; t < lens[b]; ++t) {
      if (t % 97 < 5) continue;  // steps without rows (standstill)
      const double a = N(rng), c = N(rng), d = std::sin(0.003 * t);
      for (int side = 0; side < 2; ++side) {
        const double s = side == 0 ? 1 : -1;
        Eigen::RowVectorXd x(p);
        x << a, 1e3 * a, s * c, d;  // column 1 = 1e3 column 0: rank 3
        e = 0.95 * e + N(rng);
        xs.push_back(x);
        ys.push_back(2 * a + 3 * s * c - d + 0.1 * e);
        in.time_index.push_back(t);
        in.block.push_back(b);
      }
    }
  in.X.resize(long(xs.size()), p);
  in.y.resize(long(xs.size()));
  for (std::size_t r = 0; r < xs.size(); ++r) in.X.row(long(r)) = xs[r], in.y(long(r)) = ys[r];
  stats::LsOptions lo;
  lo.hac_lags = 60;
  const auto ref = solveLeastSquares(in, lo);
  const long n = in.X.rows();
  const stats::LsRowSource rows = [&](const stats::LsBlockVisitor& visit) {
    for (long r0 = 0, nb = 1; r0 < n; r0 += nb, nb = nb * 3 % 1999 + 1) {
      nb = std::min(nb, n - r0);
      visit(in.X.middleRows(r0, nb), in.y.segment(r0, nb),
            std::vector<long>(in.time_index.begin() + r0, in.time_index.begin() + r0 + nb),
            std::vector<int>(in.block.begin() + r0, in.block.begin() + r0 + nb));
    }
  };
  const auto s = stats::solveLeastSquaresBlocked(rows, p, lo);
  ASSERT_EQ(s.rank, 3);
  EXPECT_EQ(ref.rank, 3);
  EXPECT_TRUE(s.residuals.size() == 0);
  for (int k = 0; k < p; ++k) {
    EXPECT_NEAR(s.column_scale(k), ref.column_scale(k), 1e-13 * ref.column_scale(k));
    EXPECT_NEAR(s.beta(k), ref.beta(k), 1e-10 * ref.beta.norm()) << k;
    for (int j = 0; j < p; ++j) {
      const double sc = std::sqrt(ref.cov(k, k) * ref.cov(j, j)) + 1e-300;
      EXPECT_NEAR(s.cov(k, j), ref.cov(k, j), 1e-9 * sc) << k << "," << j;
      const double scn = std::sqrt(ref.cov_naive(k, k) * ref.cov_naive(j, j)) + 1e-300;
      EXPECT_NEAR(s.cov_naive(k, j), ref.cov_naive(k, j), 1e-9 * scn);
    }
  }
  for (int k = 0; k < 3; ++k)
    EXPECT_NEAR(s.singular_values(k), ref.singular_values(k), 1e-12 * ref.singular_values(0));
  EXPECT_LT(s.singular_values(3), 1e-12 * s.singular_values(0));
  EXPECT_NEAR(s.condition_number_identifiable, ref.condition_number_identifiable,
              1e-10 * ref.condition_number_identifiable);
  const Eigen::Vector4d w(1, 1e3, 0, 0), w2(0, 0, 1, 0);
  EXPECT_TRUE(s.isEstimable(w));
  EXPECT_FALSE(s.isEstimable(Eigen::Vector4d(1, 0, 0, 0)));
  EXPECT_NEAR(s.standardError(w2), ref.standardError(w2), 1e-9 * ref.standardError(w2));
  const auto &a = s.residual, &b = ref.residual;
  EXPECT_EQ(a.n_rows, b.n_rows);
  EXPECT_EQ(a.dof, b.dof);
  EXPECT_NEAR(a.rms, b.rms, 1e-12 * b.rms);
  EXPECT_NEAR(a.mean, b.mean, 1e-10 * b.rms);
  EXPECT_NEAR(a.max_abs, b.max_abs, 1e-10 * b.max_abs);
  EXPECT_NEAR(a.rms_y, b.rms_y, 1e-13 * b.rms_y);
  EXPECT_NEAR(a.r_squared, b.r_squared, 1e-12);
  EXPECT_NEAR(a.lag1_autocorr, b.lag1_autocorr, 1e-12);
  EXPECT_NEAR(a.n_effective, b.n_effective, 1e-9 * b.n_effective);
  // rows of a block that come back after another block are refused
  const stats::LsRowSource bad = [&](const stats::LsBlockVisitor& visit) {
    for (int b : {0, 1, 0})
      visit(in.X.topRows(10), in.y.head(10), std::vector<long>(10, 0), std::vector<int>(10, b));
  };
  EXPECT_THROW(stats::solveLeastSquaresBlocked(bad, p, lo), std::invalid_argument);
}
