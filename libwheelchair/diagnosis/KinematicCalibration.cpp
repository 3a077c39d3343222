#include "libwheelchair/diagnosis/KinematicCalibration.h"
#include "libwheelchair/stats/Descriptive.h"
#include "libwheelchair/stats/Distributions.h"

#include <Eigen/Dense>

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>

namespace wheelchair::diagnosis {

namespace {

using identification::OdometryGeometry;
using identification::OdometryRun;
using identification::TrajectoryFit;

struct CandidateModel {
  const char* name;
  TrajectoryFit fit;
  bool heading_first = false;  ///< heading rates from heading increments, then the fit
  /// every kinematic parameter from increments (the two-step least squares; the whole-run fit
  /// adds only the travel angle, a rotation of the path about its start)
  bool increment_domain = false;
};

OdometryGeometry fitModel(const CandidateModel& m, const std::vector<OdometryRun>& runs,
                          const OdometryGeometry& nominal) {
  OdometryGeometry start = nominal;
  if (m.heading_first) {
    start = identification::leastSquaresCalibration(runs, 1.0);
    start.lever_x_m = nominal.lever_x_m, start.lever_y_m = nominal.lever_y_m;
  }
  TrajectoryFit f = m.fit;
  f.travel_angle = true;
  return identification::trajectoryCalibration(runs, start, f);
}

std::vector<CandidateModel> candidateModels() {
  std::vector<CandidateModel> c(5);
  c[0] = {"track", {}};
  c[0].fit.free = {false, false, true};
  c[1] = {"scale", {}};
  c[1].fit.free = {true, true, false}, c[1].fit.common_scale = true;
  c[2] = {"scale+track", {}};
  c[2].fit.free = {true, true, true}, c[2].fit.common_scale = true;
  c[3] = {"wheels", {}};
  c[3].fit.free = {true, true, false};
  c[4] = {"wheels+track", {}};
  {
    CandidateModel h{"heading+scale", {}, true};
    h.fit.free = {false, false, false}, h.fit.uniform_scale = true;
    c.push_back(h);
    CandidateModel h2{"heading-ls", {}, true, true};
    h2.fit.free = {false, false, false};
    c.push_back(h2);
  }
  return c;
}

double rel(double a, double b) {
  return a / b - 1;
}

/// Fit units: one per recording, or 4 time blocks of a single recording.
std::vector<OdometryRun> fitUnits(const std::vector<OdometryRun>& runs) {
  if (runs.size() >= 2) return runs;
  std::vector<OdometryRun> out;
  for (const auto& r : runs) {
    if (r.size() < 8) continue;
    const double t0 = r.t_s.front(), T = r.t_s.back() - t0;
    for (int k = 0; k < 4; ++k)
      out.push_back(identification::cropRun(r, t0 + k * T / 4, t0 + (k + 1) * T / 4));
  }
  return out;
}

/// Delete-a-group jackknife 1-sigma of the leave-one-fold-out estimates x_k (K folds):
/// sqrt((K - 1) / K sum (x_k - mean)^2); `mean` (optional) receives their mean.
double jackknifeSd(const std::vector<double>& x, double* mean = nullptr) {
  const double K = static_cast<double>(x.size());
  double m = 0, ss = 0;
  for (double v : x) m += v / K;
  for (double v : x) ss += (v - m) * (v - m);
  if (mean) *mean = m;
  return K > 1 ? std::sqrt((K - 1) / K * ss) : 0.0;
}

/// Turn gain: heading per tick of wheel-tick difference, (k_R + k_L) / (2 b) (rad/tick).
double turnGain(const OdometryGeometry& g) {
  return 0.5 * (g.m_per_tick_right + g.m_per_tick_left) / g.track_m;
}

/// Specification check (header: "misspecification"): the best whole-run candidate (by CV; not
/// "heading+scale", whose turn gain is the increments') against the increment-domain candidate,
/// the fold-wise relative difference of their turn gains, delete-a-group jackknife over the folds.
void checkSpecification(const std::vector<CandidateModel>& models, const std::vector<double>& cv,
                        const std::vector<std::vector<OdometryGeometry>>& foldFits,
                        KinematicCalibration& kc) {
  int bw = -1, bi = -1;
  for (std::size_t m = 0; m < models.size(); ++m) {
    if (models[m].heading_first && !models[m].increment_domain) continue;  // keeps the gain
    int& b = models[m].increment_domain ? bi : bw;
    if (b < 0 || cv[m] < cv[b]) b = static_cast<int>(m);
  }
  if (bw < 0 || bi < 0) return;
  const auto& A = foldFits[bw];
  const auto& B = foldFits[bi];
  const int K = static_cast<int>(A.size());
  std::vector<double> d(K);
  for (int k = 0; k < K; ++k) d[k] = turnGain(A[k]) / turnGain(B[k]) - 1;
  double mean = 0;
  const double sd = jackknifeSd(d, &mean);
  kc.gain_difference_rel = mean, kc.gain_difference_sd = sd;
  kc.whole_run_model = models[bw].name, kc.increment_model = models[bi].name;
  // significant (z) and larger than the resolution of a reported correction
  kc.whole_run_misspecified =
      std::abs(mean) > kMaxGainDisagreementZ * sd && std::abs(mean) >= kMinRelativeChange;
}

/// 1-sigma of the chosen candidate's relative corrections and travel angle from its fold fits.
void jackknifeUncertainty(const std::vector<OdometryGeometry>& F, KinematicCalibration& kc) {
  const auto& n = kc.nominal;
  std::vector<double> x[4];
  for (const auto& g : F) {
    x[0].push_back(rel(g.m_per_tick_right, n.m_per_tick_right));
    x[1].push_back(rel(g.m_per_tick_left, n.m_per_tick_left));
    x[2].push_back(rel(g.track_m, n.track_m));
    x[3].push_back(g.travel_angle_rad);
  }
  for (int p = 0; p < 3; ++p) kc.sd_rel[p] = jackknifeSd(x[p]);
  kc.sd_travel_angle_rad = jackknifeSd(x[3]);
}

std::string percentText(double d, double sd, const char* more, const char* less) {
  return fmt::format("{:.2f} % {} (+- {:.2f} %)", std::abs(d) * 100, d >= 0 ? more : less,
                     sd * 100);
}

/// The fit and validation runs (encoders + ground truth, >= 8 samples): with no --validate
/// recordings the first fit_fraction of each recording is fitted and the rest held out.
void splitRuns(const std::vector<io::Recording>& fit, const std::vector<io::Recording>& val,
               const DiagnosisOptions& opt, std::vector<OdometryRun>& fitRuns,
               std::vector<OdometryRun>& valRuns) {
  for (std::size_t i = 0; i < fit.size(); ++i) {
    OdometryRun r = identification::odometryRun(fit[i], fmt::format("fit {}", i + 1));
    if (r.size() < 8) continue;
    if (val.empty()) {
      const double tc = r.t_s.front() + opt.fit_fraction * (r.t_s.back() - r.t_s.front());
      fitRuns.push_back(identification::cropRun(r, r.t_s.front(), tc));
      valRuns.push_back(identification::cropRun(r, tc, r.t_s.back()));
    } else {
      fitRuns.push_back(r);
    }
  }
  for (std::size_t i = 0; i < val.size(); ++i) {
    OdometryRun r = identification::odometryRun(val[i], fmt::format("validate {}", i + 1));
    if (r.size() >= 8) valRuns.push_back(r);
  }
}

/// K-fold cross-validation of every candidate model against the nominal geometry (mean
/// position error on the left-out folds; kc.candidates records each). Returns the best
/// candidate that beats nominal by kMinCvGain, or -1; foldFits[m] holds model m's fold fits.
int crossValidate(const std::vector<CandidateModel>& models,
                  const std::vector<std::vector<OdometryRun>>& train,
                  const std::vector<std::vector<OdometryRun>>& test, KinematicCalibration& kc,
                  std::vector<std::vector<OdometryGeometry>>& foldFits) {
  const int K = static_cast<int>(test.size());
  double cv_nominal = 0;
  for (int k = 0; k < K; ++k)
    cv_nominal += identification::meanOdometryError(test[k], kc.nominal).mean_position_m / K;
  std::vector<double> cv(models.size(), 0.0);
  for (std::size_t m = 0; m < models.size(); ++m) {
    for (int k = 0; k < K; ++k) {
      const auto g = fitModel(models[m], train[k], kc.nominal);
      foldFits[m].push_back(g);
      cv[m] += identification::meanOdometryError(test[k], g).mean_position_m / K;
    }
    double mean[3] = {0, 0, 0};  // the fold fits' mean relative corrections (evidence)
    for (const auto& g : foldFits[m]) {
      mean[0] += rel(g.m_per_tick_right, kc.nominal.m_per_tick_right) / K;
      mean[1] += rel(g.m_per_tick_left, kc.nominal.m_per_tick_left) / K;
      mean[2] += rel(g.track_m, kc.nominal.track_m) / K;
    }
    kc.candidates.push_back({{"model", models[m].name},
                             {"cv_mean_position_error_m", cv[m]},
                             {"folds_radius_right_rel", mean[0]},
                             {"folds_radius_left_rel", mean[1]},
                             {"folds_track_rel", mean[2]}});
  }
  kc.candidates.push_back({{"model", "nominal"}, {"cv_mean_position_error_m", cv_nominal}});
  // a whole-run fit that disagrees with the increments is misspecified: only increment-domain
  // candidates may then be chosen (checkSpecification)
  checkSpecification(models, cv, foldFits, kc);
  int best = -1;
  double best_cv = (1 - kMinCvGain) * cv_nominal;
  for (std::size_t m = 0; m < models.size(); ++m)
    if (cv[m] < best_cv && (models[m].increment_domain || !kc.whole_run_misspecified))
      best_cv = cv[m], best = static_cast<int>(m);
  return best;
}

/// Whether the refitted geometry is reported: it changes a parameter by kMinRelativeChange,
/// lowers the held-out mean position error by kMinHeldOutGain and makes neither the end
/// position nor the end heading worse; otherwise kc.rejected says why.
void judgeRefit(KinematicCalibration& kc) {
  // relative changes; the travel angle in rad (1e-3 rad: 1 mm sideways per metre driven)
  const double change =
      std::max({std::abs(rel(kc.fitted.m_per_tick_right, kc.nominal.m_per_tick_right)),
                std::abs(rel(kc.fitted.m_per_tick_left, kc.nominal.m_per_tick_left)),
                std::abs(rel(kc.fitted.track_m, kc.nominal.track_m)),
                std::abs(kc.fitted.travel_angle_rad - kc.nominal.travel_angle_rad)});
  const bool better =
      kc.heldout_after.mean_position_m < (1 - kMinHeldOutGain) * kc.heldout_before.mean_position_m;
  // held-out rule (issue 16): neither the end position nor the end heading (the quantity the
  // track and the radius ratio set) may get worse either
  const bool not_worse = kc.heldout_after.end_position_m <= kc.heldout_before.end_position_m &&
                         kc.heldout_after.end_heading_rad <= kc.heldout_before.end_heading_rad;
  kc.accepted = change >= kMinRelativeChange && better && not_worse;
  if (better && !not_worse)
    kc.rejected = fmt::format(
        "the {} correction lowers the held-out mean position error ({:.4f} m -> {:.4f} m) but "
        "makes the end position ({:.4f} m -> {:.4f} m) or the end heading ({:.2f} deg -> "
        "{:.2f} deg) worse: not reported",
        kc.model, kc.heldout_before.mean_position_m, kc.heldout_after.mean_position_m,
        kc.heldout_before.end_position_m, kc.heldout_after.end_position_m,
        kc.heldout_before.end_heading_rad * 180 / M_PI,
        kc.heldout_after.end_heading_rad * 180 / M_PI);
  else if (!better)
    kc.rejected = fmt::format(
        "the {} correction fitted on the fit data does not lower the held-out odometry error "
        "by {:.0f} % ({:.4f} m -> {:.4f} m): not reported",
        kc.model, 100 * kMinHeldOutGain, kc.heldout_before.mean_position_m,
        kc.heldout_after.mean_position_m);
  else if (!kc.accepted)
    kc.rejected = fmt::format(
        "the {} correction changes no parameter by {:.1f} % or more (largest {:.4f} %): within "
        "the resolution, not reported",
        kc.model, 100 * kMinRelativeChange, 100 * change);
}

/// Name of a whole-run candidate with these free parameters (right, left, track).
const char* restrictedName(const TrajectoryFit& f) {
  const bool wheels = f.free[0] || f.free[1], track = f.free[2];
  if (!wheels) return track ? "track" : "travel_angle";
  if (f.common_scale) return track ? "scale+track" : "scale";
  return track ? "wheels+track" : "wheels";
}

/// The chosen whole-run candidate without the geometry parameters its own fold fits do not
/// establish (|relative change| < kEstablishedZ x its jackknife 1-sigma: inside the
/// uncertainty, so the held-out gain is not theirs): refitted on all fit data with those
/// parameters at the nominal geometry (the travel angle stays free), its fold fits redone for
/// the uncertainty, and judged again (judgeRefit). Increment-domain candidates are left as
/// they are. E.g. "wheels" with radii -0.05 % +- 0.05 % and a travel angle 0.12 deg: the
/// travel angle alone ("travel_angle"). Returns false when nothing was restricted.
bool restrictToEstablished(const CandidateModel& chosen, const std::vector<OdometryRun>& fitRuns,
                           const std::vector<OdometryRun>& valRuns,
                           const std::vector<std::vector<OdometryRun>>& train,
                           KinematicCalibration& kc) {
  if (chosen.heading_first) return false;
  const auto& n = kc.nominal;
  const double d[3] = {rel(kc.fitted.m_per_tick_right, n.m_per_tick_right),
                       rel(kc.fitted.m_per_tick_left, n.m_per_tick_left),
                       rel(kc.fitted.track_m, n.track_m)};
  CandidateModel m = chosen;
  bool restricted = false;
  for (int p = 0; p < 3; ++p) {
    if (!m.fit.free[p] || std::abs(d[p]) >= kEstablishedZ * kc.sd_rel[p]) continue;
    m.fit.free[p] = false, restricted = true;
  }
  if (!restricted) return false;
  if (m.fit.common_scale && !(m.fit.free[0] && m.fit.free[1]))
    m.fit.free[0] = m.fit.free[1] = false, m.fit.common_scale = false;
  m.name = restrictedName(m.fit);
  kc.rejected_parameters = fmt::format(
      "{}: radius right {:+.3f} % (+- {:.3f} %), left {:+.3f} % (+- {:.3f} %), track {:+.3f} % "
      "(+- {:.3f} %); the parameters within {:.0f} sigma are left at the configured geometry "
      "({})",
      kc.model, 100 * d[0], 100 * kc.sd_rel[0], 100 * d[1], 100 * kc.sd_rel[1], 100 * d[2],
      100 * kc.sd_rel[2], kEstablishedZ, m.name);
  kc.model = m.name;
  kc.fitted = fitModel(m, fitRuns, n);
  kc.heldout_after = identification::meanOdometryError(valRuns, kc.fitted);
  kc.rejected.clear();
  judgeRefit(kc);
  std::vector<OdometryGeometry> folds;
  for (const auto& t : train) folds.push_back(fitModel(m, t, n));
  jackknifeUncertainty(folds, kc);
  return true;
}

}  // namespace

nlohmann::json slopeYawCreep(const std::vector<OdometryRun>& runs, const OdometryGeometry& g,
                             double downhill_rad, double alpha) {
  std::vector<std::array<double, 4>> rows;  // y, dphi_odo, T, sin(h - phi) T
  for (const auto& r : runs) {
    std::size_t i0 = 0;
    for (std::size_t i = 1; i < r.size(); ++i) {
      const double T = r.t_s[i] - r.t_s[i0];
      if (T < 1.0) continue;
      const double odo = (g.m_per_tick_right * (r.ticks_right[i] - r.ticks_right[i0]) -
                          g.m_per_tick_left * (r.ticks_left[i] - r.ticks_left[i0])) /
                         g.track_m;
      const double phi = r.phi_rad[(i0 + i) / 2] - r.phi_rad.front();
      rows.push_back(
          {r.phi_rad[i] - r.phi_rad[i0] - odo, odo, T, std::sin(downhill_rad - phi) * T});
      i0 = i;
    }
  }
  const int n = static_cast<int>(rows.size());
  if (n < 12) return nullptr;
  Eigen::MatrixXd X(n, 3);
  Eigen::VectorXd y(n);
  for (int k = 0; k < n; ++k) y(k) = rows[k][0], X.row(k) << rows[k][1], rows[k][2], rows[k][3];
  auto fit = [&](int cols, Eigen::VectorXd& beta) {
    const Eigen::MatrixXd A = X.leftCols(cols);
    beta = A.colPivHouseholderQr().solve(y);
    return (y - A * beta).squaredNorm();
  };
  Eigen::VectorXd b0, b1;
  const double rss0 = fit(2, b0), rss1 = fit(3, b1);
  const double lr = n * std::log(rss0 / std::max(1e-300, rss1));
  const double needed = stats::chi2Quantile(1 - alpha, 1);
  return {{"windows", n},
          {"likelihood_ratio", lr},
          {"needed", needed},
          {"creep_rad_s", b1(2)},
          {"turn_gain_rel_without", b0(0)},
          {"turn_gain_rel_with", b1(0)},
          {"significant", lr >= needed}};
}

KinematicCalibration calibrateKinematics(const std::vector<io::Recording>& fit,
                                         const std::vector<io::Recording>& val,
                                         const config::WheelchairConfig& cfg,
                                         const DiagnosisOptions& opt, const Corrections* stage1,
                                         double slope_downhill_rad) {
  KinematicCalibration kc;
  kc.nominal = identification::odometryGeometry(cfg);
  if (stage1) {  // reported / true distance: the true metres per tick are k / scale
    kc.nominal.m_per_tick_right /= stage1->enc_scale[0];
    kc.nominal.m_per_tick_left /= stage1->enc_scale[1];
  }
  std::vector<OdometryRun> fitRuns, valRuns;
  splitRuns(fit, val, opt, fitRuns, valRuns);
  kc.validation = val.empty() ? fmt::format("held-out last {:.0f}% of each recording",
                                            100 * (1 - opt.fit_fraction))
                              : fmt::format("{} --validate recording(s)", val.size());
  if (fitRuns.empty() || valRuns.empty()) {
    kc.not_tested =
        "no recording with both wheel encoders and ground-truth poses (motion capture): the "
        "odometric geometry (wheel radii, track) was not calibrated";
    return kc;
  }
  // timing nuisance: the fit runs' truth re-sampled at the encoder-lag-corrected times
  for (auto& r : fitRuns) {
    const double d = identification::estimateTimeOffset(r, kc.nominal);
    kc.lags_s.push_back(d);
    r = identification::shiftTruth(r, d);
  }
  kc.tested = true;
  kc.fit_runs = static_cast<int>(fitRuns.size());
  kc.validation_runs = static_cast<int>(valRuns.size());

  // ---- choose a candidate by k-fold cross-validation over the fit units
  const std::vector<OdometryRun> units = fitUnits(fitRuns);
  const int K = std::min<int>(10, static_cast<int>(units.size()));
  kc.folds = K;
  if (K < 2) {
    kc.tested = false;
    kc.not_tested = "too little encoder + ground-truth data for cross-validation (< 2 blocks)";
    return kc;
  }
  // contiguous folds: recordings given together (one experiment) stay in one fold
  auto foldOf = [&](std::size_t u) { return static_cast<int>(u * K / units.size()); };
  std::vector<std::vector<OdometryRun>> train(K), test(K);
  for (std::size_t u = 0; u < units.size(); ++u)
    for (int k = 0; k < K; ++k) (foldOf(u) == k ? test : train)[k].push_back(units[u]);
  const auto models = candidateModels();
  std::vector<std::vector<OdometryGeometry>> foldFits(models.size());
  const int best = crossValidate(models, train, test, kc, foldFits);
  kc.heldout_before = identification::meanOdometryError(valRuns, kc.nominal);
  kc.heldout_after = kc.heldout_before;
  if (best < 0) return kc;  // no candidate predicts left-out fit data better than nominal

  // ---- refit on all fit data; keep only if the held-out prediction improves
  kc.model = models[best].name;
  kc.fitted = fitModel(models[best], fitRuns, kc.nominal);
  kc.heldout_after = identification::meanOdometryError(valRuns, kc.fitted);
  judgeRefit(kc);
  jackknifeUncertainty(foldFits[best], kc);
  if (kc.accepted) restrictToEstablished(models[best], fitRuns, valRuns, train, kc);
  if (kc.accepted && std::isfinite(slope_downhill_rad)) {
    kc.slope_creep = slopeYawCreep(fitRuns, kc.nominal, slope_downhill_rad, opt.alpha);
    if (!kc.slope_creep.is_null() && kc.slope_creep["significant"].get<bool>()) {
      kc.accepted = false;
      kc.rejected = fmt::format(
          "the {} correction is not reported: the chair's heading creeps on the slope the "
          "dynamics named ({:+.4f} rad/s x sin(downhill - heading), likelihood ratio {:.1f} >= "
          "{:.1f}), which a flat-floor geometry absorbs",
          kc.model, kc.slope_creep["creep_rad_s"].get<double>(),
          kc.slope_creep["likelihood_ratio"].get<double>(), kc.slope_creep["needed"].get<double>());
    }
  }
  return kc;
}

void foldRadiusIntoEncoderScale(KinematicCalibration& kc, Corrections& corr, DiagnosisReport& rep) {
  if (!kc.accepted) return;
  Finding* named = nullptr;
  int count = 0;
  for (auto& f : rep.findings)
    if (f.effect == "encoder_scale" && !f.command_response && f.parameters.contains("side"))
      named = &f, ++count;
  if (count != 1 || !named->parameters["scale"].is_number()) return;
  const int s = named->parameters["side"] == "left" ? 1 : 0;
  double* n[2] = {&kc.nominal.m_per_tick_right, &kc.nominal.m_per_tick_left};
  double* g[2] = {&kc.fitted.m_per_tick_right, &kc.fitted.m_per_tick_left};
  const double dS = rel(*g[s], *n[s]), dO = rel(*g[1 - s], *n[1 - s]);
  if (dS == dO) return;
  const double factor = (1 + dO) / (1 + dS);
  const double before = named->parameters["scale"].get<double>(), after = before * factor;
  kc.folded = {{"side", s == 0 ? "right" : "left"},
               {"scale_before", before},
               {"scale_after", after},
               {"radius_rel_before", dS},
               {"radius_rel_after", dO}};
  named->parameters["scale"] = after;
  if (named->uncertainty.contains("scale") && named->uncertainty["scale"].is_number())
    named->uncertainty["scale"] =
        std::hypot(named->uncertainty["scale"].get<double>(), after * kc.sd_rel[s]);
  named->description += fmt::format(
      " Refined against the ground truth: the wheel's metres per tick it measures ({:+.3f} % "
      "against the other wheel's {:+.3f} %) belong to this encoder (one observable): scale "
      "{:.5f} -> {:.5f}.",
      100 * dS, 100 * dO, before, after);
  corr.enc_scale[s] *= factor;
  *n[s] = *g[s] / (1 + dO);  // the same metres per tick, now with the other wheel's radius
  kc.sd_rel[s] = kc.sd_rel[1 - s];
  const double beta = kc.fitted.travel_angle_rad - kc.nominal.travel_angle_rad;
  if (std::abs(dO) < kMinRelativeChange &&
      std::abs(rel(kc.fitted.track_m, kc.nominal.track_m)) < kMinRelativeChange &&
      std::abs(beta) < kMinRelativeChange) {
    kc.accepted = false;
    kc.rejected =
        "the calibration's only geometry change was the radius of the wheel whose encoder scale "
        "is named; it is folded into that scale";
  }
}

namespace {

/// The accepted calibration's geometry in words: the wheels' effective radii, the track and the
/// travel angle, each that the chosen model changed, with its uncertainty.
std::string geometryWords(const KinematicCalibration& kc) {
  const auto& n = kc.nominal;
  const auto& g = kc.fitted;
  const double dR = rel(g.m_per_tick_right, n.m_per_tick_right),
               dL = rel(g.m_per_tick_left, n.m_per_tick_left), db = rel(g.track_m, n.track_m);
  std::string what;
  if (kc.model == "scale" || kc.model == "scale+track")
    what = fmt::format("both wheels' effective radius is {} than configured",
                       percentText(dR, kc.sd_rel[0], "larger", "smaller"));
  else if (kc.model != "track" && kc.model != "travel_angle")  // wheels(+track), heading-*
    what = fmt::format(
        "the right wheel's effective radius is {} and the left wheel's {} than configured "
        "(ratio right/left {:.4f})",
        percentText(dR, kc.sd_rel[0], "larger", "smaller"),
        percentText(dL, kc.sd_rel[1], "larger", "smaller"),
        g.m_per_tick_right / g.m_per_tick_left * n.m_per_tick_left / n.m_per_tick_right);
  if (kc.model.find("track") != std::string::npos || kc.model.rfind("heading", 0) == 0)
    what += fmt::format("{}the effective track is {}", what.empty() ? "" : "; ",
                        percentText(db, kc.sd_rel[2], "wider", "narrower"));
  const double beta = g.travel_angle_rad - n.travel_angle_rad;
  if (std::abs(beta) >= kMinRelativeChange)
    what += fmt::format(
        "{}the body travels {:.2f} deg (+- {:.2f} deg) to the {} of the heading the ground truth "
        "measures (a motion-capture body frame rotated off the axle, or an axle not square to "
        "the body: the same in these data)",
        what.empty() ? "" : "; ", std::abs(beta) * 180 / M_PI, kc.sd_travel_angle_rad * 180 / M_PI,
        beta > 0 ? "left" : "right");
  return what;
}

}  // namespace

void addKinematicCalibration(const KinematicCalibration& kc, const config::WheelchairConfig& cfg,
                             DiagnosisReport& rep) {
  nlohmann::json info = {{"tested", kc.tested}};
  if (!kc.tested) {
    info["not_tested"] = kc.not_tested;
    rep.info["kinematic_calibration"] = info;
    return;
  }
  const auto errJson = [](const identification::OdometryError& e) {
    return nlohmann::json{{"odometry_mean_position_error_m", e.mean_position_m},
                          {"odometry_end_position_error_m", e.end_position_m},
                          {"odometry_end_heading_error_deg", e.end_heading_rad * 180 / M_PI},
                          {"runs", e.runs}};
  };
  info["validation"] = kc.validation;
  info["fit_runs"] = kc.fit_runs;
  if (!kc.lags_s.empty()) {
    std::vector<double> l = kc.lags_s;
    std::sort(l.begin(), l.end());
    info["encoder_lag_behind_truth_s"] = {
        {"min", l.front()}, {"median", stats::median(l)}, {"max", l.back()}};
  }
  info["folds"] = kc.folds;
  info["candidates"] = kc.candidates;
  info["chosen"] = kc.model.empty() ? "nominal" : kc.model;
  info["heldout_before"] = errJson(kc.heldout_before);
  info["heldout_after"] = errJson(kc.heldout_after);
  if (!kc.whole_run_model.empty())
    info["specification"] = {{"whole_run", kc.whole_run_model},
                             {"increments", kc.increment_model},
                             {"turn_gain_difference_rel", kc.gain_difference_rel},
                             {"turn_gain_difference_sd", kc.gain_difference_sd},
                             {"max_z", kMaxGainDisagreementZ},
                             {"whole_run_misspecified", kc.whole_run_misspecified}};
  info["accepted"] = kc.accepted;
  if (!kc.rejected.empty()) info["rejected"] = kc.rejected;
  if (!kc.rejected_parameters.empty()) info["not_established"] = kc.rejected_parameters;
  if (!kc.folded.is_null()) info["folded_into_encoder_scale"] = kc.folded;
  if (!kc.slope_creep.is_null()) {
    info["slope_creep"] = kc.slope_creep;
    if (kc.slope_creep["significant"].get<bool>())
      rep.info["cannot_tell"].push_back(
          "wheel geometry (radii, track) against the ground truth vs the slope's yaw creep: on "
          "the slope the dynamics named, the heading drifts downhill with the heading, which a "
          "flat-floor geometry absorbs. To tell: the same path on the flat, or across the slope "
          "in both directions");
  }
  rep.info["kinematic_calibration"] = info;
  if (!kc.accepted) return;

  const auto& n = kc.nominal;
  const auto& g = kc.fitted;
  const double dR = rel(g.m_per_tick_right, n.m_per_tick_right),
               dL = rel(g.m_per_tick_left, n.m_per_tick_left), db = rel(g.track_m, n.track_m);
  Finding f;
  f.effect = kWheelGeometryEffect;
  f.channels = {"encoders", "ground_truth"};
  const std::string what = geometryWords(kc);
  std::string why;
  if (kc.whole_run_misspecified)
    why = fmt::format(
        " Whole-run dead reckoning ({}) wants a turn gain {:+.2f} % (+- {:.2f} %) off the heading "
        "increments' ({}): heading that the wheel kinematics do not explain accumulates over the "
        "runs (e.g. in or after turns on the spot), so the geometry is taken from the increments.",
        kc.whole_run_model, 100 * kc.gain_difference_rel, 100 * kc.gain_difference_sd,
        kc.increment_model);
  f.description = fmt::format(
      "the odometric geometry does not match the ground truth: {} (track {:.4f} m). Dead reckoning "
      "with it predicts the held-out runs better: mean position error {:.4f} m -> {:.4f} m, end "
      "error {:.4f} m -> {:.4f} m ({}, {} run(s)).{}",
      what, g.track_m, kc.heldout_before.mean_position_m, kc.heldout_after.mean_position_m,
      kc.heldout_before.end_position_m, kc.heldout_after.end_position_m, kc.validation,
      kc.heldout_after.runs, why);
  f.parameters = {{"model", kc.model},
                  {"wheel_radius_right_rel", dR},
                  {"wheel_radius_left_rel", dL},
                  {"track_rel", db},
                  {"m_per_tick_right", g.m_per_tick_right},
                  {"m_per_tick_left", g.m_per_tick_left},
                  {"track_width_m", g.track_m},
                  {"travel_angle_rad", g.travel_angle_rad}};
  f.uncertainty = {{"wheel_radius_right_rel", kc.sd_rel[0]},
                   {"wheel_radius_left_rel", kc.sd_rel[1]},
                   {"track_rel", kc.sd_rel[2]},
                   {"travel_angle_rad", kc.sd_travel_angle_rad}};
  f.evidence = {{"criterion", "k-fold cross-validated dead-reckoning position error"},
                {"candidates", kc.candidates}};
  f.fit_before = errJson(kc.heldout_before);
  f.fit_after = errJson(kc.heldout_after);
  rep.addFinding(f);
  // k = r * wheel angle per tick: each configured odometric radius scales like its k
  const auto& geom = cfg.vehicle.geom;
  const double rR = geom.odometryRadius(0) * (1 + dR), rL = geom.odometryRadius(1) * (1 + dL);
  auto& v = rep.config_updates["vehicle"];
  v["wheel_radius_right_m"] = fmt::format("{:.8g}", rR);
  v["wheel_radius_left_m"] = fmt::format("{:.8g}", rL);
  v["wheel_radius_m"] = fmt::format("{:.8g}", 0.5 * (rR + rL));
  v["track_width_m"] = fmt::format("{:.8g}", g.track_m);
  v["odometry_travel_angle_rad"] = fmt::format("{:.8g}", g.travel_angle_rad);
}

}  // namespace wheelchair::diagnosis
