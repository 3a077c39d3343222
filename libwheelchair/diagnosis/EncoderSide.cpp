#include "libwheelchair/diagnosis/EncoderSide.h"

#include "libwheelchair/identification/OdometryCalibration.h"
#include "libwheelchair/stats/Distributions.h"

#include <algorithm>

namespace wheelchair::diagnosis {

namespace {

constexpr double kTruthRatio = 0.8;

int candidateIndex(const std::vector<Candidate>& cands, const std::string& name) {
  for (std::size_t i = 0; i < cands.size(); ++i)
    if (cands[i].name == name) return static_cast<int>(i);
  return -1;
}

// Encoder scale (reported / true distance) of the accepted encoder candidate of a stage-1 fit:
// k = g / (1 + b_g + b_enc) with g = 1 + b_g (Diagnosis.cpp, "coefficients").
double encoderScale(const std::vector<Candidate>& cands, const std::vector<int>& accepted,
                    const std::vector<std::pair<int, int>>& ranges, const Eigen::VectorXd& beta,
                    int enc_pos) {
  double bg = 0;
  for (std::size_t a = 0; a < accepted.size(); ++a)
    if (cands[accepted[a]].name == "gyro_scale") bg = beta(ranges[a].first);
  const double be = beta(ranges[enc_pos].first);
  return (1 + bg) / (1 + bg + be);
}

}  // namespace

EncoderSideDecision resolveEncoderSideByGroundTruth(const std::vector<io::Recording>& fit,
                                                    double fit_fraction,
                                                    const config::WheelchairConfig& cfg,
                                                    const KinRows& k,
                                                    const std::vector<Candidate>& cands,
                                                    Selection& sel, int lags, double alpha_b) {
  EncoderSideDecision d;
  int pos = -1;
  for (std::size_t a = 0; a < sel.accepted.size(); ++a)
    if (cands[sel.accepted[a]].effect == "encoder_scale") pos = static_cast<int>(a);
  if (pos < 0) return d;
  const int chosen = sel.accepted[pos];
  const bool chosen_right = cands[chosen].name == "encoder_scale/right";
  const int other =
      candidateIndex(cands, chosen_right ? "encoder_scale/left" : "encoder_scale/right");
  if (other < 0) return d;
  std::vector<int> swapped = sel.accepted;
  swapped[pos] = other;
  const LinearFit a = fitLinear(acceptedDesign(k.X, cands, sel.accepted), k.y, k.groups, lags);
  const LinearFit b = fitLinear(acceptedDesign(k.X, cands, swapped), k.y, k.groups, lags);
  if (!a.ok || !b.ok || k.X.rows() == 0) return d;
  double var = 0;
  for (int i = 0; i < k.X.rows(); ++i)
    var += k.noise_var_per_s * (k.t1[i] - k.t0[i]) + k.noise_var_const;
  var /= k.X.rows();
  const double lr = var > 0 ? (b.rss - a.rss) / var : 0.0;
  const double needed = stats::chi2Quantile(1 - alpha_b, 1);
  if (lr >= needed) return d;  // the gyro decides

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
  if (runs.empty()) return d;
  const auto nominal = identification::odometryGeometry(cfg);
  auto errorWith = [&](bool right, double scale) {
    auto g = nominal;
    (right ? g.m_per_tick_right : g.m_per_tick_left) /= scale;
    return identification::meanOdometryError(runs, g).mean_position_m;
  };
  const double ka = encoderScale(cands, sel.accepted, sel.ranges, a.beta, pos);
  const double kb = encoderScale(cands, swapped, sel.ranges, b.beta, pos);
  const double ea = errorWith(chosen_right, ka), eb = errorWith(!chosen_right, kb);
  const double e_none = identification::meanOdometryError(runs, nominal).mean_position_m;
  d.decided = std::min(ea, eb) <= kTruthRatio * std::max(ea, eb);
  const bool take_other = d.decided && eb < ea;
  const char* side_a = chosen_right ? "right" : "left";
  const char* side_b = chosen_right ? "left" : "right";
  d.evidence = {
      {"gyro_likelihood_ratio", lr},
      {"gyro_needed", needed},
      {"runs", runs.size()},
      {"mean_position_error_m", {{side_a, ea}, {side_b, eb}, {"no_encoder_correction", e_none}}},
      {"scale", {{side_a, ka}, {side_b, kb}}},
      {"ratio_needed", kTruthRatio},
      {"decided", d.decided},
      {"side", d.decided ? (take_other ? side_b : side_a) : "undecided"}};
  if (take_other) {
    sel.accepted = swapped;
    sel.fit = b;
  }
  return d;
}

}  // namespace wheelchair::diagnosis
