#include "libwheelchair/diagnosis/HeldOut.h"

#include "libwheelchair/stats/Distributions.h"

#include <Eigen/QR>

#include <algorithm>
#include <cmath>
#include <random>

namespace wheelchair::diagnosis {

double blockBootstrapProbNotPositive(const std::vector<double>& d, int block, int resamples,
                                     unsigned seed) {
  const int n = static_cast<int>(d.size());
  if (n == 0) return 1.0;
  const int b = std::clamp(block, 1, n);
  const int nb = (n + b - 1) / b;  // blocks per resample
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> start(0, n - 1);
  int not_positive = 0;
  for (int r = 0; r < resamples; ++r) {
    double sum = 0;
    int cnt = 0;
    for (int k = 0; k < nb; ++k) {
      const int s = start(rng);
      for (int q = 0; q < b && cnt < n; ++q, ++cnt) sum += d[(s + q) % n];
    }
    if (sum <= 0) ++not_positive;
  }
  return static_cast<double>(not_positive) / resamples;
}

namespace {
/// Solves the normal equations G b = h restricted to the columns `c` (least-squares sense).
Eigen::VectorXd solveSub(const Eigen::MatrixXd& G, const Eigen::VectorXd& h,
                         const std::vector<int>& c) {
  const int k = static_cast<int>(c.size());
  Eigen::MatrixXd Gs(k, k);
  Eigen::VectorXd hs(k);
  for (int a = 0; a < k; ++a) {
    hs(a) = h(c[a]);
    for (int b = 0; b < k; ++b) Gs(a, b) = G(c[a], c[b]);
  }
  return Gs.completeOrthogonalDecomposition().solve(hs);
}
}  // namespace

bool BlockedCvTerm::kept(double alpha) const {
  return testable && p_not_positive < alpha &&
         std::abs(coef) >= stats::normalQuantile(1 - alpha / 2) * coef_se;
}

nlohmann::json BlockedCvTerm::toJson() const {
  return {{"blocked_cv_mean_gain", mean_gain},
          {"blocked_cv_p_not_positive", p_not_positive},
          {"jackknife_sigma", coef_se}};
}

BlockedCvTerm blockedCvTerm(const Eigen::MatrixXd& A, const Eigen::VectorXd& y, int j, int blocks,
                            int boot_block) {
  return blockedCvTerm(
      [&A](Eigen::Index r0, Eigen::Index r1) { return Eigen::MatrixXd(A.middleRows(r0, r1 - r0)); },
      A.rows(), A.cols(), y, j, blocks, boot_block);
}

BlockedCvTerm blockedCvTerm(const CvRows& rowsOf, Eigen::Index n, Eigen::Index k,
                            const Eigen::VectorXd& y, int j, int blocks, int boot_block) {
  BlockedCvTerm r;
  const int K = std::max(2, blocks);
  if (j < 0 || j >= k || n != y.size() || n < 20 * K * std::max<Eigen::Index>(1, k)) return r;
  std::vector<Eigen::MatrixXd> Gb(K);
  std::vector<Eigen::VectorXd> hb(K);
  Eigen::MatrixXd G = Eigen::MatrixXd::Zero(k, k);
  Eigen::VectorXd h = Eigen::VectorXd::Zero(k);
  auto rows = [&](int b) {
    return std::pair<Eigen::Index, Eigen::Index>{n * b / K, n * (b + 1) / K};
  };
  for (int b = 0; b < K; ++b) {
    const auto [r0, r1] = rows(b);
    const Eigen::MatrixXd Ab = rowsOf(r0, r1);
    Gb[b] = Ab.transpose() * Ab;
    hb[b] = Ab.transpose() * y.segment(r0, r1 - r0);
    G += Gb[b], h += hb[b];
  }
  std::vector<int> all(k), without;
  for (int c = 0; c < k; ++c) {
    all[c] = c;
    if (c != j) without.push_back(c);
  }
  r.coef = solveSub(G, h, all)(j);
  std::vector<double> d(n), bj(K);
  for (int b = 0; b < K; ++b) {
    const auto [r0, r1] = rows(b);
    const Eigen::MatrixXd Go = G - Gb[b];
    const Eigen::VectorXd ho = h - hb[b];
    const Eigen::VectorXd b1 = solveSub(Go, ho, all);
    bj[b] = b1(j);
    Eigen::VectorXd b0 = Eigen::VectorXd::Zero(k);
    if (!without.empty()) {
      const Eigen::VectorXd s = solveSub(Go, ho, without);
      for (size_t c = 0; c < without.size(); ++c) b0(without[c]) = s(c);
    }
    const Eigen::MatrixXd A = rowsOf(r0, r1);  // this block's rows (row i: A.row(i - r0))
    for (Eigen::Index i = r0; i < r1; ++i) {
      const double e1 = y(i) - A.row(i - r0).dot(b1), e0 = y(i) - A.row(i - r0).dot(b0);
      d[i] = e0 * e0 - e1 * e1;
    }
  }
  double mean_b = 0, ss = 0;
  for (double x : bj) mean_b += x / K;
  for (double x : bj) ss += (x - mean_b) * (x - mean_b);
  r.coef_se = std::sqrt((K - 1.0) / K * ss);
  for (double x : d) r.mean_gain += x / n;
  r.p_not_positive = blockBootstrapProbNotPositive(d, boot_block);
  r.testable = true;
  return r;
}

const std::vector<std::string>& heldOutKeys() {
  static const std::vector<std::string> keys = {"validation_rms_rad",
                                                "validation_rms_A",
                                                "validation_rms_m_s",
                                                "validation_rms_rad_s",
                                                "validation_rms",
                                                "drift_10s_m",
                                                "drift_60s_m",
                                                "heading_drift_10s_deg",
                                                "heading_drift_60s_deg",
                                                "odometry_mean_position_error_m",
                                                "odometry_end_position_error_m",
                                                "odometry_end_heading_error_deg"};
  return keys;
}

int enforceHeldOutRule(DiagnosisReport& rep) {
  std::vector<Finding> kept;
  nlohmann::json rejected = rep.info.contains("rejected_heldout") ? rep.info["rejected_heldout"]
                                                                  : nlohmann::json::array();
  int removed = 0;
  for (auto& f : rep.findings) {
    std::vector<std::string> worse;
    for (const auto& k : heldOutKeys()) {
      if (!f.fit_before.contains(k) || !f.fit_after.contains(k)) continue;
      const auto &b = f.fit_before[k], &a = f.fit_after[k];
      if (!b.is_number() || !a.is_number()) continue;
      const double vb = b.get<double>(), va = a.get<double>();
      // Relative tolerance of rounding only: equal predictions are not "worse".
      if (std::isfinite(vb) && std::isfinite(va) && va > vb + 1e-9 * std::max(1.0, std::abs(vb)))
        worse.push_back(k);
    }
    // The stage's own check says the held-out data cannot test this term (predicted held-out
    // likelihood-ratio gain below its threshold, e.g. a gyro scale when the held-out part has
    // no turning): its held-out residual change is noise, neither better nor worse. Kept, and
    // said so.
    const bool untestable = f.evidence.contains("validation_tested") &&
                            f.evidence["validation_tested"].is_boolean() &&
                            !f.evidence["validation_tested"].get<bool>();
    if (untestable) {
      f.evidence["heldout"] = "not testable on the held-out data (it predicts no difference there)";
      worse.erase(
          std::remove_if(worse.begin(), worse.end(),
                         [](const std::string& k) { return k.rfind("validation_rms", 0) == 0; }),
          worse.end());
    }
    if (worse.empty()) {
      kept.push_back(std::move(f));
      continue;
    }
    ++removed;
    rejected.push_back({{"effect", f.effect},
                        {"analyser", f.command_response ? "command_response" : "diagnose"},
                        {"parameters", f.parameters},
                        {"reason", "its own held-out prediction gets worse"},
                        {"worse", worse},
                        {"fit_before", f.fit_before},
                        {"fit_after", f.fit_after}});
  }
  const bool had = !rep.findings.empty();
  rep.findings = std::move(kept);
  if (removed > 0) {
    rep.info["rejected_heldout"] = rejected;
    if (had && rep.findings.empty()) rep.mismatch = rep.info.contains("insufficient_data");
  }
  return removed;
}

}  // namespace wheelchair::diagnosis
