#include "libwheelchair/evaluation/Outliers.h"

#include "libwheelchair/stats/Descriptive.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace wheelchair::evaluation {

namespace {

using stats::median;

bool finitePos(const Position2DStamped& g) {
  return std::isfinite(g.x_m) && std::isfinite(g.y_m);
}

}  // namespace

OutlierReport detectGtOutliers(const std::vector<Position2DStamped>& gt, const OutlierOptions& o) {
  checkTimeOrdered(gt, "detectGtOutliers: ground truth");
  const std::size_t n = gt.size();
  OutlierReport r;
  r.is_outlier.assign(n, false);
  r.residual_m.assign(n, std::numeric_limits<double>::quiet_NaN());
  for (std::size_t i = 0; i < n; ++i) r.is_outlier[i] = !finitePos(gt[i]);
  if (o.enabled && n >= 3) {
    const int w = std::max(1, o.half_window);
    std::vector<Eigen::Vector2d> res(n, Eigen::Vector2d::Constant(std::nan("")));
    for (int iter = 0; iter < std::max(1, o.max_iterations); ++iter) {
      // Residuals against the robust constant-velocity prediction from unflagged neighbours.
      for (std::size_t i = 0; i < n; ++i) {
        res[i].setConstant(std::nan(""));
        if (!finitePos(gt[i])) continue;
        std::vector<std::size_t> before, after;
        for (std::size_t k = i; k-- > 0 && static_cast<int>(before.size()) < w;) {
          if (gt[i].t_s - gt[k].t_s > o.window_s) break;
          if (!r.is_outlier[k]) before.push_back(k);
        }
        for (std::size_t k = i + 1; k < n && static_cast<int>(after.size()) < w; ++k) {
          if (gt[k].t_s - gt[i].t_s > o.window_s) break;
          if (!r.is_outlier[k]) after.push_back(k);
        }
        std::vector<std::pair<std::size_t, std::size_t>> pairs;
        if (!before.empty() && !after.empty()) {
          for (auto a : before)
            for (auto b : after) pairs.emplace_back(a, b);
        } else {
          const auto& side = before.empty() ? after : before;
          for (std::size_t u = 0; u < side.size(); ++u)
            for (std::size_t v = u + 1; v < side.size(); ++v) pairs.emplace_back(side[u], side[v]);
          if (pairs.empty() && side.size() == 1) pairs.emplace_back(side[0], side[0]);
        }
        if (pairs.empty()) continue;
        std::vector<double> px, py;
        for (auto [a, b] : pairs) {
          const double dt = gt[b].t_s - gt[a].t_s;
          const double s = dt != 0.0 ? (gt[i].t_s - gt[a].t_s) / dt : 0.0;
          px.push_back(gt[a].x_m + s * (gt[b].x_m - gt[a].x_m));
          py.push_back(gt[a].y_m + s * (gt[b].y_m - gt[a].y_m));
        }
        res[i] = Eigen::Vector2d(gt[i].x_m - median(px), gt[i].y_m - median(py));
      }
      // Robust scale from the residual components of the samples not flagged so far.
      std::vector<double> comp;
      for (std::size_t i = 0; i < n; ++i) {
        if (r.is_outlier[i] || !std::isfinite(res[i].x())) continue;
        comp.push_back(res[i].x());
        comp.push_back(res[i].y());
      }
      if (comp.empty()) break;
      const double med = median(comp);
      for (auto& c : comp) c = std::abs(c - med);
      r.sigma_m = 1.4826 * median(comp);
      r.threshold_m = std::max(o.k_mad * r.sigma_m, o.floor_m);
      // Flags are recomputed from scratch each pass (not sticky): a good sample next to a burst
      // of outliers may be flagged in the first pass, when the burst still corrupts its
      // prediction, and is cleared once the burst is excluded from its neighbours.
      std::vector<bool> next(n, false);
      for (std::size_t i = 0; i < n; ++i) {
        r.residual_m[i] =
            std::isfinite(res[i].x()) ? res[i].norm() : std::numeric_limits<double>::quiet_NaN();
        next[i] =
            !finitePos(gt[i]) || (std::isfinite(res[i].x()) && r.residual_m[i] > r.threshold_m);
      }
      const bool changed = next != r.is_outlier;
      r.is_outlier = next;
      if (!changed) break;
    }
  }
  for (std::size_t i = 0; i < n; ++i)
    if (r.is_outlier[i]) r.indices.push_back(i);
  return r;
}

}  // namespace wheelchair::evaluation
