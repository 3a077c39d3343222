#include "libwheelchair/stats/Statistics.h"

#include <algorithm>
#include <cmath>

namespace wheelchair::stats {

namespace {

double autocov(const Eigen::VectorXd& r, const Groups& groups, int k, bool demean) {
  double s = 0;
  double mean = 0;
  if (demean) {
    double n = 0;
    for (auto [a, b] : groups)
      for (int i = a; i < b; ++i) mean += r(i), n += 1;
    mean = n > 0 ? mean / n : 0;
  }
  for (auto [a, b] : groups)
    for (int i = a + k; i < b; ++i) s += (r(i) - mean) * (r(i - k) - mean);
  return s;
}

}  // namespace

double effectiveSampleSize(const Eigen::VectorXd& r, const Groups& groups, int lags) {
  double n = 0;
  for (auto [a, b] : groups) n += std::max(0, b - a);
  if (n < 2) return std::max(1.0, n);
  double g0 = autocov(r, groups, 0, true);
  if (!(g0 > 0)) return n;
  double lrv = g0;
  for (int k = 1; k <= lags; ++k)
    lrv += 2.0 * (1.0 - double(k) / (lags + 1)) * autocov(r, groups, k, true);
  // The long-run variance of a sum cannot be below a small fraction of g0 for physical
  // residuals; a negative estimate (strong alternation) is treated as white.
  if (!(lrv > 0)) return n;
  return std::clamp(n * g0 / lrv, 1.0, n);
}

HeldOutGain heldOutGain(const Eigen::VectorXd& y, const Eigen::VectorXd& p0, double rss0,
                        const Eigen::VectorXd& p1, const Groups& groups, int lags) {
  HeldOutGain g;
  const Eigen::VectorXd r1 = y - p1;
  g.rss1 = r1.squaredNorm();
  g.n_eff = effectiveSampleSize(r1, groups, lags);
  const double rss1 = std::max(1e-300, g.rss1);
  g.lr = g.n_eff * std::log(rss0 / rss1);
  g.lr_expected = g.n_eff * std::log(1.0 + (p1 - p0).squaredNorm() / rss1);
  return g;
}

Whiteness ljungBox(const Eigen::VectorXd& r, const Groups& groups, int m) {
  Whiteness w;
  double n = 0;
  for (auto [a, b] : groups) n += std::max(0, b - a);
  w.lags = m;
  if (n < m + 2) return w;
  double g0 = autocov(r, groups, 0, true);
  if (!(g0 > 0)) return w;
  for (int k = 1; k <= m; ++k) {
    double rho = autocov(r, groups, k, true) / g0;
    if (k == 1) w.rho1 = rho;
    w.q += rho * rho / (n - k);
  }
  w.q *= n * (n + 2);
  w.p_value = chi2Sf(w.q, m);
  return w;
}

Evidence compareNested(double rss0, double rss1, int k, double n_eff) {
  Evidence e;
  e.k = k;
  e.n_eff = n_eff;
  if (!(rss1 > 0) || !(rss0 > 0)) return e;
  e.lr = std::max(0.0, n_eff * std::log(rss0 / rss1));
  e.p_value = chi2Sf(e.lr, k);
  e.delta_bic = -e.lr + k * std::log(std::max(2.0, n_eff));
  return e;
}

Evidence compareNestedWithFloor(double rss0, double rss1, double n, int k, double n_eff,
                                double floor_var) {
  if (!(n > 0)) return compareNested(rss0, rss1, k, n_eff);
  const double f = std::max(0.0, floor_var);
  return compareNested(rss0 / n + f, rss1 / n + f, k, n_eff);
}

BiasTest biasTest(const Eigen::VectorXd& r, const Groups& groups, int lags) {
  BiasTest b;
  double n = 0, s = 0, s2 = 0;
  for (auto [a, e] : groups)
    for (int i = a; i < e; ++i) s += r(i), s2 += r(i) * r(i), n += 1;
  b.n = static_cast<int>(n);
  if (n < 2) return b;
  b.mean = s / n;
  b.rms = std::sqrt(s2 / n);
  b.n_eff = effectiveSampleSize(r, groups, lags);
  double var = std::max(1e-300, s2 / n - b.mean * b.mean);
  b.t = b.mean / std::sqrt(var / b.n_eff);
  b.p_value = normalTwoSidedP(b.t);
  return b;
}

}  // namespace wheelchair::stats
