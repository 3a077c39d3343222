#include "libwheelchair/evaluation/Nees.h"

#include "libwheelchair/stats/Distributions.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <tuple>

#include <fmt/format.h>
#include <Eigen/Cholesky>

namespace wheelchair::evaluation {

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
  std::tie(r.lower95, r.upper95) = stats::chi2MeanBand(0.95, 2.0, N);
  r.fraction_inside95 = static_cast<double>(inside) / N;
  return r;
}

}  // namespace wheelchair::evaluation
