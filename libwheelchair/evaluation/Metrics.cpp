#include "libwheelchair/evaluation/Metrics.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <stdexcept>

#include <fmt/format.h>

#include "libwheelchair/model/Kinematics.h"
#include "libwheelchair/stats/Descriptive.h"
#include "libwheelchair/util/AtomicFile.h"

namespace wheelchair::evaluation {

namespace {
constexpr double kRad2Deg = 180.0 / M_PI;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

}  // namespace

const char* toString(HeadingDriftMethod m) {
  switch (m) {
    case HeadingDriftMethod::Unavailable:
      return "unavailable";
    case HeadingDriftMethod::GroundTruthHeading:
      return "gt_heading";
    case HeadingDriftMethod::DirectionOfTravel:
      return "direction_of_travel";
  }
  return "?";
}

ErrorStats errorStats(const std::vector<double>& e) {
  ErrorStats s{kNaN, kNaN, kNaN, kNaN, kNaN, kNaN, e.size()};
  if (e.empty()) return s;
  const double n = static_cast<double>(e.size());
  double sum = 0.0, sq = 0.0;
  for (double v : e) {
    sum += v;
    sq += v * v;
  }
  s.mean = sum / n;
  s.rmse = std::sqrt(sq / n);
  double var = 0.0;
  for (double v : e) var += (v - s.mean) * (v - s.mean);
  s.std = std::sqrt(var / n);  // numpy.std (ddof = 0), as evo
  s.max = *std::max_element(e.begin(), e.end());
  s.min = *std::min_element(e.begin(), e.end());
  s.median = stats::median(e);
  return s;
}

std::vector<std::pair<std::size_t, std::size_t>> pairsByPath(const std::vector<Eigen::Vector2d>& p,
                                                             double delta_m) {
  std::vector<std::size_t> ids;
  double path = 0.0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (i > 0) path += (p[i] - p[i - 1]).norm();
    if (path >= delta_m) {
      ids.push_back(i);
      path = 0.0;
    }
  }
  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  for (std::size_t k = 1; k < ids.size(); ++k) pairs.emplace_back(ids[k - 1], ids[k]);
  return pairs;
}

std::vector<double> rpeTranslationErrors(const Association& a, double delta_m, RpePairsFrom from) {
  const auto pairs = pairsByPath(from == RpePairsFrom::Reference ? a.gt : a.est, delta_m);
  std::vector<double> err;
  err.reserve(pairs.size());
  for (auto [i, j] : pairs) {
    const Eigen::Vector2d dP = a.est[j] - a.est[i];
    const Eigen::Vector2d dQ = a.gt[j] - a.gt[i];
    // |R_Pi^T dP - R_Qi^T dQ| = |dP - R(phi_P,i - phi_Q,i) dQ|; GT heading borrowed if absent.
    const double dphi = std::isfinite(a.gt_phi[i]) ? a.est_phi[i] - a.gt_phi[i] : 0.0;
    const double c = std::cos(dphi), s = std::sin(dphi);
    const Eigen::Vector2d RdQ(c * dQ.x() - s * dQ.y(), s * dQ.x() + c * dQ.y());
    err.push_back((dP - RdQ).norm());
  }
  return err;
}

double headingDriftDeg(const Association& a, const MetricOptions& o, HeadingDriftMethod* method) {
  if (method) *method = HeadingDriftMethod::Unavailable;
  const std::size_t n = a.t.size();
  if (n < 2) return kNaN;
  if (std::isfinite(a.gt_phi.front()) && std::isfinite(a.gt_phi.back())) {
    const double e0 = model::wrapAngle(a.est_phi.front() - a.gt_phi.front());
    const double e1 = model::wrapAngle(a.est_phi.back() - a.gt_phi.back());
    if (method) *method = HeadingDriftMethod::GroundTruthHeading;
    return model::wrapAngle(e1 - e0) * kRad2Deg;
  }
  // Direction of travel: SE(2) fit of the estimate onto the ground truth over the initial and the
  // final segment; the fitted rotation is minus the estimate's heading error over that segment.
  std::vector<double> s(n, 0.0);
  for (std::size_t k = 1; k < n; ++k) s[k] = s[k - 1] + (a.est[k] - a.est[k - 1]).norm();
  auto segmentTheta = [&](bool initial, double& theta) {
    std::vector<Eigen::Vector2d> e, g;
    for (std::size_t k = 0; k < n; ++k) {
      const bool in = initial ? s[k] <= s.front() + o.heading_segment_m
                              : s[k] >= s.back() - o.heading_segment_m;
      if (in) {
        e.push_back(a.est[k]);
        g.push_back(a.gt[k]);
      }
    }
    if (e.size() < 3) return false;
    Eigen::Vector2d mu = Eigen::Vector2d::Zero();
    for (const auto& q : g) mu += q;
    mu /= static_cast<double>(g.size());
    double ss = 0.0;
    for (const auto& q : g) ss += (q - mu).squaredNorm();
    if (std::sqrt(ss / static_cast<double>(g.size())) < o.heading_min_spread_m) return false;
    theta = alignSE2(e, g).theta;
    return true;
  };
  double th0 = 0.0, th1 = 0.0;
  if (!segmentTheta(true, th0) || !segmentTheta(false, th1)) return kNaN;
  if (method) *method = HeadingDriftMethod::DirectionOfTravel;
  return model::wrapAngle(th0 - th1) * kRad2Deg;  // (-th1) - (-th0)
}

Association alignedAssociation(const Trajectory& est, const std::vector<Position2DStamped>& gt,
                               const MetricOptions& o, OutlierReport* outliers_out,
                               Association* unaligned_out, SE2* T_out, double* spread_out) {
  checkTimeOrdered(est, "computeMetrics: estimate");
  checkTimeOrdered(gt, "computeMetrics: ground truth");
  const OutlierReport rep = detectGtOutliers(gt, o.outliers);
  std::vector<Position2DStamped> clean;
  std::vector<std::size_t> clean_index;
  for (std::size_t k = 0; k < gt.size(); ++k) {
    if (rep.is_outlier[k]) continue;
    clean.push_back(gt[k]);
    clean_index.push_back(k);
  }
  Association a = associate(est, clean, o.max_gap_s, o.lever_arm_m);
  a.n_gt_total = gt.size();
  for (auto& gi : a.gt_index) gi = clean_index[gi];
  double spread = 0.0;
  const SE2 T = computeAlignment(a, o.alignment, o.align_first_s, &spread);
  if (outliers_out) *outliers_out = rep;
  if (unaligned_out) *unaligned_out = a;
  if (T_out) *T_out = T;
  if (spread_out) *spread_out = spread;
  return applyAlignment(a, T);
}

Metrics computeMetrics(const Trajectory& est, const std::vector<Position2DStamped>& gt,
                       const MetricOptions& o) {
  Metrics m;
  OutlierReport rep;
  const Association a =
      alignedAssociation(est, gt, o, &rep, nullptr, &m.alignment, &m.alignment_spread_m);
  m.n_gt = gt.size();
  m.n_outliers = rep.indices.size();
  m.outlier_indices = rep.indices;
  m.n_matched = a.n_matched;
  m.d_path_m = pathLength(est);
  if (!est.empty()) {
    m.loop_error_m = std::hypot(est.back().x_m - est.front().x_m, est.back().y_m - est.front().y_m);
  }
  if (a.n_matched == 0) return m;
  double dgt = 0.0;
  for (std::size_t k = 1; k < a.gt.size(); ++k) dgt += (a.gt[k] - a.gt[k - 1]).norm();
  m.d_path_gt_m = dgt;

  std::vector<double> e(a.n_matched);
  for (std::size_t k = 0; k < a.n_matched; ++k) e[k] = (a.est[k] - a.gt[k]).norm();
  const ErrorStats st = errorStats(e);
  m.ate_rmse_m = st.rmse;
  m.ate_mean_m = st.mean;
  m.ate_median_m = st.median;
  m.ate_max_m = st.max;
  m.ate_std_m = st.std;
  m.terminal_error_m = e.back();

  const auto r1 = rpeTranslationErrors(a, 1.0, o.rpe_pairs_from);
  const auto r5 = rpeTranslationErrors(a, 5.0, o.rpe_pairs_from);
  m.rpe_1m_m = errorStats(r1).rmse;
  m.rpe_5m_m = errorStats(r5).rmse;
  m.n_rpe_1m = r1.size();
  m.n_rpe_5m = r5.size();
  m.heading_drift_deg = headingDriftDeg(a, o, &m.heading_drift_method);
  return m;
}

std::string metricsCsvHeader() {
  return "name,d_path_m,d_path_gt_m,terminal_error_m,loop_error_m,ate_rmse_m,ate_mean_m,"
         "ate_median_m,ate_max_m,rpe_1m_m,rpe_5m_m,heading_drift_deg,n_matched,n_gt,n_outliers,"
         "alignment";
}

std::string metricsCsvRow(const std::string& name, const Metrics& m, Alignment alignment) {
  return fmt::format(
      "{},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},"
      "{:.9g},{},{},{},{}",
      name, m.d_path_m, m.d_path_gt_m, m.terminal_error_m, m.loop_error_m, m.ate_rmse_m,
      m.ate_mean_m, m.ate_median_m, m.ate_max_m, m.rpe_1m_m, m.rpe_5m_m, m.heading_drift_deg,
      m.n_matched, m.n_gt, m.n_outliers, toString(alignment));
}

void writeMetricsCsv(const std::string& path,
                     const std::vector<std::pair<std::string, Metrics>>& rows,
                     Alignment alignment) {
  std::string text = metricsCsvHeader() + "\n";
  for (const auto& [name, m] : rows) text += metricsCsvRow(name, m, alignment) + "\n";
  util::writeFileAtomically(path, text);
}

void writeEvoFiles(const std::string& prefix, const Trajectory& est,
                   const std::vector<Position2DStamped>& gt, const MetricOptions& o) {
  Association raw;
  const Association al = alignedAssociation(est, gt, o, nullptr, &raw);
  Trajectory g, e, ea;
  for (std::size_t k = 0; k < al.n_matched; ++k) {
    const double gphi = std::isfinite(al.gt_phi[k]) ? al.gt_phi[k] : al.est_phi[k];
    g.push_back({al.t[k], al.gt[k].x(), al.gt[k].y(), gphi});
    e.push_back({raw.t[k], raw.est[k].x(), raw.est[k].y(), raw.est_phi[k]});
    ea.push_back({al.t[k], al.est[k].x(), al.est[k].y(), al.est_phi[k]});
  }
  writeTum(prefix + "gt.tum", g);
  writeTum(prefix + "est.tum", e);
  writeTum(prefix + "est_aligned.tum", ea);
}

}  // namespace wheelchair::evaluation
