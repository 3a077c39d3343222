// Normal quantile against tabulated values and its own inverse; chi-square tail, CDF and
// quantiles against independently computed values;
// median and quantile semantics.
#include "libwheelchair/stats/Descriptive.h"
#include "libwheelchair/stats/Distributions.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

using namespace wheelchair::stats;

TEST(Distributions, NormalQuantileMatchesTabulatedValues) {
  // Reference values: Python's statistics.NormalDist().inv_cdf (Wichura AS241, ~1e-16).
  EXPECT_EQ(normalQuantile(0.5), 0.0);
  EXPECT_NEAR(normalQuantile(0.975), 1.959963984540054, 1e-14);
  EXPECT_NEAR(normalQuantile(0.995), 2.5758293035489004, 1e-14);
  EXPECT_NEAR(normalQuantile(0.84134474606854293), 1.0, 1e-13);
  EXPECT_NEAR(normalQuantile(0.001), -3.090232306167813, 1e-13);
  EXPECT_NEAR(normalQuantile(1e-10), -6.361340902404056, 1e-12);
  EXPECT_NEAR(normalQuantile(0.02425), -1.9729610513118845, 1e-13);  // Acklam's region edge
  EXPECT_NEAR(normalQuantile(0.3), -0.5244005127080407, 1e-14);
  EXPECT_NEAR(normalQuantile(0.999999), 4.753424308817089, 1e-9);  // 1 - p exact to 1e-10
  EXPECT_EQ(normalQuantile(0.0), -std::numeric_limits<double>::infinity());
  EXPECT_EQ(normalQuantile(1.0), std::numeric_limits<double>::infinity());
  EXPECT_TRUE(std::isnan(normalQuantile(1.5)));
  EXPECT_TRUE(std::isnan(normalQuantile(std::nan(""))));
}

TEST(Distributions, NormalQuantileInvertsPhiToDoublePrecision) {
  // Phi(z(p)) = p over the whole range, both tails (Acklam alone is only good to 1e-9).
  double worst = 0;
  for (double lp = -300; lp < -0.3011; lp += 0.37) {
    const double p = std::pow(10.0, lp);
    const double zl = normalQuantile(p), zu = normalQuantile(1 - p);
    worst = std::max(worst, std::abs(0.5 * std::erfc(-zl / std::sqrt(2.0)) / p - 1));
    // Upper tail: exact against 1 - (1 - p), the probability it was actually given.
    const double pu = 1 - (1 - p);
    if (pu > 0) worst = std::max(worst, std::abs(0.5 * std::erfc(zu / std::sqrt(2.0)) / pu - 1));
  }
  EXPECT_LT(worst, 1e-12);  // at p = 1e-300, z = -37: one ulp of z moves Phi by 3e-13
  EXPECT_NEAR(normalTwoSidedP(normalQuantile(0.975)), 0.05, 1e-15);
}

// Chi-square reference values below: mpmath 1.3.0 at 40 significant digits (the regularised
// incomplete gamma gammainc(k/2, 0, x/2, regularized=True), and its root for the quantiles),
// rounded to 17 digits; an independent implementation, not the one under test. Where printed
// tables have them (df <= 100) they agree with the tables' 3 decimals (e.g. NIST/SEMATECH
// e-Handbook of Statistical Methods, 1.3.6.7.4: 3.841, 10.828, 13.816, 16.013, 24.322).

TEST(Distributions, Chi2UpperTail) {
  EXPECT_EQ(chi2Sf(0, 3), 1.0);
  EXPECT_EQ(chi2Sf(-1, 3), 1.0);
  EXPECT_NEAR(chi2Sf(3.8414588206941245, 1), 0.05, 1e-12);
  EXPECT_NEAR(chi2Sf(2 * std::log(100.0), 2), 0.01, 1e-14);  // chi2(2) tail = exp(-x/2)
  EXPECT_EQ(chi2Sf(1e7, 2), 0.0);
  EXPECT_NEAR(chi2Sf(24.321886347856853, 7), 0.001, 1e-12);
  // Series (x < k/2 + 1) and continued-fraction branches, half-integer and large k.
  EXPECT_NEAR(chi2Sf(3, 5), 0.69998583587862751, 1e-12);
  EXPECT_NEAR(chi2Sf(10, 7), 0.18857346751345007, 1e-12);
  EXPECT_NEAR(chi2Sf(0.5, 1), 0.47950012218695346, 1e-12);
  EXPECT_NEAR(chi2Sf(40, 20), 0.0049954123083075872, 1e-14);
  EXPECT_NEAR(chi2Sf(150, 140), 0.26645395495428190, 1e-12);
  EXPECT_NEAR(chi2Sf(2.5, 0.5), 0.047246701143909356, 1e-12);
  EXPECT_NEAR(chi2Cdf(10, 7), 0.81142653248654993, 1e-12);
  EXPECT_NEAR(chi2Cdf(3, 5), 0.30001416412137249, 1e-12);
}

TEST(Distributions, Chi2QuantilesMatchReferenceValues) {
  auto rel = [](double x, double ref) { return std::abs(x / ref - 1); };
  EXPECT_LT(rel(chi2Quantile(0.95, 1), 3.8414588206941245), 1e-10);
  EXPECT_LT(rel(chi2Quantile(0.999, 1), 10.827566170662731), 1e-10);
  EXPECT_LT(rel(chi2Quantile(0.999, 2), 13.815510557964272), 1e-10);
  EXPECT_LT(rel(chi2Quantile(0.025, 1), 0.00098206911717525602), 1e-10);
  EXPECT_LT(rel(chi2Quantile(0.975, 7), 16.012764274629322), 1e-10);
  EXPECT_LT(rel(chi2Quantile(0.999, 7), 24.321886347856853), 1e-10);
  EXPECT_LT(rel(chi2Quantile(0.5, 3), 2.3659738843753383), 1e-10);
  EXPECT_LT(rel(chi2Quantile(0.998, 1), 9.5495357060832417), 1e-10);
  EXPECT_LT(rel(chi2Quantile(0.01, 0.5), 1.3499395859116937e-8), 1e-9);
  // Large k, where the Wilson-Hilferty approximation is off in the second decimal (109.13).
  EXPECT_LT(rel(chi2Quantile(0.025, 140), 109.13686821589097), 1e-10);
  EXPECT_LT(rel(chi2Quantile(0.975, 140), 174.64783219009056), 1e-10);
  // 95 % band of the mean of 20 chi2(7): the chi2(140) quantiles / 20.
  const auto [lo, hi] = chi2MeanBand(0.95, 7, 20);
  EXPECT_LT(rel(lo, 5.4568434107945485), 1e-10);
  EXPECT_LT(rel(hi, 8.7323916095045281), 1e-10);
}

TEST(Descriptive, MedianIsTheMeanOfTheTwoMiddleValuesOfFiniteData) {
  EXPECT_EQ(median({3, 1, 2}), 2);
  EXPECT_EQ(median({3, 1, 2, 10}), 2.5);
  EXPECT_EQ(median({4, 4, 1, 9}), 4);
  const double nan = std::nan(""), inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(median({nan, 5, inf, 1, -inf}), 3);  // non-finite values are dropped
  EXPECT_TRUE(std::isnan(median({})));
  EXPECT_TRUE(std::isnan(median({nan})));
  EXPECT_EQ(quantile({4, 1, 3, 2}, 0.9), 4);
  EXPECT_EQ(quantile({4, 1, 3, 2}, 0.5), 3);
  EXPECT_EQ(quantile({4, 1, nan, 2}, 0.0), 1);
  EXPECT_TRUE(std::isnan(quantile({}, 0.5)));
}
