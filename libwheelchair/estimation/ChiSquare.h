// Chi-square distribution functions for innovation gating and consistency bands.
//
// chi2Cdf uses the regularised lower incomplete gamma function P(k/2, x/2) (series for
// x < a + 1, Lentz continued fraction otherwise, Numerical Recipes 6.2); chi2Quantile inverts
// it by bracketed bisection/Newton to ~1e-12 relative accuracy. Exact for every k >= 1
// (including k = 1, where the Wilson-Hilferty approximation is poor).
//
// Example:
//   double gate = chi2Quantile(0.999, 1);   // 10.83: NIS gate for a scalar measurement
//   auto [lo, hi] = chi2MeanBand(0.95, 2, 100);   // 95 % band of the mean of 100 chi2(2)
#pragma once

#include <utility>

namespace wheelchair::estimation {

/// P(X <= x) for X ~ chi2(k), k > 0.
double chi2Cdf(double x, double k);
/// x such that chi2Cdf(x, k) = p, 0 < p < 1.
double chi2Quantile(double p, double k);
/// Two-sided band of probability `prob` for the MEAN of n independent chi2(k) values:
/// [chi2Quantile((1-prob)/2, n k) / n, chi2Quantile((1+prob)/2, n k) / n].
std::pair<double, double> chi2MeanBand(double prob, double k, double n);

}  // namespace wheelchair::estimation
