// Unit tests of the evidence statistics (effective sample size, HAC fit, Ljung-Box, evidence).
#include "libwheelchair/stats/Statistics.h"

#include <gtest/gtest.h>

#include <random>

using namespace wheelchair::stats;

TEST(Statistics, EffectiveSampleSizeOfWhiteAndAr1) {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> N(0, 1);
  const int n = 20000;
  Eigen::VectorXd w(n), a(n);
  double x = 0;
  for (int i = 0; i < n; ++i) {
    w(i) = N(rng);
    x = 0.8 * x + N(rng);
    a(i) = x;
  }
  double ne_w = effectiveSampleSize(w, singleGroup(n), 30);
  double ne_a = effectiveSampleSize(a, singleGroup(n), 60);
  EXPECT_GT(ne_w, 0.85 * n);
  // AR(1) with phi: n_eff = n (1 - phi) / (1 + phi) = n / 9
  EXPECT_NEAR(ne_a / n, 1.0 / 9.0, 0.04);
  EXPECT_GT(ljungBox(w, singleGroup(n), 10).p_value, 1e-3);
  EXPECT_LT(ljungBox(a, singleGroup(n), 10).p_value, 1e-10);
}

TEST(Statistics, HacFitRecoversCoefficientAndHonestError) {
  std::mt19937_64 rng(5);
  std::normal_distribution<double> N(0, 1);
  const int n = 5000;
  Eigen::MatrixXd X(n, 1);
  Eigen::VectorXd y(n);
  double e = 0;
  for (int i = 0; i < n; ++i) {
    X(i, 0) = std::sin(i * 0.01);
    e = 0.9 * e + 0.1 * N(rng);
    y(i) = 0.3 * X(i, 0) + e;
  }
  LinearFit f = fitLinear(X, y, singleGroup(n), 100);
  ASSERT_TRUE(f.ok);
  EXPECT_NEAR(f.beta(0), 0.3, 5 * std::sqrt(f.cov(0, 0)));
  Evidence ev = compareNested(y.squaredNorm(), f.rss, 1,
                              effectiveSampleSize(f.residual, singleGroup(n), 100));
  EXPECT_LT(ev.p_value, 1e-6);
  EXPECT_LT(ev.delta_bic, -10);
}

TEST(Statistics, RankDeficientDesignIsReported) {
  Eigen::MatrixXd X(10, 2);
  X.col(0).setLinSpaced(10, 0, 1);
  X.col(1) = 2 * X.col(0);
  Eigen::VectorXd y = X.col(0);
  EXPECT_FALSE(fitLinear(X, y, singleGroup(10), 2).ok);
}
