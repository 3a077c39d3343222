// Distribution functions used by the tests of the estimator and the diagnosis: chi-square
// (innovation gates, consistency bands, likelihood-ratio p-values) and the standard normal.
//
// chi2Cdf uses the regularised lower incomplete gamma function P(k/2, x/2) (series for
// x < a + 1, Lentz continued fraction otherwise, Numerical Recipes 6.2); chi2Quantile inverts
// it by bracketed bisection to ~1e-12 relative accuracy. Exact for every k >= 1 (including
// k = 1, where the Wilson-Hilferty approximation is poor).
//
// normalQuantile: Acklam's rational approximation (|rel. error| < 1.2e-9) refined by one
// Halley step on Phi(z) = erfc(-z / sqrt 2) / 2, which brings it to double precision
// (~1e-15 relative) over (0, 1).
//
// Example:
//   double gate = chi2Quantile(0.999, 1);         // 10.83: NIS gate for a scalar measurement
//   auto [lo, hi] = chi2MeanBand(0.95, 2, 100);   // 95 % band of the mean of 100 chi2(2)
//   double p = chi2Sf(lr, k);                     // p-value of a likelihood ratio
//   double z = normalQuantile(0.975);             // 1.959963984540054
#pragma once

#include <utility>

namespace wheelchair::stats {

/// P(X <= x) for X ~ chi2(k), k > 0 (throws std::invalid_argument for k <= 0).
double chi2Cdf(double x, double k);
/// x such that chi2Cdf(x, k) = p, 0 < p < 1.
double chi2Quantile(double p, double k);
/// Two-sided band of probability `prob` for the MEAN of n independent chi2(k) values:
/// [chi2Quantile((1-prob)/2, n k) / n, chi2Quantile((1+prob)/2, n k) / n].
std::pair<double, double> chi2MeanBand(double prob, double k, double n);
/// Upper tail P(X > x) of chi2(k) (1 for x <= 0, 0 far in the tail).
double chi2Sf(double x, double k);

/// Inverse of the standard normal CDF: z with Phi(z) = p, 0 < p < 1 (-inf / +inf at 0 / 1,
/// NaN outside [0, 1]).
double normalQuantile(double p);
/// Standard normal two-sided p-value of |z|: P(|Z| > |z|).
double normalTwoSidedP(double z);

}  // namespace wheelchair::stats
