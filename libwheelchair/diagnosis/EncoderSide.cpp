#include "libwheelchair/diagnosis/EncoderSide.h"

#include <Eigen/Dense>

#include "libwheelchair/identification/OdometryCalibration.h"
#include "libwheelchair/stats/Distributions.h"

#include <algorithm>
#include <cmath>

namespace wheelchair::diagnosis {

using stats::fitLinear;
using stats::LinearFit;

namespace {

constexpr double kTruthRatio = 0.8;

int candidateIndex(const std::vector<Candidate>& cands, const std::string& name) {
  for (std::size_t i = 0; i < cands.size(); ++i)
    if (cands[i].name == name) return static_cast<int>(i);
  return -1;
}

// One explanation of the stage-1 residual: the accepted candidate set, its fit and the encoder
// scales (reported / true distance, right and left) it implies: k_i = g / (1 + b_g + b_i),
// g = 1 + b_g (Diagnosis.cpp, "coefficients"); 1 for a side without an encoder term.
struct Explanation {
  std::vector<int> accepted;
  LinearFit fit;
  double k[2] = {1, 1};
  double error_m = 0;
  std::string name;
};

Explanation explain(const KinRows& k, const std::vector<Candidate>& cands,
                    const std::vector<int>& accepted,
                    const std::vector<std::pair<int, int>>& ranges, int lags) {
  Explanation e;
  e.accepted = accepted;
  e.fit = fitLinear(acceptedDesign(k.X, cands, accepted), k.y, k.groups, lags);
  if (!e.fit.ok) return e;
  double bg = 0, b[2] = {0, 0};
  bool on[2] = {false, false};
  for (std::size_t a = 0; a < accepted.size(); ++a) {
    const auto& n = cands[accepted[a]].name;
    const double v = e.fit.beta(ranges[a].first);
    if (n == "gyro_scale") bg = v;
    if (n == "encoder_scale/right") b[0] = v, on[0] = true;
    if (n == "encoder_scale/left") b[1] = v, on[1] = true;
  }
  for (int s = 0; s < 2; ++s)
    if (on[s]) e.k[s] = (1 + bg) / (1 + bg + b[s]);
  e.name = std::string(bg != 0 ? "gyro_scale+" : "") + (on[0] ? "right" : "") +
           (on[0] && on[1] ? "+" : "") + (on[1] ? "left" : "");
  return e;
}

// The explanations the gyro cannot tell apart from the accepted one: one encoder swapped for
// the other; or, with both encoders and no gyro scale, either encoder swapped for a gyro
// scale.
std::vector<std::vector<int>> alternatives(const std::vector<Candidate>& cands,
                                           const std::vector<int>& accepted) {
  const int R = candidateIndex(cands, "encoder_scale/right");
  const int L = candidateIndex(cands, "encoder_scale/left");
  const int G = candidateIndex(cands, "gyro_scale");
  auto has = [&](int c) {
    return std::find(accepted.begin(), accepted.end(), c) != accepted.end();
  };
  auto replaced = [&](int from, int to) {
    std::vector<int> a = accepted;
    std::replace(a.begin(), a.end(), from, to);
    return a;
  };
  std::vector<std::vector<int>> out;
  if (R < 0 || L < 0) return out;
  if (has(R) != has(L)) out.push_back(has(R) ? replaced(R, L) : replaced(L, R));
  if (has(R) && has(L) && G >= 0 && !has(G)) {
    out.push_back(replaced(L, G));
    out.push_back(replaced(R, G));
  }
  return out;
}

std::vector<identification::OdometryRun> truthRuns(const std::vector<io::Recording>& fit,
                                                   double fit_fraction) {
  std::vector<identification::OdometryRun> runs;
  for (const auto& r : fit) {
    if (r.ground_truth.size() < 8 || r.encoders.size() < 8) continue;
    auto run = identification::odometryRun(r);
    if (run.size() >= 8 && fit_fraction < 1) {
      const double t0 = run.t_s.front();
      run = identification::cropRun(run, t0, t0 + fit_fraction * (run.t_s.back() - t0));
    }
    if (run.size() >= 8) runs.push_back(std::move(run));
  }
  return runs;
}

// RMS (A) of the motor-current equation error on the fit data with this explanation's encoder
// scales applied, after the least-squares fit of every dynamic catalogue column (asymmetry,
// Coulomb, payload, slope, delay): what the dynamics cannot explain with either side.
double dynamicsRms(const std::vector<Streams>& fitS, const Explanation& e,
                   const config::WheelchairConfig& cfg, const DiagnosisOptions& opt) {
  Corrections c;
  c.enc_scale[0] = e.k[0];
  c.enc_scale[1] = e.k[1];
  const DynRows r = dynamicRows(fitS, c, cfg, opt);
  if (r.y.size() < 50) return std::nan("");
  const Eigen::MatrixXd X = r.design().matrix();
  const Eigen::VectorXd b = X.colPivHouseholderQr().solve(r.y);
  return std::sqrt((r.y - X * b).squaredNorm() / r.y.size());
}

}  // namespace

EncoderSideDecision resolveEncoderSide(const std::vector<io::Recording>& fit, double fit_fraction,
                                       const config::WheelchairConfig& cfg, const KinRows& k,
                                       const std::vector<Candidate>& cands, Selection& sel,
                                       int lags, double alpha_b,
                                       const std::vector<Streams>* dyn_fit,
                                       const DiagnosisOptions* opt) {
  EncoderSideDecision d;
  const auto alts = alternatives(cands, sel.accepted);
  if (alts.empty() || k.X.rows() == 0) return d;
  std::vector<Explanation> ex = {explain(k, cands, sel.accepted, sel.ranges, lags)};
  if (!ex[0].fit.ok) return d;
  double var = 0;
  for (int i = 0; i < k.X.rows(); ++i)
    var += k.noise_var_per_s * (k.t1[i] - k.t0[i]) + k.noise_var_const;
  var /= k.X.rows();
  const double needed = stats::chi2Quantile(1 - alpha_b, 1);
  nlohmann::json gyro = nlohmann::json::object();
  for (const auto& a : alts) {
    Explanation e = explain(k, cands, a, sel.ranges, lags);
    const double lr = var > 0 && e.fit.ok ? (e.fit.rss - ex[0].fit.rss) / var : 1e9;
    gyro[e.name] = lr;
    if (lr < needed) ex.push_back(std::move(e));  // the gyro cannot rule it out
  }
  if (ex.size() < 2) return d;  // the gyro decides
  const auto runs = truthRuns(fit, fit_fraction);
  const bool by_truth = !runs.empty();
  if (!by_truth && !(dyn_fit && opt)) return d;
  const auto nominal = identification::odometryGeometry(cfg);
  std::size_t best = 0;
  nlohmann::json err = nlohmann::json::object(), scale = nlohmann::json::object();
  for (std::size_t i = 0; i < ex.size(); ++i) {
    if (by_truth) {
      auto g = nominal;
      g.m_per_tick_right /= ex[i].k[0];
      g.m_per_tick_left /= ex[i].k[1];
      ex[i].error_m = identification::meanOdometryError(runs, g).mean_position_m;
    } else {
      ex[i].error_m = dynamicsRms(*dyn_fit, ex[i], cfg, *opt);
    }
    err[ex[i].name] = ex[i].error_m;
    scale[ex[i].name] = {{"right", ex[i].k[0]}, {"left", ex[i].k[1]}};
    if (ex[i].error_m < ex[best].error_m) best = i;
  }
  if (!std::isfinite(ex[best].error_m)) return d;
  // Decided when the best predicts 20 % better than every other; or when all explanations
  // within that margin put the large encoder error on the same side (then only a small
  // remainder -- the other encoder or the gyro scale -- is ambiguous: `near_tie`).
  auto majorSide = [](const Explanation& e) {
    return std::abs(e.k[0] - 1) >= std::abs(e.k[1] - 1) ? 0 : 1;
  };
  d.decided = true;
  nlohmann::json near = nlohmann::json::array();
  for (std::size_t i = 0; i < ex.size(); ++i) {
    if (i == best || ex[best].error_m <= kTruthRatio * ex[i].error_m) continue;
    near.push_back(ex[i].name);
    if (majorSide(ex[i]) != majorSide(ex[best])) d.decided = false;
  }
  d.evidence = {
      {"gyro_likelihood_ratio", gyro},
      {"gyro_needed", needed},
      {"runs", runs.size()},
      {"by", by_truth ? "ground_truth" : "dynamics"},
      {by_truth ? "mean_position_error_m" : "current_residual_rms_A", err},
      {"encoder_scales", scale},
      {"no_encoder_correction_m",
       by_truth ? identification::meanOdometryError(runs, nominal).mean_position_m : std::nan("")},
      {"ratio_needed", kTruthRatio},
      {"decided", d.decided},
      {"near_tie", near},
      {"explanation", d.decided ? ex[best].name : "undecided"}};
  if (d.decided && best != 0) {
    sel.accepted = ex[best].accepted;
    sel.fit = ex[best].fit;
  }
  return d;
}

namespace {

/// Cumulative trapezoid integral of x over the sorted times t, read at time q (linear inside a
/// sample interval; clamped to the ends).
struct CumulativeIntegral {
  std::vector<double> t, I;
  CumulativeIntegral(const std::vector<double>& tt, const std::vector<double>& x) : t(tt) {
    I.assign(t.size(), 0.0);
    for (std::size_t k = 1; k < t.size(); ++k)
      I[k] = I[k - 1] + 0.5 * (x[k] + x[k - 1]) * (t[k] - t[k - 1]);
  }
  double at(double q) const {
    auto it = std::upper_bound(t.begin(), t.end(), q);
    if (it == t.begin()) return I.front();
    if (it == t.end()) return I.back();
    const std::size_t k = static_cast<std::size_t>(it - t.begin());
    const double w = (q - t[k - 1]) / std::max(1e-12, t[k] - t[k - 1]);
    return I[k - 1] + w * (I[k] - I[k - 1]);
  }
};

}  // namespace

GyroTruthDecision gyroScaleAgainstTruth(const std::vector<Streams>& fit, double delay_imu_s,
                                        double b_stage1, double sd_stage1,
                                        const Eigen::VectorXd& gyro_col,
                                        double min_contribution_rms, double alpha_b) {
  GyroTruthDecision d;
  d.b_stage1 = b_stage1;
  std::vector<double> y, dpsi, T;
  stats::Groups groups;
  for (const Streams& s : fit) {
    if (s.gt.size() < 8 || !s.hasGyro()) continue;
    const CumulativeIntegral G(s.tg, s.gz);
    const int first = static_cast<int>(y.size());
    std::size_t i = 0;
    for (std::size_t j = 1; j < s.gt.size(); ++j) {
      const double t0 = s.gt[i].t_s, t1 = s.gt[j].t_s;
      if (t1 - t0 < kGyroTruthWindow_s) continue;
      const double q0 = t0 + delay_imu_s, q1 = t1 + delay_imu_s;
      if (q0 >= s.tg.front() && q1 <= s.tg.back()) {
        double dp = 0;  // unwrapped truth heading change over the window
        for (std::size_t k = i + 1; k <= j; ++k)
          dp += std::remainder(s.gt[k].phi_rad - s.gt[k - 1].phi_rad, 2 * M_PI);
        y.push_back(G.at(q1) - G.at(q0) - dp);
        dpsi.push_back(dp);
        T.push_back(t1 - t0);
      }
      i = j;
    }
    if (static_cast<int>(y.size()) > first) groups.push_back({first, static_cast<int>(y.size())});
  }
  const int n = static_cast<int>(y.size());
  double turned = 0;
  for (double p : dpsi) turned += std::abs(p);
  // too little turning to measure a scale at all (how well it is measured: sd_b)
  if (n < 20 || turned < kGyroTruthMinTurn_rad) return d;
  Eigen::MatrixXd X(n, 2);
  Eigen::VectorXd yy(n);
  for (int k = 0; k < n; ++k) X(k, 0) = dpsi[k], X(k, 1) = T[k], yy(k) = y[k];
  const LinearFit f = fitLinear(X, yy, groups, 5);
  if (!f.ok) return d;
  d.tested = true;
  d.b = f.beta(0);
  d.sd_b = std::sqrt(std::max(0.0, f.cov(0, 0)));
  const double z = std::sqrt(stats::chi2Quantile(1 - alpha_b, 1));
  // The two estimates are independent measurements of different things only under the
  // alternative; under "stage 1 measured the gyro" both estimate b: their difference has the
  // variance of both.
  const double sd_diff = std::hypot(d.sd_b, sd_stage1);
  const bool consistent = std::abs(d.b - b_stage1) < z * sd_diff;
  const double contribution =
      gyro_col.size() ? std::abs(d.b) * gyro_col.norm() / std::sqrt(double(gyro_col.size())) : 0;
  const bool significant = std::abs(d.b) >= z * d.sd_b;
  const bool relevant = contribution >= min_contribution_rms;
  // the truth can tell "the gyro is off by b1" from "the gyro is right" only if b1 is
  // outside the difference's uncertainty; otherwise stage 1 stands (and the ambiguity is said)
  const bool informative = std::abs(b_stage1) >= z * sd_diff;
  std::string verdict;
  if (!informative) {
    d.tested = false;
    verdict = "truth_not_informative";
  } else if (!(significant && relevant)) {
    verdict = "encoder_geometry";
  } else if (consistent) {
    d.report = true;
    verdict = "confirmed";
  } else {
    d.report = true, d.use_truth_value = true;
    verdict = "gyro_and_encoder_geometry";
  }
  d.evidence = {{"windows", n},
                {"window_s", kGyroTruthWindow_s},
                {"turned_rad", turned},
                {"scale_vs_truth", 1 + d.b},
                {"scale_vs_truth_sd", d.sd_b},
                {"scale_vs_encoders", 1 + b_stage1},
                {"scale_vs_encoders_sd", sd_stage1},
                {"z_needed", z},
                {"contribution_rms_rad", contribution},
                {"min_contribution_rms_rad", min_contribution_rms},
                {"verdict", verdict}};
  return d;
}

}  // namespace wheelchair::diagnosis
