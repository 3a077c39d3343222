#include "libwheelchair/stats/Distributions.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace wheelchair::stats {

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
    if (hi - lo <= 1e-13 * hi) break;  // relative: small quantiles too (chi2(0.5) at 0.01: 1.3e-8)
  }
  return 0.5 * (lo + hi);
}

std::pair<double, double> chi2MeanBand(double prob, double k, double n) {
  const double a = 0.5 * (1.0 - prob);
  return {chi2Quantile(a, n * k) / n, chi2Quantile(1.0 - a, n * k) / n};
}

double chi2Sf(double x, double k) {
  if (!(x > 0)) return 1.0;
  if (x > 1e4 * std::max(1.0, k)) return 0.0;
  return std::clamp(1.0 - chi2Cdf(x, k), 0.0, 1.0);
}

double normalQuantile(double p) {
  if (!(p >= 0 && p <= 1)) return std::numeric_limits<double>::quiet_NaN();
  if (p == 0) return -std::numeric_limits<double>::infinity();
  if (p == 1) return std::numeric_limits<double>::infinity();
  // Acklam's rational approximation: central region and the two tails.
  static const double a[] = {-3.969683028665376e+01, 2.209460984245205e+02,  -2.759285104469687e+02,
                             1.383577518672690e+02,  -3.066479806614716e+01, 2.506628277459239e+00};
  static const double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                             6.680131188771972e+01, -1.328068155288572e+01};
  static const double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                             -2.549732539343734e+00, 4.374664141464968e+00,  2.938163982698783e+00};
  static const double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                             3.754408661907416e+00};
  const double pl = 0.02425;
  const double pt = std::min(p, 1 - p);  // tail probability
  double z;
  if (pt < pl) {
    const double q = std::sqrt(-2 * std::log(pt));
    z = (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
        ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
    if (p > 0.5) z = -z;
  } else {
    const double q = p - 0.5, r = q * q;
    z = (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
        (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1);
  }
  // One Halley step on f(z) = Phi(z) - p, in the tail that keeps Phi accurate.
  const double kSqrt2 = 1.4142135623730950488, kSqrt2Pi = 2.5066282746310005024;
  const double e =
      p < 0.5 ? 0.5 * std::erfc(-z / kSqrt2) - p : (1 - p) - 0.5 * std::erfc(z / kSqrt2);
  const double u = e * kSqrt2Pi * std::exp(0.5 * z * z);
  return z - u / (1 + 0.5 * z * u);
}

double normalTwoSidedP(double z) {
  return std::erfc(std::abs(z) / std::sqrt(2.0));
}

}  // namespace wheelchair::stats
