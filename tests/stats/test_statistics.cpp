// Unit tests of the evidence statistics (effective sample size, HAC fit, Ljung-Box, evidence).
#include "libwheelchair/stats/Statistics.h"

#include <gtest/gtest.h>

#include <cmath>
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

// heldOutGain against its closed form on rows whose residual is white enough that n_eff = n
// (lags 0): y = (1, -1, 2, -2), p0 = 0 (rss0 = 10), p1 = y / 2 (rss1 = 2.5, |p1 - p0|^2 = 2.5):
// lr = 4 log(10 / 2.5) = 4 log 4, predicted 4 log(1 + 1) = 4 log 2. And a prediction that
// overshoots as far as p0 falls short (p1 = 2 y: rss1 = 10) gains nothing, lr = 0, though
// it predicted 4 log(1 + 40 / 10).
TEST(Statistics, HeldOutGainIsTheClosedFormLikelihoodRatio) {
  Eigen::VectorXd y(4);
  y << 1, -1, 2, -2;
  const Eigen::VectorXd p0 = Eigen::VectorXd::Zero(4);
  const Groups g{{0, 4}};
  const HeldOutGain half = heldOutGain(y, p0, y.squaredNorm(), 0.5 * y, g, 0);
  EXPECT_DOUBLE_EQ(half.rss1, 2.5);
  EXPECT_DOUBLE_EQ(half.n_eff, 4.0);
  EXPECT_NEAR(half.lr, 4 * std::log(4.0), 1e-12);
  EXPECT_NEAR(half.lr_expected, 4 * std::log(2.0), 1e-12);
  const HeldOutGain twice = heldOutGain(y, p0, y.squaredNorm(), 2.0 * y, g, 0);
  EXPECT_NEAR(twice.lr, 0.0, 1e-12);
  EXPECT_NEAR(twice.lr_expected, 4 * std::log(1.0 + 40.0 / 10.0), 1e-12);
}
