#include "libwheelchair/evaluation/Nees.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <fmt/format.h>
#include <Eigen/Cholesky>

namespace wheelchair::evaluation {

namespace {
// Inverse of the standard normal CDF (Acklam's rational approximation, |rel. error| < 1.2e-9).
double normalQuantile(double p) {
  static const double a[] = {-3.969683028665376e+01, 2.209460984245205e+02,  -2.759285104469687e+02,
                             1.383577518672690e+02,  -3.066479806614716e+01, 2.506628277459239e+00};
  static const double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                             6.680131188771972e+01, -1.328068155288572e+01};
  static const double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                             -2.549732539343734e+00, 4.374664141464968e+00,  2.938163982698783e+00};
  static const double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                             3.754408661907416e+00};
  const double pl = 0.02425;
  if (p < pl) {
    const double q = std::sqrt(-2 * std::log(p));
    return (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
           ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
  }
  if (p > 1 - pl) return -normalQuantile(1 - p);
  const double q = p - 0.5, r = q * q;
  return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
         (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1);
}
}  // namespace

double chi2QuantileApprox(double p, double k) {
  const double z = normalQuantile(p);
  const double h = 2.0 / (9.0 * k);
  const double v = 1.0 - h + z * std::sqrt(h);
  return k * v * v * v;
}

NeesResult averageNees(const std::vector<PositionEstimateStamped>& est,
                       const std::vector<Position2DStamped>& gt, const NeesOptions& o) {
  for (std::size_t k = 1; k < est.size(); ++k) {
    if (!(est[k].t_s > est[k - 1].t_s)) {
      throw std::invalid_argument(
          fmt::format("averageNees: estimate times must be strictly increasing (sample {})", k));
    }
  }
  const OutlierReport rep = detectGtOutliers(gt, o.outliers);  // also checks gt ordering
  NeesResult r{std::numeric_limits<double>::quiet_NaN(), 0, 0.0, 0.0, 0.0, {}};
  const double chi2_95 = -2.0 * std::log(0.05);  // exact for 2 dof: 5.991
  std::size_t inside = 0;
  for (std::size_t i = 0; i < gt.size(); ++i) {
    if (rep.is_outlier[i] || est.empty()) continue;
    const double t = gt[i].t_s;
    if (t < est.front().t_s || t > est.back().t_s) continue;
    auto hi =
        std::upper_bound(est.begin(), est.end(), t,
                         [](double tv, const PositionEstimateStamped& p) { return tv < p.t_s; });
    auto lo = hi - 1;
    Eigen::Vector2d p;
    Eigen::Matrix2d P;
    if (lo->t_s == t) {
      p = lo->p_m;
      P = lo->cov_m2;
    } else {
      const double dt = hi->t_s - lo->t_s;
      if (dt > o.max_gap_s) continue;
      const double a = (t - lo->t_s) / dt;
      p = (1 - a) * lo->p_m + a * hi->p_m;
      P = (1 - a) * lo->cov_m2 + a * hi->cov_m2;
    }
    const Eigen::Vector2d e = p - Eigen::Vector2d(gt[i].x_m, gt[i].y_m);
    const Eigen::Matrix2d S = P + o.gt_cov_m2;
    const Eigen::LLT<Eigen::Matrix2d> llt(S);
    if (llt.info() != Eigen::Success) {
      throw std::invalid_argument(
          fmt::format("averageNees: covariance at t={} s is not positive definite", t));
    }
    const double v = e.dot(llt.solve(e));
    r.nees.push_back(v);
    if (v <= chi2_95) ++inside;
  }
  r.n = r.nees.size();
  if (r.n == 0) return r;
  double sum = 0.0;
  for (double v : r.nees) sum += v;
  const double N = static_cast<double>(r.n);
  r.mean_nees = sum / N;
  r.lower95 = chi2QuantileApprox(0.025, 2.0 * N) / N;
  r.upper95 = chi2QuantileApprox(0.975, 2.0 * N) / N;
  r.fraction_inside95 = static_cast<double>(inside) / N;
  return r;
}

}  // namespace wheelchair::evaluation
