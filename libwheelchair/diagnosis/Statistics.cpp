#include "libwheelchair/diagnosis/Statistics.h"

#include "libwheelchair/estimation/ChiSquare.h"

#include <Eigen/LU>
#include <Eigen/QR>

#include <algorithm>
#include <cmath>

namespace wheelchair::diagnosis {

Groups singleGroup(int n) {
  return {{0, n}};
}

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

LinearFit fitLinear(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, const Groups& groups,
                    int lags) {
  LinearFit f;
  const int n = static_cast<int>(y.size());
  const int p = static_cast<int>(X.cols());
  if (p == 0) {
    f.beta.resize(0);
    f.cov.resize(0, 0);
    f.residual = y;
    f.rss = y.squaredNorm();
    f.ok = true;
    return f;
  }
  Eigen::VectorXd scale(p);
  for (int j = 0; j < p; ++j) {
    double c = X.col(j).norm();
    scale(j) = c > 0 ? c : 1.0;
  }
  Eigen::MatrixXd Xs = X * scale.cwiseInverse().asDiagonal();
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(Xs);
  qr.setThreshold(1e-10);
  f.rank = static_cast<int>(qr.rank());
  if (f.rank < p || n <= p) {
    f.ok = false;
    f.beta = Eigen::VectorXd::Zero(p);
    f.residual = y;
    f.rss = y.squaredNorm();
    f.cov = Eigen::MatrixXd::Identity(p, p) * 1e300;
    return f;
  }
  Eigen::VectorXd bs = qr.solve(y);
  f.beta = bs.cwiseQuotient(scale);
  f.residual = y - X * f.beta;
  f.rss = f.residual.squaredNorm();
  // Sandwich: (X'X)^-1 S (X'X)^-1, S = sum_l w_l sum_t (x_t e_t)(x_{t-l} e_{t-l})' (+ transpose).
  Eigen::MatrixXd XtXi = (Xs.transpose() * Xs).inverse();
  Eigen::MatrixXd g = Xs.array().colwise() * f.residual.array();
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(p, p);
  for (auto [a, b] : groups) {
    if (b <= a) continue;
    S += g.middleRows(a, b - a).transpose() * g.middleRows(a, b - a);
    for (int l = 1; l <= lags && l < b - a; ++l) {
      double w = 1.0 - double(l) / (lags + 1);
      Eigen::MatrixXd G = g.middleRows(a + l, b - a - l).transpose() * g.middleRows(a, b - a - l);
      S += w * (G + G.transpose());
    }
  }
  double dof_corr = double(n) / std::max(1, n - p);
  Eigen::MatrixXd cs = XtXi * S * XtXi * dof_corr;
  f.cov = scale.cwiseInverse().asDiagonal() * cs * scale.cwiseInverse().asDiagonal();
  f.ok = true;
  return f;
}

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

double chi2Sf(double x, double k) {
  if (!(x > 0)) return 1.0;
  if (x > 1e4 * std::max(1.0, k)) return 0.0;
  double c = estimation::chi2Cdf(x, k);
  return std::clamp(1.0 - c, 0.0, 1.0);
}

double normalTwoSidedP(double z) {
  return std::erfc(std::abs(z) / std::sqrt(2.0));
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

}  // namespace wheelchair::diagnosis
