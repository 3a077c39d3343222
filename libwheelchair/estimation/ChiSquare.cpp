#include "libwheelchair/estimation/ChiSquare.h"

#include <cmath>
#include <limits>
#include <stdexcept>

namespace wheelchair::estimation {

namespace {

// Regularised lower incomplete gamma P(a, x).
double gammaP(double a, double x) {
  if (x <= 0) return 0.0;
  const double gln = std::lgamma(a);
  if (x < a + 1.0) {
    double ap = a, sum = 1.0 / a, del = sum;
    for (int n = 0; n < 10000; ++n) {
      ap += 1.0;
      del *= x / ap;
      sum += del;
      if (std::fabs(del) < std::fabs(sum) * 1e-16) break;
    }
    return sum * std::exp(-x + a * std::log(x) - gln);
  }
  // Continued fraction for Q(a, x), modified Lentz.
  const double fpmin = std::numeric_limits<double>::min() / 1e-16;
  double b = x + 1.0 - a, c = 1.0 / fpmin, d = 1.0 / b, h = d;
  for (int i = 1; i < 10000; ++i) {
    const double an = -i * (i - a);
    b += 2.0;
    d = an * d + b;
    if (std::fabs(d) < fpmin) d = fpmin;
    c = b + an / c;
    if (std::fabs(c) < fpmin) c = fpmin;
    d = 1.0 / d;
    const double del = d * c;
    h *= del;
    if (std::fabs(del - 1.0) < 1e-16) break;
  }
  return 1.0 - std::exp(-x + a * std::log(x) - gln) * h;
}

}  // namespace

double chi2Cdf(double x, double k) {
  if (!(k > 0)) throw std::invalid_argument("chi2Cdf: degrees of freedom must be > 0");
  return gammaP(0.5 * k, 0.5 * x);
}

double chi2Quantile(double p, double k) {
  if (!(p > 0 && p < 1)) throw std::invalid_argument("chi2Quantile: p must be in (0, 1)");
  if (!(k > 0)) throw std::invalid_argument("chi2Quantile: degrees of freedom must be > 0");
  double lo = 0.0, hi = std::max(1.0, k);
  while (chi2Cdf(hi, k) < p) hi *= 2.0;
  for (int it = 0; it < 200; ++it) {
    const double mid = 0.5 * (lo + hi);
    if (chi2Cdf(mid, k) < p)
      lo = mid;
    else
      hi = mid;
    if (hi - lo <= 1e-13 * std::max(1.0, hi)) break;
  }
  return 0.5 * (lo + hi);
}

std::pair<double, double> chi2MeanBand(double prob, double k, double n) {
  const double a = 0.5 * (1.0 - prob);
  return {chi2Quantile(a, n * k) / n, chi2Quantile(1.0 - a, n * k) / n};
}

}  // namespace wheelchair::estimation
