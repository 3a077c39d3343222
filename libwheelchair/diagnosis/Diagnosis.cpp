#include "libwheelchair/diagnosis/Diagnosis.h"
#include "libwheelchair/diagnosis/EncoderSide.h"
#include "libwheelchair/diagnosis/HeldOut.h"
#include "libwheelchair/diagnosis/RawlogInput.h"
#include "libwheelchair/stats/Statistics.h"

#include "libwheelchair/diagnosis/KinematicCalibration.h"
#include "libwheelchair/diagnosis/SensorFaults.h"
#include "libwheelchair/diagnosis/Stages.h"
#include "libwheelchair/diagnosis/UnmodeledPhysics.h"
#include "libwheelchair/model/DriveDynamics.h"
#include "libwheelchair/model/Kinematics.h"
#include "libwheelchair/sensors/Filtering.h"
#include "libwheelchair/stats/Descriptive.h"
#include "libwheelchair/stats/Distributions.h"
#include "libwheelchair/util/SpilledColumns.h"

#include <Eigen/LU>
#include <Eigen/QR>

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>
#include <utility>

namespace wheelchair::diagnosis {

using stats::BiasTest;
using stats::biasTest;
using stats::compareNested;
using stats::effectiveSampleSize;
using stats::Evidence;
using stats::fitLinear;
using stats::Groups;
using stats::LinearFit;
using stats::ljungBox;
using stats::singleGroup;
using stats::Whiteness;

namespace {

constexpr double kRad2Deg = 180.0 / M_PI;

/// The catalogue terms of the two stages (effects/: registry order).
std::vector<Candidate> kinematicCandidates(bool delay) {
  return stageCandidates(effects::Stage::kinematic, {0.0, delay});
}

std::vector<Candidate> dynamicCandidates(double body_mass, bool delay) {
  return stageCandidates(effects::Stage::dynamic, {body_mass, delay});
}

/// Index of the candidate called `name` (-1: none).
int candidateIndex(const std::vector<Candidate>& cands, const std::string& name) {
  for (std::size_t i = 0; i < cands.size(); ++i)
    if (cands[i].name == name) return static_cast<int>(i);
  return -1;
}

/// Time segments where |contribution| exceeds 2 sigma, merged over gaps < 1 s.
std::vector<std::pair<double, double>> activeSegments(std::vector<std::pair<double, double>> tc,
                                                      double sigma) {
  std::sort(tc.begin(), tc.end());
  std::vector<std::pair<double, double>> segs;
  for (auto& [t, c] : tc) {
    if (std::abs(c) < 2 * sigma) continue;
    if (!segs.empty() && t - segs.back().second < 1.0)
      segs.back().second = t;
    else
      segs.push_back({t, t});
  }
  std::vector<std::pair<double, double>> out;
  for (auto& s : segs)
    if (s.second - s.first >= 0.5) out.push_back(s);
  if (out.size() > 20) {
    std::sort(out.begin(), out.end(),
              [](auto& a, auto& b) { return a.second - a.first > b.second - b.first; });
    out.resize(20);
    std::sort(out.begin(), out.end());
  }
  if (out.empty() && !tc.empty()) out.push_back({tc.front().first, tc.back().first});
  return out;
}

/// Whether the data decide WHICH encoder is off. A short left and a long right encoder predict
/// the same gyro-vs-encoder residual whenever the ratio of the wheel distances is constant
/// (straight driving, or one steady curve): their columns are then collinear, and only data
/// mixing straight driving with turns separates them. The evidence is the likelihood ratio of
/// the two explanations under the configured sensor noise (not the residual noise of a few
/// windows): LR = (RSS_other - RSS_chosen) / sigma^2, sigma^2 the predicted variance of one
/// window's residual (gyro white noise + tick quantisation); the side is decided when LR
/// exceeds chi2Quantile(1 - alpha_b, 1). Otherwise the returned text says what is missing and
/// about how much more driving with turns it needs (the LR grows about linearly with it).
/// Sums over the kinematic windows: predicted residual variance (configured sensor noise),
/// turning, distance and duration.
struct RowTotals {
  double var_sum = 0, turn_rad = 0, dist_m = 0, duration_s = 0;
};
RowTotals rowTotals(const KinRows& k) {
  RowTotals s;
  for (int i = 0; i < k.X.rows(); ++i) {
    const double T = k.t1[i] - k.t0[i];
    s.var_sum += k.noise_var_per_s * T + k.noise_var_const;
    s.turn_rad += std::abs(k.omega[i]) * T;
    s.dist_m += std::abs(k.v[i]) * T;
    s.duration_s += T;
  }
  return s;
}

std::string encoderSideUndecided(const KinRows& k, const std::vector<Candidate>& cands,
                                 const std::vector<int>& accepted, int chosen, int other,
                                 double alpha_b, int lags) {
  std::vector<int> swapped = accepted;
  std::replace(swapped.begin(), swapped.end(), chosen, other);
  const LinearFit a = fitLinear(acceptedDesign(k.X, cands, accepted), k.y, k.groups, lags);
  const LinearFit b = fitLinear(acceptedDesign(k.X, cands, swapped), k.y, k.groups, lags);
  const auto [var_sum, turn_rad, dist_m, duration_s] = rowTotals(k);
  const double var = k.X.rows() > 0 ? var_sum / k.X.rows() : 0.0;
  const double lr = a.ok && b.ok && var > 0 ? (b.rss - a.rss) / var : 0.0;
  const double needed = stats::chi2Quantile(1 - alpha_b, 1);
  if (lr >= needed) return "";
  const double factor = std::min(needed / std::max(lr, 1e-3), 100.0);
  return fmt::format(
      "which encoder is off (the two encoders disagree by a scale, but a scale error of the {} "
      "and one of the {} encoder fit this data alike: likelihood ratio {:.2f}, {:.2f} needed); "
      "drive straight AND "
      "turn in both directions, about {:.0f} s / {:.0f} m more (this data: {:.1f} s, {:.1f} m, "
      "{:.0f} deg of turning)",
      cands[chosen].name == "encoder_scale/left" ? "left" : "right",
      cands[chosen].name == "encoder_scale/left" ? "right" : "left", lr, needed,
      std::max(10.0, duration_s * (factor - 1)), std::max(5.0, dist_m * (factor - 1)), duration_s,
      dist_m, turn_rad * kRad2Deg);
}

/// A 1 % scale error of one encoder turns the odometry by about 10 deg per 10 m driven straight
/// (0.55 m track): the smallest encoder fault the diagnosis must be able to see.
constexpr double kReportableEncoderScale = 0.01;

/// When no encoder scale was found: can the data see one of kReportableEncoderScale? The
/// smallest detectable scale error is eps = sqrt(chi2Quantile(1 - alpha_b, 1) sigma^2 / |x|^2),
/// x the encoder-scale column over the fit windows and sigma^2 the predicted variance of one
/// window's residual (configured sensor noise). "" when eps <= kReportableEncoderScale or an
/// encoder scale was accepted; else what is missing and how much driving would do (|x|^2 grows
/// about linearly with the distance driven).
std::string encoderScaleUndetectable(const KinRows& k, const std::vector<Candidate>& cands,
                                     const std::vector<int>& accepted, double alpha_b) {
  for (int a : accepted)
    if (cands[a].effect == "encoder_scale") return "";
  if (k.X.rows() == 0) return "";
  const auto [var_sum, turn_rad, dist_m, duration_s] = rowTotals(k);
  const double x2 =
      std::min(k.X.col(columnIndex(effects::Stage::kinematic, "encoder_scale/right")).squaredNorm(),
               k.X.col(columnIndex(effects::Stage::kinematic, "encoder_scale/left")).squaredNorm());
  const double var = var_sum / k.X.rows();
  const double eps = x2 > 0 ? std::sqrt(stats::chi2Quantile(1 - alpha_b, 1) * var / x2)
                            : std::numeric_limits<double>::infinity();
  if (eps <= kReportableEncoderScale) return "";
  const double factor = std::min(std::pow(eps / kReportableEncoderScale, 2), 1e4);
  return fmt::format(
      "whether an encoder is off: this data cannot tell an encoder scale error below {} from "
      "noise (it drove {:.1f} m, turned {:.0f} deg); drive about {:.0f} m or more, straight and "
      "turning, to see a {:.0f} % error",
      std::isfinite(eps) ? fmt::format("{:.1f} %", 100 * eps) : std::string("any size"), dist_m,
      turn_rad * kRad2Deg, std::max(10.0, dist_m * factor), 100 * kReportableEncoderScale);
}

struct ChannelSet {
  std::string name;
  Eigen::VectorXd r;
  Groups g;
  double noise_var = 0;
};

nlohmann::json channelMetrics(const Eigen::VectorXd& r, const Groups& g, int lags,
                              double noise_var) {
  nlohmann::json j;
  if (r.size() < 3) return j;
  BiasTest b = biasTest(r, g, lags);
  Whiteness w = ljungBox(r, g, std::min<int>(20, static_cast<int>(r.size()) / 4));
  j["n"] = b.n;
  j["rms"] = b.rms;
  j["mean"] = b.mean;
  j["bias_t"] = b.t;
  j["bias_p"] = b.p_value;
  j["n_eff"] = b.n_eff;
  j["ljung_box_q"] = w.q;
  j["ljung_box_p"] = w.p_value;
  j["rho1"] = w.rho1;
  if (noise_var > 0) {
    double nis = b.rms * b.rms / noise_var;
    auto band = stats::chi2MeanBand(0.95, 1, std::max(1.0, b.n_eff));
    j["mean_nis"] = nis;
    j["nis_band95"] = {band.first, band.second};
  }
  return j;
}

/// Regime bias tests: where the residual is biased (locate step).
nlohmann::json regimeStats(const Eigen::VectorXd& r, const std::vector<double>& v,
                           const std::vector<double>& w, const std::vector<double>& vd,
                           const std::vector<double>& phi, int lags, double alpha) {
  std::map<std::string, std::function<bool(size_t)>> reg = {
      {"standing", [&](size_t i) { return std::abs(v[i]) < 0.03 && std::abs(w[i]) < 0.05; }},
      {"straight", [&](size_t i) { return std::abs(v[i]) >= 0.03 && std::abs(w[i]) < 0.1; }},
      {"turning", [&](size_t i) { return std::abs(w[i]) >= 0.1; }},
      {"accelerating", [&](size_t i) { return !vd.empty() && std::abs(vd[i]) > 0.15; }},
      {"fast", [&](size_t i) { return std::abs(v[i]) > 0.5; }},
      {"slow", [&](size_t i) { return std::abs(v[i]) >= 0.03 && std::abs(v[i]) <= 0.5; }},
      {"heading_E", [&](size_t i) { return std::abs(v[i]) >= 0.03 && std::cos(phi[i]) > 0.7071; }},
      {"heading_N", [&](size_t i) { return std::abs(v[i]) >= 0.03 && std::sin(phi[i]) > 0.7071; }},
      {"heading_W", [&](size_t i) { return std::abs(v[i]) >= 0.03 && std::cos(phi[i]) < -0.7071; }},
      {"heading_S", [&](size_t i) { return std::abs(v[i]) >= 0.03 && std::sin(phi[i]) < -0.7071; }},
  };
  nlohmann::json j = nlohmann::json::object();
  const double level = stats::SelectionRule{alpha, static_cast<int>(reg.size())}.level();
  for (auto& [name, f] : reg) {
    std::vector<double> sub;
    for (size_t i = 0; i < static_cast<size_t>(r.size()) && i < v.size(); ++i)
      if (f(i)) sub.push_back(r(i));
    if (sub.size() < 10) continue;
    Eigen::VectorXd s = Eigen::Map<Eigen::VectorXd>(sub.data(), sub.size());
    BiasTest b = biasTest(s, singleGroup(static_cast<int>(s.size())), lags);
    j[name] = {{"n", b.n}, {"mean", b.mean}, {"rms", b.rms},
               {"t", b.t}, {"p", b.p_value}, {"biased", b.p_value < level}};
  }
  return j;
}

std::vector<std::string> biasedRegimes(const nlohmann::json& reg) {
  std::vector<std::string> out;
  for (auto it = reg.begin(); it != reg.end(); ++it)
    if (it->value("biased", false)) out.push_back(it.key());
  return out;
}

// ---------- trajectory check (dead reckoning against ground truth) ----------

struct TrajMetrics {
  double ate = 0, terminal = 0;
  int n = 0;
};

TrajMetrics deadReckoningMetrics(const Streams& s, const Corrections& c,
                                 const config::WheelchairConfig& cfg, bool gyro) {
  TrajMetrics m;
  if (s.gt.size() < 2 || s.te.size() < 3 || (gyro && !s.hasGyro())) return m;
  const double lw = cfg.vehicle.geom.track_width_m;
  std::vector<double> tgt, gx, gy, gp;
  for (auto& p : s.gt)
    tgt.push_back(p.t_s), gx.push_back(p.x_m), gy.push_back(p.y_m), gp.push_back(p.phi_rad);
  for (size_t i = 1; i < gp.size(); ++i)  // unwrapped
    gp[i] = gp[i - 1] + model::wrapAngle(gp[i] - gp[i - 1]);
  std::vector<double> gzc;
  if (gyro)
    for (double g : s.gz) gzc.push_back((g - c.gyro_bias) / c.gyro_scale);
  auto interp = [](const std::vector<double>& t, const std::vector<double>& x, double q) {
    if (q <= t.front()) return x.front();
    if (q >= t.back()) return x.back();
    size_t k = std::upper_bound(t.begin(), t.end(), q) - t.begin();
    double a = (q - t[k - 1]) / (t[k] - t[k - 1]);
    return x[k - 1] + a * (x[k] - x[k - 1]);
  };
  auto gyroInt = [&](double a, double b) {
    // trapezoid on a fine subdivision of the linear interpolant
    double sum = 0;
    double t = a;
    auto it = std::upper_bound(s.tg.begin(), s.tg.end(), a + c.delay_imu);
    while (t < b) {
      double tn = b;
      if (it != s.tg.end() && *it - c.delay_imu < b) tn = *it - c.delay_imu, ++it;
      sum += 0.5 * (interp(s.tg, gzc, t + c.delay_imu) + interp(s.tg, gzc, tn + c.delay_imu)) *
             (tn - t);
      t = tn;
    }
    return sum;
  };
  double t0 = s.te.front() - c.delay_enc;
  if (t0 < tgt.front()) return m;
  double x = interp(tgt, gx, t0), y = interp(tgt, gy, t0), phi = interp(tgt, gp, t0);
  double se = 0;
  for (size_t i = 1; i < s.te.size(); ++i) {
    double a = s.te[i - 1] - c.delay_enc, b = s.te[i] - c.delay_enc;
    double dR = (s.sR[i] - s.sR[i - 1]) / c.enc_scale[0];
    double dL = (s.sL[i] - s.sL[i - 1]) / c.enc_scale[1];
    double ds = 0.5 * (dR + dL);
    double dphi = gyro ? gyroInt(a, b) : (dR - dL) / lw;
    x += ds * std::cos(phi + 0.5 * dphi);
    y += ds * std::sin(phi + 0.5 * dphi);
    phi += dphi;
    if (b > tgt.back()) break;
    double ex = x - interp(tgt, gx, b), ey = y - interp(tgt, gy, b);
    se += ex * ex + ey * ey;
    m.n++;
    m.terminal = std::hypot(ex, ey);
  }
  m.ate = m.n ? std::sqrt(se / m.n) : 0;
  return m;
}

nlohmann::json trajectoryJson(const std::vector<Streams>& recs, const Corrections& c,
                              const config::WheelchairConfig& cfg) {
  nlohmann::json j = nlohmann::json::array();
  for (auto& s : recs) {
    if (s.gt.size() < 2) continue;
    TrajMetrics o = deadReckoningMetrics(s, c, cfg, false);
    TrajMetrics g = deadReckoningMetrics(s, c, cfg, true);
    j.push_back({{"odometry_ate_m", o.ate},
                 {"odometry_terminal_m", o.terminal},
                 {"encoder_gyro_ate_m", g.ate},
                 {"encoder_gyro_terminal_m", g.terminal},
                 {"duration_s", s.t_end - s.t_begin}});
  }
  return j;
}

// ---------- STLSQ (sparse regression) for `unmodeled` ----------

struct SparseResult {
  std::vector<int> terms;
  Eigen::VectorXd coef, se;
  Evidence ev;
  bool accepted = false;
  double lr_val = 0, lr_val_expected = 0;
  double rms_before_val = 0, rms_after_val = 0;
  nlohmann::json cv = nlohmann::json::object();          ///< per term: blockedCvTerm numbers
  nlohmann::json cannot_tell = nlohmann::json::array();  ///< terms below the misspecification
  /// Confirmed by blocked cross-validation on the fit rows because the held-out part could
  /// not test it (cv_lr: n_eff log(RSS_cv without / with), cv_rms_*: CV RMS without / with).
  bool cross_validated = false;
  double cv_lr = 0, cv_rms_before = 0, cv_rms_after = 0;
};

/// A term library over a set of rows, its columns made on demand (a long drive's library is
/// not kept as a matrix: memory, docs/benchmarks.md). Its designs are never made whole either:
/// the fits, predictions and cross-validations below take them block of rows by block.
struct Library {
  int rows = 0, cols = 0;
  /// Column j over rows [r0, r0 + n).
  std::function<Eigen::VectorXd(int j, int r0, int n)> range;
  Eigen::VectorXd col(int j) const { return range(j, 0, rows); }
  /// Rows [r0, r0 + n) of the columns `which`, in order.
  Eigen::MatrixXd block(const std::vector<int>& which, int r0, int n) const {
    Eigen::MatrixXd A(n, which.size());
    for (size_t k = 0; k < which.size(); ++k) A.col(k) = range(which[k], r0, n);
    return A;
  }
  /// The design of the columns `which` as fitLinear's block source.
  stats::DesignRows blocks(const std::vector<int>& which) const {
    return [this, which](long r0, long nb, Eigen::MatrixXd& out) {
      out = block(which, static_cast<int>(r0), static_cast<int>(nb));
    };
  }
  Eigen::VectorXd times(const std::vector<int>& which, const Eigen::VectorXd& coef) const;
  void timesRows(const std::vector<int>& which, const Eigen::VectorXd& coef, int a, int b,
                 Eigen::VectorXd& p, Eigen::Index at = 0) const;
  Eigen::VectorXd solve(const std::vector<int>& which, const Eigen::VectorXd& y, int skip0 = 0,
                        int skip1 = 0) const;
};

constexpr int kLibraryBlockRows = static_cast<int>(stats::kDesignBlockRows);  // rows per block

/// The design of `which` times coef (a prediction on every row), block by block.
Eigen::VectorXd Library::times(const std::vector<int>& which, const Eigen::VectorXd& coef) const {
  Eigen::VectorXd p(rows);
  timesRows(which, coef, 0, rows, p);
  return p;
}

/// The same on rows [a, b) only, into p.segment(at + a, b - a).
void Library::timesRows(const std::vector<int>& which, const Eigen::VectorXd& coef, int a, int b,
                        Eigen::VectorXd& p, Eigen::Index at) const {
  for (int r0 = a; r0 < b; r0 += kLibraryBlockRows) {
    const int nb = std::min(kLibraryBlockRows, b - r0);
    p.segment(at + r0, nb).noalias() = block(which, r0, nb) * coef;
  }
}

/// The least-squares coefficients of y on the columns `which` over all rows but [skip0, skip1),
/// as a column-pivoting QR of that design gives them (its basic solution when rank deficient):
/// the QR is the one of the design's triangle R (blocked Householder QR of [A y], TSQR), whose
/// column norms and least-squares problem are A's (A = Q R).
Eigen::VectorXd Library::solve(const std::vector<int>& which, const Eigen::VectorXd& y, int skip0,
                               int skip1) const {
  const Eigen::Index k = static_cast<Eigen::Index>(which.size());
  stats::TsqrAccumulator acc(Eigen::VectorXd::Ones(k));
  for (const auto& [a, b] : {std::pair{0, skip0}, std::pair{std::max(skip0, skip1), rows}})
    for (int r0 = a; r0 < b; r0 += kLibraryBlockRows) {
      const int nb = std::min(kLibraryBlockRows, b - r0);
      acc.add(block(which, r0, nb), y.segment(r0, nb));
    }
  const Eigen::MatrixXd T = acc.triangle();
  return T.topLeftCorner(k, k).colPivHouseholderQr().solve(Eigen::VectorXd(T.col(k).head(k)));
}

/// blockedCvTerm (HeldOut.h) of every term of `terms`, on the fit rows followed by the
/// validation rows (10 time blocks; bootstrap blocks of `lags` rows).
std::vector<BlockedCvTerm> blockedCv(const Library& L, const Eigen::VectorXd& y, const Library& Lv,
                                     const Eigen::VectorXd& yv, const std::vector<int>& terms,
                                     int lags) {
  const Eigen::Index nf = y.size(), n = nf + yv.size();
  // Rows [r0, r1) of the fit rows' design followed by the validation rows' (made per block).
  auto rows = [&](Eigen::Index r0, Eigen::Index r1) {
    Eigen::MatrixXd A(r1 - r0, terms.size());
    const Eigen::Index a = std::min(r1, nf) - std::min(r0, nf);
    if (a > 0) A.topRows(a) = L.block(terms, static_cast<int>(r0), static_cast<int>(a));
    if (r1 - r0 > a)
      A.bottomRows(r1 - r0 - a) =
          Lv.block(terms, static_cast<int>(std::max(r0, nf) - nf), static_cast<int>(r1 - r0 - a));
    return A;
  };
  Eigen::VectorXd Y(n);
  Y.head(nf) = y;
  Y.tail(yv.size()) = yv;
  std::vector<BlockedCvTerm> r;
  for (size_t k = 0; k < terms.size(); ++k)
    r.push_back(blockedCvTerm(rows, n, static_cast<Eigen::Index>(terms.size()), Y,
                              static_cast<int>(k), 10, std::max(1, lags)));
  return r;
}

/// Out-of-sample prediction of a term set's fit (rows of the data it is judged on).
using Predictor = std::function<Eigen::VectorXd(const std::vector<int>&)>;

/// Fit on L's rows, predict Lv's (the held-out part).
Predictor heldOutPredictor(const Library& L, const Eigen::VectorXd& y, const Library& Lv) {
  return [&L, &y, &Lv](const std::vector<int>& t) { return Lv.times(t, L.solve(t, y)); };
}

/// Blocked K-fold cross-validation on the fit rows: each of K contiguous blocks predicted by
/// a fit on the others (for terms the held-out part cannot test, e.g. a turn-rate term when
/// the last 30 % of a `square` drive does not turn).
/// The predictions of the terms t writes rows [0, L.rows) of p (p has at least that many).
void crossValidationInto(const Library& L, const Eigen::VectorXd& y, int K,
                         const std::vector<int>& t, Eigen::VectorXd& p) {
  for (int k = 0; k < K; ++k) {
    const int a = static_cast<int>(Eigen::Index(L.rows) * k / K);
    const int b = static_cast<int>(Eigen::Index(L.rows) * (k + 1) / K);
    L.timesRows(t, L.solve(t, y, a, b), a, b, p);
  }
}
Predictor crossValidationPredictor(const Library& L, const Eigen::VectorXd& y, int K) {
  return [&L, &y, K](const std::vector<int>& t) {
    Eigen::VectorXd p(L.rows);
    crossValidationInto(L, y, K, t, p);
    return p;
  };
}

/// The held-out rule applied to each term of a sparse fit (issue 16): backward elimination
/// on the judged rows yv (the held-out part, or cross-validation folds: valPrediction). Each round
/// refits (on the fit rows) without each term in turn; the term whose removal costs the held-out
/// prediction least is dropped unless that cost is both significant, n_eff log(RSS_val without /
/// RSS_val with) >= chi2_1(1 - alpha), and relevant: the held-out prediction changes by at least
/// min_contribution_rms (the floor every finding must pass). Collinear library terms (e.g. the
/// other motor's current, which carries the same dynamics) then no longer smear one physical term
/// over several. Then every surviving term must pass blocked cross-validation over all rows
/// (blockedCvTerm: block-bootstrap held-out gain and delete-one-block jackknife of its
/// coefficient); the weakest failing one is dropped (one per call: the caller refits the rest and
/// calls again). (L, y) fit rows and (Lv, yv_all) held-out rows: the blocked cross-validation's
/// data. partner(j) >= 0: the column that is one physical term with j (cos/sin of one angle: a
/// heading-dependent term A sin(h - phi) has an amplitude and a phase; keeping one of the two
/// would fix its phase to the world frame's x axis), left out together with j.
std::vector<int> heldOutPrune(const Predictor& valPrediction, const Eigen::VectorXd& yv,
                              const Groups& gv, const Library& L, const Eigen::VectorXd& y,
                              const Library& Lv, const Eigen::VectorXd& yv_all, int lags,
                              const DiagnosisOptions& opt, double min_contribution_rms,
                              std::vector<int> terms, const std::function<int(int)>& partner = {}) {
  auto without = [&](const std::vector<int>& t0, int j) {
    const int mate = partner ? partner(j) : -1;
    std::vector<int> t;
    for (int i : t0)
      if (i != j && i != mate) t.push_back(i);
    return t;
  };
  const double crit = stats::chi2Quantile(1 - opt.alpha, 1);
  const double nv = std::max<double>(1, yv.size());
  while (terms.size() > 1) {
    const Eigen::VectorXd p_full = valPrediction(terms);
    const Eigen::VectorXd r_full = yv - p_full;
    const double nev = effectiveSampleSize(r_full, gv, lags);
    double best = std::numeric_limits<double>::infinity(), change_rms = 0;
    std::vector<int> best_t;
    // Each term's contribution on the fit rows (the fit of all terms there).
    const Eigen::VectorXd bf = L.solve(terms, y);
    const double nf = std::max<double>(1, y.size());
    for (size_t k = 0; k < terms.size(); ++k) {
      std::vector<int> t = without(terms, terms[k]);
      if (t.empty()) continue;
      const Eigen::VectorXd p = valPrediction(t);
      // A term relevant on the fit rows that the held-out rows cannot test (there its
      // contribution is below the relevance floor or predicts an LR gain below
      // validation_min_expected_lr: e.g. cos(phi) when the last side of a `square` runs at
      // phi = -90 deg) is not judged here: its removal would cost nothing there whatever it
      // is. The blocked cross-validation below judges it on all rows.
      const double dn = (p - p_full).squaredNorm();
      const double expected = nev * std::log(1 + dn / std::max(1e-300, r_full.squaredNorm()));
      const bool untestable =
          expected < opt.validation_min_expected_lr || std::sqrt(dn / nv) < min_contribution_rms;
      // Relevant over ALL rows (fit and held-out: a term that matters only in a short burst
      // does not pass because the burst lies in the fit part), and judged below by the blocked
      // cross-validation over all rows.
      // (made only when it decides: two whole library columns)
      auto all_rms = [&] {
        return std::abs(bf(k)) *
               std::sqrt(L.col(terms[k]).squaredNorm() + Lv.col(terms[k]).squaredNorm()) /
               std::sqrt(nf + Lv.rows);
      };
      if (opt.unmodeled_judge_where_excited && untestable && all_rms() >= min_contribution_rms)
        continue;
      const double rss = (yv - p).squaredNorm();
      if (rss < best) best = rss, best_t = t, change_rms = (p - p_full).norm() / std::sqrt(nv);
    }
    if (best_t.empty()) break;  // none of them testable on the held-out rows
    // One term (or a cos/sin pair: chi2 with 2 degrees of freedom) less.
    const double crit_k =
        terms.size() - best_t.size() == 1 ? crit : stats::chi2Quantile(1 - opt.alpha, 2);
    const bool significant =
        nev * std::log(best / std::max(1e-300, r_full.squaredNorm())) >= crit_k;
    if (significant && change_rms >= min_contribution_rms) break;
    terms = best_t;
  }
  // Blocked cross-validation over all rows (fit and validation, time blocks): a term that does
  // not predict the blocks it was not fitted on better, or whose coefficient is within its
  // block-to-block (misspecification) uncertainty, goes; the weakest first, one per call (the
  // caller refits the rest).
  const std::vector<BlockedCvTerm> cv = blockedCv(L, y, Lv, yv_all, terms, lags);
  int worst = -1;
  double worst_t = std::numeric_limits<double>::infinity();
  for (size_t k = 0; k < cv.size(); ++k) {
    if (cv[k].kept(opt.alpha)) continue;
    const double t = std::abs(cv[k].coef) / std::max(1e-300, cv[k].coef_se);
    if (t < worst_t) worst_t = t, worst = static_cast<int>(k);
  }
  if (worst >= 0) terms.erase(terms.begin() + worst);
  return terms;
}

/// The index in `act` of the term of the fit f (of the columns act) with the smallest |t|, that
/// |t| in `worst`. A cos/sin pair is one heading-dependent term (amplitude and phase): judged by
/// its joint Wald statistic W (chi2, 2 dof), as the one-dof z with the same tail probability
/// exp(-W / 2), so that the world frame's orientation cannot decide which half stays.
int weakestTerm(const LinearFit& f, const std::vector<int>& act,
                const std::function<int(int)>& partner, double& worst) {
  worst = 1e300;
  int worst_k = -1;
  for (size_t k = 0; k < act.size(); ++k) {
    double t = std::abs(f.beta(k)) / std::sqrt(std::max(1e-300, f.cov(k, k)));
    const int mate = partner ? partner(act[k]) : -1;
    const auto m = std::find(act.begin(), act.end(), mate);
    if (mate >= 0 && m != act.end()) {
      const Eigen::Index km = m - act.begin();
      Eigen::Vector2d b(f.beta(k), f.beta(km));
      Eigen::Matrix2d C;
      C << f.cov(k, k), f.cov(k, km), f.cov(km, k), f.cov(km, km);
      const double W = b.dot(C.ldlt().solve(b));
      const double tail = std::exp(-0.5 * W);
      if (W >= 0)
        t = tail >= 1 ? 0.0 : tail > 1e-15 ? std::sqrt(stats::chi2Quantile(1 - tail, 1)) : 1e300;
    }
    if (t < worst) worst = t, worst_k = static_cast<int>(k);
  }
  return worst_k;
}

/// The same structure in fewer terms (issue 16): the library is not a basis (u^2 = v^2 +- l_w v
/// omega + l_w^2 omega^2 / 4 per motor, and v*|v| = v^2 while the chair drives forward), so a
/// sequential thresholding can end with a set such as {u^2, v*|v|, omega^2} (+3.56 u^2 -3.48
/// v*|v|: two large opposite coefficients of nearly collinear columns) where {v*omega, omega^2}
/// says the same with one term less: its members' t values are deflated alike by the
/// collinearity, so which one is dropped first is arbitrary. Every pair of `terms` is tried
/// replaced by one library column not in `terms` (not `excluded`); the best replacement (least
/// held-out RSS) is taken unless it predicts the judged rows yv worse both significantly
/// (n_eff log(RSS ratio) >= chi2_1(1 - alpha)) and relevantly (prediction change >=
/// min_contribution_rms): the rule heldOutPrune applies to leaving a term out. With `stands`
/// set, the replacement taken is the best one of those that stand the fit rows' thresholding
/// (stands(set): every term's |t| >= stlsq_threshold_sigma in its refit). Returns `terms`
/// unchanged, or the set one term smaller (the caller refits and calls again).
std::vector<int> sparserEquivalent(const Predictor& valPrediction, const Eigen::VectorXd& yv,
                                   const Groups& gv, const Library& L, int excluded, int lags,
                                   const DiagnosisOptions& opt, double min_contribution_rms,
                                   const std::vector<int>& terms,
                                   const std::function<bool(const std::vector<int>&)>& stands) {
  if (terms.size() < 2) return terms;
  const double crit = stats::chi2Quantile(1 - opt.alpha, 1);
  const double nv = std::max<double>(1, yv.size());
  const Eigen::VectorXd p_full = valPrediction(terms);
  const Eigen::VectorXd r_full = yv - p_full;
  const double nev = effectiveSampleSize(r_full, gv, lags);
  struct Replacement {
    double rss, change_rms;
    std::vector<int> set;
  };
  std::vector<Replacement> cands;
  for (int j = 0; j < L.cols; ++j) {
    if (j == excluded || std::find(terms.begin(), terms.end(), j) != terms.end() ||
        !(L.col(j).norm() > 0))
      continue;
    for (size_t a = 0; a < terms.size(); ++a)
      for (size_t b = a + 1; b < terms.size(); ++b) {
        std::vector<int> t;
        for (size_t k = 0; k < terms.size(); ++k)
          if (k != a && k != b) t.push_back(terms[k]);
        t.push_back(j);
        const Eigen::VectorXd p = valPrediction(t);
        cands.push_back({(yv - p).squaredNorm(), (p - p_full).norm() / std::sqrt(nv), t});
      }
  }
  std::stable_sort(cands.begin(), cands.end(),
                   [](const Replacement& x, const Replacement& y) { return x.rss < y.rss; });
  for (const Replacement& c : cands) {
    if (stands && !stands(c.set)) continue;
    const bool significant = nev * std::log(c.rss / std::max(1e-300, r_full.squaredNorm())) >= crit;
    return significant && c.change_rms >= min_contribution_rms ? terms : c.set;
  }
  return terms;
}

/// The terms of `terms` whose held-out contribution is below the structure the model leaves
/// unexplained on the validation rows (indices into `terms`). A regressor correlated with an
/// omitted term takes up to |omitted| of it (Cauchy-Schwarz on the omitted-variable bias), so a
/// term contributing less than sigma_m = sqrt(max(0, mean(r^2) - noise_var)) (r: held-out
/// residual of the full set; noise_var: the channel's predicted noise variance per row) cannot
/// be told from a projection of what is still missing: it is not a finding (issue 16: "honest
/// when it cannot tell"). A term's contribution: the change of the held-out prediction when it
/// (with its partner(j) >= 0, e.g. cos/sin of one angle) is left out and the rest refitted.
/// With all_rows (DiagnosisOptions::unmodeled_judge_where_excited) both are measured out of
/// sample on ALL rows: the held-out rows predicted by the fit on the fit rows, and the fit rows
/// by blocked 5-fold cross-validation on them (without it, the held-out rows alone: a yaw inertia
/// on a `square` drive, whose last 30 % barely turns, contributed 0.0013 A there against 0.0064 A
/// unexplained and was never reported; its contribution is where the drive turns). Per dropped
/// term: {index, contribution rms}; sigma_m set.
std::vector<std::pair<int, double>> belowMisspecification(
    const Library& L, const Eigen::VectorXd& y, const Library& Lv, const Eigen::VectorXd& yv,
    const std::vector<int>& terms, double noise_var, const std::function<int(int)>& partner,
    bool all_rows, double& sigma_m) {
  // The judged rows yall = [y (all_rows); yv] and their out-of-sample prediction by the terms
  // t, written into p: the fit rows' by blocked 5-fold cross-validation
  // (crossValidationPredictor), the held-out rows' by the fit on the fit rows
  // (heldOutPredictor), the same numbers without their full-length temporaries (memory).
  const Eigen::Index nf = all_rows ? y.size() : 0, n = nf + yv.size();
  auto valPrediction = [&](const std::vector<int>& t, Eigen::VectorXd& p) {
    p.setZero(n);
    if (t.empty()) return;
    if (all_rows) crossValidationInto(L, y, 5, t, p);
    Lv.timesRows(t, L.solve(t, y), 0, Lv.rows, p, nf);
  };
  const double nv = std::max<double>(1, n);
  Eigen::VectorXd p_full, p;
  valPrediction(terms, p_full);
  {
    Eigen::VectorXd r(n);  // yall - p_full
    if (all_rows)
      r << y - p_full.head(nf), yv - p_full.tail(yv.size());
    else
      r = yv - p_full;
    sigma_m = std::sqrt(std::max(0.0, r.squaredNorm() / nv - noise_var));
  }
  std::vector<std::pair<int, double>> out;
  for (size_t k = 0; k < terms.size(); ++k) {
    const int mate = partner ? partner(terms[k]) : -1;
    std::vector<int> t;
    for (int j : terms)
      if (j != terms[k] && j != mate) t.push_back(j);
    valPrediction(t, p);
    const double c = (p - p_full).norm() / std::sqrt(nv);
    if (c < sigma_m) out.push_back({static_cast<int>(k), c});
  }
  return out;
}

/// Held-out numbers of a prediction p of yv: LR gain, the gain expected from p's size, RMS.
void heldOutGain(const Eigen::VectorXd& p, const Eigen::VectorXd& yv, const Groups& gv, int lags,
                 SparseResult& res) {
  const Eigen::VectorXd r1 = yv - p;
  const double nev = effectiveSampleSize(r1, gv, lags);
  res.lr_val = nev * std::log(yv.squaredNorm() / std::max(1e-300, r1.squaredNorm()));
  res.lr_val_expected = nev * std::log(1 + p.squaredNorm() / std::max(1e-300, r1.squaredNorm()));
  res.rms_before_val = std::sqrt(yv.squaredNorm() / yv.size());
  res.rms_after_val = std::sqrt(r1.squaredNorm() / yv.size());
}

/// STLSQ on (L, y) with each term set judged by `predict` against yj (groups gj): the
/// held-out rows (Lv, yv) or, for terms they cannot test, cross-validation on the fit rows.
/// Blocked cross-validation over all rows and the misspecification bound always use (L, y)
/// and (Lv, yv). Column `excluded` (-1: none) of the library is left out as if it were zero.
/// noise_var > 0: the misspecification bound (belowMisspecification, `partner` pairs columns
/// that are one physical term) marks terms that stay in the fit (leaving them out would bias
/// the others) but are not reported: SparseResult::cannot_tell (library index, numbers); the
/// caller reports the rest. `untestable`: set when the result is rejected only because the
/// judged data cannot test it. `sparser`: sparserEquivalent may take any replacement (true) or
/// only one that stands the thresholding (false); `replaced` is set when one was taken.
SparseResult stlsqWith(const Library& L, const Eigen::VectorXd& y, const Groups& g,
                       const Library& Lv, const Eigen::VectorXd& yv, const Predictor& predict,
                       const Eigen::VectorXd& yj, const Groups& gj, int lags,
                       const DiagnosisOptions& opt, double min_contribution_rms, int excluded,
                       double noise_var, const std::function<int(int)>& partner, bool& untestable,
                       bool sparser, bool& replaced) {
  untestable = false;
  bool pruned = false;
  SparseResult res;
  std::vector<int> act;
  for (int j = 0; j < L.cols; ++j)
    if (j != excluded && L.col(j).norm() > 0) act.push_back(j);
  for (int it = 0; it < 20 && !act.empty(); ++it) {
    LinearFit f = fitLinear(L.blocks(act), static_cast<long>(act.size()), y, g, lags);
    if (!f.ok) {  // drop the column with the smallest norm and retry
      act.pop_back();
      continue;
    }
    double worst = 1e300;
    const int worst_k = weakestTerm(f, act, partner, worst);
    if (worst >= opt.stlsq_threshold_sigma) {
      if (yj.size() > 10 && !pruned) {
        // Whether the held-out rows can test these terms at all (else the pruning below is
        // blind: every term would look removable).
        SparseResult probe;
        heldOutGain(predict(act), yj, gj, lags, probe);
        untestable = untestable || probe.lr_val_expected < opt.validation_min_expected_lr;
      }
      if (yj.size() > 10) {
        const std::vector<int> kept = heldOutPrune(predict, yj, gj, L, y, Lv, yv, lags, opt,
                                                   min_contribution_rms, act, partner);
        if (kept.size() < act.size()) {  // refit the kept terms (and their covariance)
          act = kept;
          pruned = true;
          continue;
        }
        // (in the second search, stlsq: only replacements that stand the thresholding)
        auto stands = [&](const std::vector<int>& t) {
          const LinearFit ft = fitLinear(L.blocks(t), static_cast<long>(t.size()), y, g, lags);
          double weakest = 0;
          weakestTerm(ft, t, partner, weakest);
          return ft.ok && weakest >= opt.stlsq_threshold_sigma;
        };
        if (std::vector<int> fewer = sparserEquivalent(
                predict, yj, gj, L, excluded, lags, opt, min_contribution_rms, act,
                sparser ? std::function<bool(const std::vector<int>&)>{} : stands);
            fewer.size() < act.size()) {  // the same structure in fewer terms: refit those
          act = std::move(fewer);
          pruned = true;
          replaced = true;
          continue;
        }
        double sigma_m = 0;
        if (noise_var > 0)
          for (const auto& [w, c_rms] :
               belowMisspecification(L, y, Lv, yv, act, noise_var, partner,
                                     opt.unmodeled_judge_where_excited, sigma_m))
            res.cannot_tell.push_back({{"term", act[w]},
                                       {"coefficient", f.beta(w)},
                                       {"heldout_contribution_rms", c_rms},
                                       {"unexplained_rms", sigma_m}});
      }
      res.terms = act;
      res.coef = f.beta;
      res.se = f.cov.diagonal().cwiseSqrt();
      double ne = effectiveSampleSize(f.residual, g, lags);
      res.ev = compareNested(y.squaredNorm(), f.rss, static_cast<int>(act.size()), ne);
      break;
    }
    // sequential thresholding: drop the weakest term (with its cos/sin partner)
    const int mate = partner ? partner(act[worst_k]) : -1;
    act.erase(act.begin() + worst_k);
    if (const auto m = std::find(act.begin(), act.end(), mate); mate >= 0 && m != act.end())
      act.erase(m);
  }
  if (res.terms.empty()) return res;
  if (!selectionRule(opt, L.cols).reject(res.ev).empty()) return res;
  if (L.times(res.terms, res.coef).norm() / std::sqrt(std::max<double>(1, y.size())) <
      min_contribution_rms)
    return res;
  if (yj.size() > 10) {
    const std::vector<BlockedCvTerm> cv = blockedCv(L, y, Lv, yv, res.terms, lags);
    for (size_t k = 0; k < cv.size(); ++k) res.cv[std::to_string(res.terms[k])] = cv[k].toJson();
    heldOutGain(predict(res.terms), yj, gj, lags, res);
    if (res.lr_val_expected >= opt.validation_min_expected_lr &&
        res.lr_val < opt.validation_fraction_of_expected * res.lr_val_expected)
      return res;
    if (res.lr_val_expected < opt.validation_min_expected_lr) {  // must be confirmed
      untestable = true;
      return res;
    }
  }
  res.accepted = true;
  return res;
}

/// STLSQ with the held-out rule on the held-out rows (Lv, yv). A result the held-out part
/// cannot test (it predicts no difference there, e.g. a turn-rate term when the last 30 % of a
/// `square` drive does not turn) is confirmed instead by blocked 5-fold cross-validation on
/// the fit rows (issue 16: "across time blocks of one"), with the same rules; its JSON then
/// says so (`evidence.cross_validation`), and its held-out numbers stay those of the held-out
/// part (validation_tested false). `sparser`, `replaced`: as stlsqWith.
SparseResult stlsqSearch(const Library& L, const Eigen::VectorXd& y, const Groups& g,
                         const Library& Lv, const Eigen::VectorXd& yv, const Groups& gv, int lags,
                         const DiagnosisOptions& opt, double min_contribution_rms, int excluded,
                         double noise_var, const std::function<int(int)>& partner, bool sparser,
                         bool& replaced) {
  bool untestable = false;
  SparseResult res =
      stlsqWith(L, y, g, Lv, yv, heldOutPredictor(L, y, Lv), yv, gv, lags, opt,
                min_contribution_rms, excluded, noise_var, partner, untestable, sparser, replaced);
  if (res.accepted || !untestable || y.size() < 50 || !opt.unmodeled_cross_validation) return res;
  bool cv_untestable = false;
  SparseResult cv = stlsqWith(L, y, g, Lv, yv, crossValidationPredictor(L, y, 5), y, g, lags, opt,
                              min_contribution_rms, excluded, noise_var, partner, cv_untestable,
                              sparser, replaced);
  if (!cv.accepted) return res;
  cv.cross_validated = true;
  cv.cv_lr = cv.lr_val, cv.cv_rms_before = cv.rms_before_val, cv.cv_rms_after = cv.rms_after_val;
  heldOutGain(Lv.times(cv.terms, cv.coef), yv, gv, lags, cv);
  return cv;
}

/// stlsqSearch, and where it accepts nothing after sparserEquivalent replaced a pair of terms by
/// one column, the same search again with only replacements that stand the fit rows'
/// thresholding (issue 16 item 3). The replacement is meant to say the same structure in fewer
/// terms; when the fewer-term set does not stand the thresholding and the whole structure then
/// dissolves (MuJoCo `square` 785894: a quadratic drag of 4.32 N s^2/m^2 with a 1-sigma current
/// trace, nothing reported), it was not the same structure, and the search that keeps what the
/// fit rows support is judged instead, by the same held-out and cross-validation rules. Where
/// the first search accepts a set, it stands (the replacement then did what it is for, and
/// over-fitted sets are still replaced by ones that do not stand).
SparseResult stlsq(const Library& L, const Eigen::VectorXd& y, const Groups& g, const Library& Lv,
                   const Eigen::VectorXd& yv, const Groups& gv, int lags,
                   const DiagnosisOptions& opt, double min_contribution_rms, int excluded = -1,
                   double noise_var = 0, const std::function<int(int)>& partner = {}) {
  bool replaced = false;
  SparseResult res = stlsqSearch(L, y, g, Lv, yv, gv, lags, opt, min_contribution_rms, excluded,
                                 noise_var, partner, true, replaced);
  if (res.accepted || !replaced) return res;
  bool again = false;
  SparseResult kept = stlsqSearch(L, y, g, Lv, yv, gv, lags, opt, min_contribution_rms, excluded,
                                  noise_var, partner, false, again);
  return kept.accepted ? kept : res;
}

nlohmann::json evidenceJson(const SelectionStep& st, double alpha_b) {
  return {{"likelihood_ratio", st.evidence.lr},
          {"p_value", st.evidence.p_value},
          {"bonferroni_level", alpha_b},
          {"delta_bic", st.evidence.delta_bic},
          {"n_eff", st.evidence.n_eff},
          {"added_parameters", st.evidence.k},
          {"validation_likelihood_ratio", st.lr_val},
          {"validation_expected_likelihood_ratio", st.lr_val_expected},
          {"validation_tested", st.val_tested}};
}

double rmsOf(double rss, Eigen::Index n) {
  return n > 0 ? std::sqrt(rss / n) : 0.0;
}

}  // namespace

namespace {
[[maybe_unused]] const bool kRegistered = config::registerOptionsOf<DiagnosisOptions>("diagnosis");
}  // namespace

config::Options DiagnosisOptions::options(const std::string& section) {
  using config::Range;
  const Range pos = Range::above(0), nonneg = Range::atLeast(0);
  return config::Options(section, "model-mismatch diagnosis (docs/discovery.md)")
      .real("fit_fraction", fit_fraction, "without --validate: fit on this first fraction (-)",
            Range{0.1, 0.95, true, true})
      .real("window_s", window_s, "stage 1 encoder window (s)", pos)
      .real("cutoff_hz", cutoff_hz, "stage 2 zero-phase low-pass (Hz)", pos)
      .real("grid_rate_hz", grid_rate_hz, "stage 2 time base (Hz); > 2 cutoff_hz", pos)
      .real("edge_trim_s", edge_trim_s, "dropped at both ends of every segment (s)", nonneg)
      .real("max_gap_s", max_gap_s, "a longer stream gap splits a segment (s)", pos)
      .real("alpha", alpha, "family-wise false-alarm level (-)", Range{0, 1, true, true})
      .real("min_bic_drop", min_bic_drop, "BIC drop required (-)", nonneg)
      .real("min_relevance", min_relevance, "minimum effect, fraction of one sample's noise (-)",
            nonneg)
      .real("validation_fraction_of_expected", validation_fraction_of_expected,
            "held-out gain >= this x predicted gain (-)", nonneg)
      .real("validation_min_expected_lr", validation_min_expected_lr,
            "below: validation cannot test the term (-)", nonneg)
      .flag("enable_unmodeled", enable_unmodeled, "sparse regression on what remains")
      .flag("unmodeled_cross_validation", unmodeled_cross_validation,
            "unmodeled terms the held-out part cannot test: confirm by blocked 5-fold CV")
      .flag("unmodeled_judge_where_excited", unmodeled_judge_where_excited,
            "unmodeled terms the held-out part cannot test: judged on all rows (CV)")
      .real("stlsq_threshold_sigma", stlsq_threshold_sigma,
            "STLSQ keeps terms with |coef| > this x HAC sigma (-)", nonneg)
      .real("castor_x_m", castor_x_m, "library castor_swivel: swivel axes ahead of the axle (m)",
            nonneg)
      .real("castor_half_spacing_m", castor_half_spacing_m,
            "library castor_swivel: swivel axes at +- this y (m)", nonneg)
      .real("castor_relaxation_m", castor_relaxation_m,
            "library castor_swivel: distance a castor rolls while turning round (m; 0: no term)",
            nonneg)
      .flag("enable_delay", enable_delay, "fit stream delays");
}

void DiagnosisOptions::loadFromConfig(const mrpt::config::CConfigFileBase& ini,
                                      const std::string& s) {
  options(s).load(ini);  // ranges of single keys
  if (!(grid_rate_hz > 2 * cutoff_hz))
    throw std::runtime_error(config::keyLocation(ini, s, "grid_rate_hz") +
                             ": must be > 2 cutoff_hz");
}

namespace {

/// The recordings as streams: `fit` and `val` (the held-out part or the --validate
/// recordings) and `all` (the whole fit recordings without motor currents, for the trajectory
/// and the Pozyx checks). `all` is empty until makeWholeStreams(): during the stages (the peak
/// of diagnose's memory) only the samples of a fit recording outside its fit and held-out parts
/// are kept, in `beyond` (before, after; memory, docs/benchmarks.md).
struct StageData {
  std::vector<Streams> fit, val, all;
  std::vector<std::array<Streams, 2>> beyond;
  bool any_enc = false, any_gyro = false, any_mot = false;
  const std::vector<io::Recording>* fit_recs = nullptr;  ///< the recordings `all` came from
  double fit_fraction = 1.0;  ///< part of each fit recording in `fit` (1: --validate given)
};

/// `make(fit, i)`: the streams of fit (true) or validation recording i (makeStreams of it, or
/// made as its rawlog was read); `fit_recs`: the fit recordings, `n_val` validation recordings.
StageData splitStreams(const std::vector<io::Recording>& fit_recs, std::size_t n_val,
                       const DiagnosisOptions& opt,
                       const std::function<Streams(bool, std::size_t)>& make) {
  StageData d;
  d.fit_recs = &fit_recs;
  d.fit_fraction = n_val == 0 ? opt.fit_fraction : 1.0;
  for (std::size_t i = 0; i < fit_recs.size(); ++i) {
    Streams s = make(true, i);
    d.any_enc |= s.hasEncoders(), d.any_gyro |= s.hasGyro(), d.any_mot |= s.hasMotors();
    // `all` serves the trajectory check and the Pozyx fault check (encoders, gyro, Pozyx,
    // ground truth); until makeWholeStreams() only what fit / val do not hold is kept.
    constexpr double kInf = std::numeric_limits<double>::infinity();
    std::vector<std::pair<double, double>> ranges{{-kInf, std::nextafter(s.t_begin, -kInf)},
                                                  {std::nextafter(s.t_end, kInf), kInf}};
    const double tc = s.t_begin + opt.fit_fraction * (s.t_end - s.t_begin);
    if (n_val == 0) ranges.push_back({s.t_begin, tc}), ranges.push_back({tc, s.t_end});
    // The crops made column by column from s, which they consume (memory); with --validate
    // the fit part is s itself.
    std::vector<Streams> parts;
    if (n_val == 0) {
      parts = cropStreams(std::move(s), ranges);
    } else {
      for (std::size_t r = 0; r < 2; ++r)
        parts.push_back(cropStreams(s, ranges[r].first, ranges[r].second));
    }
    d.beyond.push_back({std::move(parts[0]), std::move(parts[1])});
    for (Streams& b : d.beyond.back())
      for (auto* v : {&b.tm, &b.iR, &b.iL}) std::vector<double>().swap(*v);
    if (n_val == 0) {
      d.fit.push_back(std::move(parts[2]));
      d.val.push_back(std::move(parts[3]));
    } else {
      d.fit.push_back(std::move(s));
    }
  }
  for (std::size_t i = 0; i < n_val; ++i) d.val.push_back(make(false, i));
  return d;
}

/// Fills data.all: each fit recording's streams (without motor currents) joined from the
/// samples before its fit part, the fit part, its held-out part (without --validate) and the
/// samples after: the streams makeStreams() made of it, sample for sample. After the stages
/// nothing reads the motor currents, the fit parts nor (once the held-out trajectories are
/// made, heldOutTrajectories()) the held-out parts: the join consumes them, each column
/// released once joined, and the --validate recordings' streams are released (memory,
/// docs/benchmarks.md).
void makeWholeStreams(StageData& data) {
  data.all.clear();
  for (auto* parts : {&data.fit, &data.val})
    for (Streams& s : *parts)
      for (auto* v : {&s.tm, &s.iR, &s.iL}) std::vector<double>().swap(*v);
  for (std::size_t i = 0; i < data.fit.size(); ++i) {
    std::vector<Streams> parts;
    parts.push_back(std::move(data.beyond[i][0]));
    parts.push_back(std::move(data.fit[i]));
    if (data.fit_fraction < 1.0) parts.push_back(std::move(data.val[i]));
    parts.push_back(std::move(data.beyond[i][1]));
    data.all.push_back(joinStreams(std::move(parts), false));
  }
  std::vector<Streams>().swap(data.fit);
  std::vector<Streams>().swap(data.val);
  std::vector<std::array<Streams, 2>>().swap(data.beyond);
}

/// The catalogue design of a stage's rows: stage 1's stored X, stage 2's made block by block.
CatalogueDesign designOf(const KinRows& k) {
  return k.X;
}
CatalogueDesign designOf(const DynRows& d) {
  return d.design();
}

/// Rows rebuilt with a re-estimated stream delay (`delay` s).
template <class Rows>
struct DelayRefit {
  double delay = 0;
  Rows fit, val;
};

/// Nonlinear refinement of an accepted stream delay (accepted term number `di`): the
/// linearised delay term is iterated with the rows rebuilt at the current estimate, then the
/// other terms are re-selected on the delay-corrected rows (the linearised delay leaves
/// second-order structure other terms may have absorbed) and the delay updated once more.
/// `rows(fit, delay_s)` builds the fit (true) or validation (false) rows with that delay.
template <class Rows, class MakeRows>
DelayRefit<Rows> refineDelay(Selection& sel, int di, const std::vector<Candidate>& cands,
                             const DiagnosisOptions& opt, int lags, double min_contribution_rms,
                             const MakeRows& rows) {
  DelayRefit<Rows> r;
  for (int it = 0; it < 4; ++it) {
    r.delay += sel.fit.beta(sel.ranges[di].first);
    r.fit = rows(true, r.delay);
    sel.fit = fitAccepted(designOf(r.fit), r.fit.y, cands, sel.accepted, r.fit.groups, lags);
  }
  r.delay += sel.fit.beta(sel.ranges[di].first);
  r.fit = rows(true, r.delay);
  r.val = rows(false, r.delay);
  SelectionStep dstep = sel.steps[di];
  int dcand = sel.accepted[di];
  SelectionData sd2{r.fit.y,      r.val.y, designOf(r.fit),     designOf(r.val), r.fit.groups,
                    r.val.groups, lags,    min_contribution_rms};
  sel = forwardSelect(sd2, cands, opt, {dcand});
  sel.steps.insert(sel.steps.begin(), dstep);
  r.delay += sel.fit.beta(sel.ranges[0].first);
  r.fit = rows(true, r.delay);
  r.val = rows(false, r.delay);
  sel.fit = fitAccepted(designOf(r.fit), r.fit.y, cands, sel.accepted, r.fit.groups, lags);
  return r;
}

/// Index (in sel.accepted) of the candidate called `name`, or -1.
int acceptedIndex(const Selection& sel, const std::vector<Candidate>& cands,
                  const std::string& name) {
  int di = -1;
  for (size_t a = 0; a < sel.accepted.size(); ++a)
    if (cands[sel.accepted[a]].name == name) di = static_cast<int>(a);
  return di;
}

/// Evidence and before/after fit metrics of one accepted term, on channel `channel` whose
/// residual is in `unit` (rms keys validation_rms_<unit>, fit_rms_<unit>).
Finding termFinding(const Candidate& c, const SelectionStep& st, double alpha_b,
                    const std::vector<std::string>& regimes, const std::string& channel,
                    const std::string& unit, Eigen::Index n_val, Eigen::Index n_fit) {
  Finding f;
  f.effect = c.effect;
  f.evidence = evidenceJson(st, alpha_b);
  f.evidence["regimes_biased_before"] = regimes;
  f.fit_before = {{"channel", channel},
                  {"validation_rms_" + unit, rmsOf(st.rss0_val, n_val)},
                  {"fit_rms_" + unit, rmsOf(st.rss0_fit, n_fit)}};
  f.fit_after = {{"channel", channel},
                 {"validation_rms_" + unit, rmsOf(st.rss1_val, n_val)},
                 {"fit_rms_" + unit, rmsOf(st.rss1_fit, n_fit)}};
  return f;
}

/// An accepted STLSQ result as an `unmodeled` finding on `channel` (residual unit `unit`).
Finding unmodeledFinding(const SparseResult& sr, const std::vector<std::string>& names,
                         const std::string& channel, const std::string& eq_lhs,
                         const std::string& where, const std::string& unit,
                         const std::string& rms_unit) {
  Finding f;
  f.effect = "unmodeled";
  f.channels = {channel};
  std::string eq = eq_lhs + " =";
  for (size_t k = 0; k < sr.terms.size(); ++k) {
    const auto& nm = names[sr.terms[k]];
    f.parameters[nm] = sr.coef(k);
    f.uncertainty[nm] = sr.se(k);
    if (const std::string key = std::to_string(sr.terms[k]); sr.cv.contains(key))
      f.evidence["blocked_cv"][nm] = sr.cv[key];
    eq += fmt::format(" {:+.4g}*{}", sr.coef(k), nm);
  }
  f.parameters["channel"] = channel;
  f.description =
      "a term outside the catalogue acts on the " + where + ": " + eq + " (" + unit + ")";
  f.evidence["likelihood_ratio"] = sr.ev.lr;
  f.evidence["p_value"] = sr.ev.p_value;
  f.evidence["delta_bic"] = sr.ev.delta_bic;
  f.evidence["n_eff"] = sr.ev.n_eff;
  f.evidence["validation_likelihood_ratio"] = sr.lr_val;
  if (sr.cross_validated) {
    f.evidence["validation_tested"] = false;
    f.evidence["cross_validation"] = {
        {"folds", 5},
        {"why",
         "the held-out part cannot test it: confirmed on blocked 5-fold cross-validation "
         "of the fit data"},
        {"likelihood_ratio", sr.cv_lr},
        {"rms_before", sr.cv_rms_before},
        {"rms_after", sr.cv_rms_after}};
  }
  f.fit_before = {{"validation_rms_" + rms_unit, sr.rms_before_val}};
  f.fit_after = {{"validation_rms_" + rms_unit, sr.rms_after_val}};
  return f;
}

// ---------------- stage 1: kinematic consistency ----------------

/// The accepted terms of a selection by name: first coefficient and its 1-sigma.
effects::TermFit termFit(const Selection& sel, const std::vector<Candidate>& cands,
                         const config::WheelchairConfig& cfg, double delay_s) {
  effects::TermFit fit;
  fit.cfg = &cfg;
  fit.delay_s = delay_s;
  for (size_t a = 0; a < sel.accepted.size(); ++a) {
    const int i = sel.ranges[a].first;
    const auto& n = cands[sel.accepted[a]].name;
    fit.coef[n] = sel.fit.beta(i);
    fit.sigma[n] = std::sqrt(std::max(0.0, sel.fit.cov(i, i)));
  }
  return fit;
}

/// The effect's parameters, words and channels (the stage's when it names none) in a finding.
void describeFinding(Finding& f, const Candidate& c, const Selection& sel, std::size_t a,
                     const effects::TermFit& fit) {
  const int i = sel.ranges[a].first, k = sel.ranges[a].second;
  const effects::FindingText t = effects::findEffect(c.effect)->describe(
      c.name, sel.fit.beta.segment(i, k), sel.fit.cov.block(i, i, k, k), fit);
  f.parameters = t.parameters;
  f.uncertainty = t.uncertainty;
  f.description = t.description;
  if (!t.channels.empty()) f.channels = t.channels;
}

/// Column j of the stage 1 unmodeled-term library at window i: the window length T times v,
/// |omega|, omega |omega|, cos(phi), sin(phi), v omega, (u_R^3 - u_L^3) / l_w (rad for the
/// rates' terms). The last is a rolling radius that grows with the square of the rim speed u
/// (a soft or centrifugally growing tyre, r = r0 (1 + b u^2)): each wheel then rolls b u^2 further
/// per radian than the odometry says, so the chassis turns b (u_R^3 - u_L^3) / l_w faster than the
/// wheels' nominal yaw rate, with u_R,L = v +- omega l_w / 2: b (3 v^2 omega + l_w^2 omega^3 / 4)
/// (b in 1 / (m/s)^2; l_w the nominal track width).
double kinematicLibraryValue(const KinRows& k, int j, int i, double track_m) {
  const double T = k.t1[i] - k.t0[i], w = k.omega[i];
  if (j == 0) return T * k.v[i];
  if (j == 1) return T * std::abs(w);
  if (j == 2) return T * w * std::abs(w);
  if (j == 3) return T * std::cos(k.phi[i]);
  if (j == 4) return T * std::sin(k.phi[i]);
  if (j == 5) return T * k.v[i] * w;
  return T * (3 * k.v[i] * k.v[i] * w + 0.25 * track_m * track_m * w * w * w);
}

/// Stage 1 terms outside the catalogue: STLSQ over a library of window integrals.
void kinematicUnmodeled(const Selection& sel, const KinRows& kf2, const KinRows& kv2,
                        const Eigen::VectorXd& rv_after, int lags,
                        const config::WheelchairConfig& cfg, const DiagnosisOptions& opt,
                        DiagnosisReport& rep) {
  // The library's columns made when read, not stored (memory, docs/benchmarks.md, "Ninth
  // round, stage 1").
  const double lw = cfg.vehicle.geom.track_width_m;
  auto view = [lw](const KinRows& k) {
    return Library{static_cast<int>(k.y.size()), 7,
                   [&k, lw](int j, int r0, int n) -> Eigen::VectorXd {
                     Eigen::VectorXd c(n);
                     for (int r = 0; r < n; ++r) c(r) = kinematicLibraryValue(k, j, r0 + r, lw);
                     return c;
                   }};
  };
  const Eigen::VectorXd& rf = sel.fit.residual;
  SparseResult sr = stlsq(view(kf2), rf, kf2.groups, view(kv2), rv_after, kv2.groups, lags, opt,
                          opt.min_relevance * cfg.imu.gyro_noise_rad_s * opt.window_s);
  if (!sr.accepted) return;
  static const std::vector<std::string> names = {
      "v", "|omega|", "omega*|omega|", "cos(phi)", "sin(phi)", "v*omega", "(u_R^3-u_L^3)/l_w"};
  Finding f = unmodeledFinding(sr, names, "gyro_vs_encoders", "gyro - odometric turn rate",
                               "turn-rate consistency", "rad/s", "rad");
  f.physics = describeKinematicTerms(f);
  if (!f.physics.empty()) f.description += "; physically: " + physicsSummary(f.physics);
  rep.addFinding(f);
}

/// Why a gyro-vs-encoder time offset `delay_s` (> 0: the gyro stamps late) cannot be told
/// from the vehicle's own mechanics; empty if it can. The encoders measure the wheels, the
/// gyro the chassis: between them are the tyre contacts and the chassis' compliance, which
/// make the chassis' yaw lag its wheels (tyre creep / relaxation). An offset shorter than one
/// sample period of the later-stamped stream is below the time resolution of the recording,
/// so it is not named a sensor delay; a mechanical lag would show as an offset that grows at
/// low speed (a relaxation length over the speed), a time stamp's would not.
std::string delayBelowSampling(const std::vector<Streams>& recs, double delay_s) {
  std::vector<double> dt;
  for (const Streams& s : recs) {
    const std::vector<double>& t = delay_s > 0 ? s.tg : s.te;
    for (size_t i = 1; i < t.size(); ++i) dt.push_back(t[i] - t[i - 1]);
  }
  if (dt.empty()) return {};
  const double period_s = stats::median(dt);
  if (std::abs(delay_s) >= period_s) return {};
  return fmt::format(
      "the {} lags the {} by {:.1f} ms, less than one {} sample period ({:.1f} ms): cannot tell a "
      "sensor time-stamp delay from the chassis' own lag behind its wheels (tyre creep, "
      "compliance); not reported. To tell them apart: turns at two speeds (a tyre's lag scales "
      "with 1/speed, a time stamp's does not)",
      delay_s > 0 ? "gyro" : "encoders", delay_s > 0 ? "encoders" : "gyro", 1e3 * std::abs(delay_s),
      delay_s > 0 ? "gyro" : "encoder", 1e3 * period_s);
}

/// Stage 1's accepted gyro scale checked against the ground-truth heading
/// (gyroScaleAgainstTruth, EncoderSide.h), evidence in rep.info["gyro_scale_by_truth"]; what
/// the truth does not give the gyro is the encoders' effective geometry, which the kinematic
/// calibration fits against the truth poses. Without ground truth the ambiguity is said
/// (rep.info["cannot_tell"]). Not tested: no gyro scale accepted, or no ground truth.
GyroTruthDecision gyroScaleByTruth(const StageData& data, const Selection& sel,
                                   const std::vector<Candidate>& cands, const KinRows& kf2,
                                   double delay_s, double min_contribution_rms, double alpha_b,
                                   DiagnosisReport& rep) {
  const int G = candidateIndex(cands, "gyro_scale");
  const auto it = std::find(sel.accepted.begin(), sel.accepted.end(), G);
  if (G < 0 || it == sel.accepted.end()) return {};
  const auto& range = sel.ranges[static_cast<std::size_t>(it - sel.accepted.begin())];
  const double b1 = sel.fit.beta(range.first);
  const double sd1 = std::sqrt(std::max(0.0, sel.fit.cov(range.first, range.first)));
  const Eigen::VectorXd col = kf2.X * cands[G].S;
  GyroTruthDecision d = gyroScaleAgainstTruth(data.fit, std::max(0.0, delay_s), b1, sd1, col,
                                              min_contribution_rms, alpha_b);
  if (!d.evidence.empty()) rep.info["gyro_scale_by_truth"] = d.evidence;
  if (!d.tested) {
    rep.info["cannot_tell"].push_back(fmt::format(
        "the gyro reads {:.4f} x the encoders' yaw rate; the gyro scale and the encoders' "
        "effective geometry (rolling radius, track) off by the same fraction look the same to "
        "the gyro-vs-encoder comparison. To tell: ground-truth poses (motion capture) or turns "
        "of a known angle",
        1 + b1));
  }
  return d;
}

/// The gyro-scale finding with the value the ground truth measured (GyroTruthDecision::b).
void describeGyroByTruth(Finding& f, const Candidate& c, const Selection& sel, std::size_t a,
                         const effects::TermFit& fit, const GyroTruthDecision& d) {
  Selection s = sel;
  s.fit.residual = Eigen::VectorXd();
  const int i = s.ranges[a].first;
  s.fit.beta(i) = d.b;
  s.fit.cov.row(i).setZero(), s.fit.cov.col(i).setZero();
  s.fit.cov(i, i) = d.sd_b * d.sd_b;
  effects::TermFit ft = fit;
  ft.coef[c.name] = d.b, ft.sigma[c.name] = d.sd_b;
  describeFinding(f, c, s, a, ft);
  f.description += fmt::format(
      " (measured against the ground-truth heading; the gyro-vs-encoder comparison reads "
      "{:.4f}: the rest is the encoders' effective geometry)",
      1 + d.b_stage1);
}

/// Stage 1: the gyro integral over encoder windows against the odometric heading change.
/// Sets the sensor corrections (gyro, encoder scales, delay) in `corr`.
void kinematicStage(const StageData& data, const config::WheelchairConfig& cfg,
                    const DiagnosisOptions& opt, Corrections& corr, DiagnosisReport& rep) {
  const int lags = 5;
  auto cands = kinematicCandidates(opt.enable_delay);
  KinRows kf = kinematicRows(data.fit, corr, cfg, opt),
          kv = kinematicRows(data.val, corr, cfg, opt);
  SelectionData sd{
      kf.y,      kv.y,      kf.X, kv.X,
      kf.groups, kv.groups, lags, opt.min_relevance * cfg.imu.gyro_noise_rad_s * opt.window_s};
  Selection sel = forwardSelect(sd, cands, opt);
  double alpha_b = selectionRule(opt, cands.size()).level();
  // Re-built rows with the re-estimated delay; without a delay kf, kv themselves (no copy).
  DelayRefit<KinRows> refit;
  const KinRows* pkf2 = &kf;
  const KinRows* pkv2 = &kv;
  if (const int di = acceptedIndex(sel, cands, "sensor_delay/imu"); di >= 0) {
    refit = refineDelay<KinRows>(sel, di, cands, opt, lags, sd.min_contribution_rms,
                                 [&](bool fit, double delay) {
                                   Corrections c2;
                                   c2.delay_imu = delay;
                                   return kinematicRows(fit ? data.fit : data.val, c2, cfg, opt);
                                 });
    pkf2 = &refit.fit;
    pkv2 = &refit.val;
  }
  const KinRows& kf2 = *pkf2;
  const KinRows& kv2 = *pkv2;
  // which encoder: ground truth or the currents decide when the gyro cannot (EncoderSide.h)
  const EncoderSideDecision side_truth =
      resolveEncoderSide(*data.fit_recs, data.fit_fraction, cfg, kf2, cands, sel, lags, alpha_b,
                         data.any_mot ? &data.fit : nullptr, &opt);
  if (!side_truth.evidence.empty()) rep.info["encoder_side"] = side_truth.evidence;
  const effects::TermFit fit = termFit(sel, cands, cfg, refit.delay);
  const double bg = fit.value("gyro_scale"), g = 1 + bg;
  const GyroTruthDecision gyro_truth =
      gyroScaleByTruth(data, sel, cands, kf2, refit.delay, sd.min_contribution_rms, alpha_b, rep);
  corr.gyro_scale = !gyro_truth.tested           ? g
                    : !gyro_truth.report         ? 1.0
                    : gyro_truth.use_truth_value ? 1 + gyro_truth.b
                                                 : g;
  corr.gyro_bias = fit.value("gyro_bias");
  corr.enc_scale[0] = g / (1 + bg + fit.value("encoder_scale/right"));
  corr.enc_scale[1] = g / (1 + bg + fit.value("encoder_scale/left"));
  if (refit.delay > 0)
    corr.delay_imu = refit.delay;
  else
    corr.delay_enc = -refit.delay;
  // residuals before/after on validation
  Eigen::VectorXd rv_after = kv2.y - acceptedDesign(kv2.X, cands, sel.accepted) * sel.fit.beta;
  double nv_per = 0;
  {
    double T = 0;
    for (int i = 0; i < kv.X.rows(); ++i) T += kv.t1[i] - kv.t0[i];
    nv_per = kv.X.rows() ? kf.noise_var_per_s * T / kv.X.rows() + kf.noise_var_const : 0;
  }
  if (const std::string why = encoderScaleUndetectable(kf, cands, sel.accepted, alpha_b);
      !why.empty())
    rep.info["insufficient_data"].push_back(why);
  rep.channels["gyro_vs_encoders"] = {
      {"unit", "rad per window"},
      {"window_s", opt.window_s},
      {"before", channelMetrics(kv.y, kv.groups, lags, nv_per)},
      {"after", channelMetrics(rv_after, kv2.groups, lags, nv_per)},
      {"regimes_before", regimeStats(kf.y, kf.v, kf.omega, {}, kf.phi, lags, opt.alpha)},
      {"rejected_candidates", sel.log}};
  auto regimes = biasedRegimes(rep.channels["gyro_vs_encoders"]["regimes_before"]);
  double sigma = std::sqrt(sel.fit.rss / std::max<Eigen::Index>(1, kf2.y.size()));
  for (size_t a = 0; a < sel.accepted.size(); ++a) {
    const Candidate& c = cands[sel.accepted[a]];
    Finding f = termFinding(c, sel.steps[a], alpha_b, regimes, "gyro_vs_encoders", "rad",
                            kv.y.size(), kf.y.size());
    f.channels = {"gyro", "encoders"};
    Eigen::VectorXd contrib =
        (kf2.X * c.S) * sel.fit.beta.segment(sel.ranges[a].first, sel.ranges[a].second);
    std::vector<std::pair<double, double>> tc;
    for (int i = 0; i < contrib.size(); ++i)
      tc.push_back({0.5 * (kf2.t0[i] + kf2.t1[i]), contrib(i)});
    f.segments = activeSegments(tc, sigma);
    if (c.effect == "encoder_scale") {
      // Which side: the data must tell a short one from a long other one.
      const int other = candidateIndex(
          cands, c.name == "encoder_scale/right" ? "encoder_scale/left" : "encoder_scale/right");
      if (const std::string why = side_truth.decided
                                      ? std::string()
                                      : encoderSideUndecided(kf2, cands, sel.accepted,
                                                             sel.accepted[a], other, alpha_b, lags);
          !why.empty()) {
        rep.info["insufficient_data"].push_back(why);
        rep.mismatch = true;  // the encoders disagree, only the side is undecided
        corr.enc_scale[0] = corr.enc_scale[1] = 1.0;  // none written, so none applied after
        continue;
      }
    }
    if (c.name == "gyro_scale" && gyro_truth.tested && !gyro_truth.report) continue;
    if (c.name == "gyro_scale" && gyro_truth.use_truth_value) {
      describeGyroByTruth(f, c, sel, a, fit, gyro_truth);
      rep.addFinding(f);
      continue;
    }
    if (c.effect == "sensor_delay") {
      if (const std::string why = delayBelowSampling(data.fit, refit.delay); !why.empty()) {
        rep.info["cannot_tell"].push_back(why);
        corr.delay_imu = corr.delay_enc = 0;  // not reported, so not applied after
        continue;
      }
    }
    describeFinding(f, c, sel, a, fit);
    rep.addFinding(f);
  }
  if (opt.enable_unmodeled) kinematicUnmodeled(sel, kf2, kv2, rv_after, lags, cfg, opt, rep);
}

// ---------------- stage 2: dynamics in current space ----------------

/// Rows [left ? nR : 0, left ? 2 nR : nR) of a right-then-left group list, re-based.
Groups half(const Groups& g, int nR, bool left) {
  Groups o;
  for (auto [a, b] : g)
    if ((a >= nR) == left)
      o.push_back(left ? std::make_pair(a - nR, b - nR) : std::make_pair(a, b));
  return o;
}

/// The current_right / current_left channel metrics (before, after, fully nominal, regimes).
void dynamicChannels(const DynRows& df, const DynRows& dv, const DynRows& dv2, const DynRows& dn,
                     const Eigen::VectorXd& rv_after, const Selection& sel, int lags,
                     const DiagnosisOptions& opt, DiagnosisReport& rep) {
  int nRv = static_cast<int>(dv.y.size() / 2), nRv2 = static_cast<int>(dv2.y.size() / 2);
  const int nRn = static_cast<int>(dn.y.size() / 2);
  for (int sd2 = 0; sd2 < 2; ++sd2) {
    std::string ch = sd2 == 0 ? "current_right" : "current_left";
    int nRf = static_cast<int>(df.y.size() / 2);
    const auto &v = df.grid.v, &w = df.grid.omega, &vd = df.grid.vdot, &ph = df.grid.phi;
    rep.channels[ch] = {
        {"unit", "A (equation error of (6), zero-phase filtered)"},
        {"cutoff_hz", opt.cutoff_hz},
        {"before", channelMetrics(dv.y.segment(sd2 * nRv, nRv), half(dv.groups, nRv, sd2 == 1),
                                  lags, dv.noise_var)},
        {"after", channelMetrics(rv_after.segment(sd2 * nRv2, nRv2),
                                 half(dv2.groups, nRv2, sd2 == 1), lags, dv.noise_var)},
        {"before_nominal", channelMetrics(dn.y.segment(sd2 * nRn, nRn),
                                          half(dn.groups, nRn, sd2 == 1), lags, dn.noise_var)},
        {"regimes_before",
         regimeStats(df.y.segment(sd2 * nRf, nRf), v, w, vd, ph, lags, opt.alpha)},
        {"rejected_candidates", sel.log}};
  }
}

/// Library terms that are functions of the motor's own rim speed u alone (1, sgn(u), |u|,
/// u^2): the shape of a friction law F(u).
bool frictionShapeTerm(int j) {
  return j == 0 || j == 5 || j == 6 || j == 7;
}

/// The terms of `sr` for which `which` is true (coefficients, sigmas and cross-validation
/// numbers; the evidence and held-out RMS stay those of the whole set).
SparseResult sparseSubset(const SparseResult& sr, const std::function<bool(int)>& which) {
  SparseResult out = sr;
  out.terms.clear();
  std::vector<double> c, e;
  for (size_t k = 0; k < sr.terms.size(); ++k)
    if (which(sr.terms[k]))
      out.terms.push_back(sr.terms[k]), c.push_back(sr.coef(k)), e.push_back(sr.se(k));
  out.coef = Eigen::Map<Eigen::VectorXd>(c.data(), static_cast<Eigen::Index>(c.size()));
  out.se = Eigen::Map<Eigen::VectorXd>(e.data(), static_cast<Eigen::Index>(e.size()));
  return out;
}

/// A friction finding (coulomb_friction accepted on motor `ch`) gets the unmodeled terms that
/// are functions of that wheel's speed alone as the shape of its friction law (those below the
/// channel's unexplained structure too, marked `below_unexplained`: one law): the same
/// physics as the catalogue term, which only fixes the shape to the model's smooth sign (the
/// catalogue value plus these terms is the friction current as a function of u), not a new
/// effect (issue 16).
void addFrictionShape(Finding& friction, const SparseResult& shape, const std::string& ch) {
  nlohmann::json terms = nlohmann::json::object();
  std::string eq;
  for (size_t k = 0; k < shape.terms.size(); ++k) {
    const std::string& nm = dynLibNames()[shape.terms[k]];
    terms[nm] = {{"coefficient_A", shape.coef(k)}, {"sigma_A", shape.se(k)}};
    if (const std::string key = std::to_string(shape.terms[k]); shape.cv.contains(key))
      terms[nm]["blocked_cv"] = shape.cv[key];
    for (const auto& c : shape.cannot_tell)  // below the channel's unexplained structure
      if (c["term"].get<int>() == shape.terms[k]) terms[nm]["below_unexplained"] = c;
    eq += fmt::format(" {:+.3g}*{}", shape.coef(k), nm);
  }
  friction.evidence["friction_shape"][ch] = terms;
  if (!friction.description.empty() && friction.description.back() != '.')
    friction.description += '.';
  friction.description += " The friction current of " + ch +
                          " is not the model's smooth sign of the wheel speed u: beyond it" + eq +
                          " A (the shape of the friction law, e.g. stiction; not a new effect).";
}

/// Whether two motors' coefficients b (1-sigma sd) are one: the same sign and equal within 10 %
/// of the larger or 3 sigma of the difference.
bool equalOnBothMotors(const double b[2], const double sd[2]) {
  if (b[0] * b[1] <= 0) return false;
  const double diff = std::abs(b[0] - b[1]);
  return diff <= 0.1 * std::max(std::abs(b[0]), std::abs(b[1])) ||
         diff <= 3 * std::hypot(sd[0], sd[1]);
}

/// The two readings of two motors' coefficients b (1-sigma sd > 0; 0 right, 1 left) of a
/// motor-asymmetry column: one extra load on both motors, b_R = b_L = c (c their
/// inverse-variance mean, sd_c = (sum_i 1/sd_i^2)^-1/2; chi2_both = sum_i (b_i - c)^2 / sd_i^2),
/// or a load on one motor only, `side`, the other zero (chi2_one = min_i (b_i / sd_i)^2, side
/// the other motor than the minimiser). One free parameter each: chi^2 with 1 degree of freedom.
struct AsymmetryOrLoad {
  double c = 0, sd_c = 0, chi2_both = 0, chi2_one = 0;
  int side = 0;
};
AsymmetryOrLoad asymmetryOrLoad(const double b[2], const double sd[2]) {
  AsymmetryOrLoad r;
  const double w0 = 1 / (sd[0] * sd[0]), w1 = 1 / (sd[1] * sd[1]);
  r.c = (w0 * b[0] + w1 * b[1]) / (w0 + w1), r.sd_c = 1 / std::sqrt(w0 + w1);
  r.chi2_both = w0 * (b[0] - r.c) * (b[0] - r.c) + w1 * (b[1] - r.c) * (b[1] - r.c);
  const double zero[2] = {w0 * b[0] * b[0], w1 * b[1] * b[1]};  // that motor's term zero
  r.side = zero[0] <= zero[1] ? 1 : 0;
  r.chi2_one = std::min(zero[0], zero[1]);
  return r;
}

/// Whether one extra load on both motors (b_R = b_L = c, c their inverse-variance mean) fits
/// the two coefficients b (1-sigma sd) at least as well as a load on one motor only (the other
/// zero; the better side): chi^2 of the first sum_i (b_i - c)^2 / sd_i^2 against min_i
/// (b_i / sd_i)^2, one free parameter each. equalOnBothMotors alone cannot tell "equal" from
/// "one poorly determined": MuJoCo triple 976019, a left asymmetry 1.49 with the right
/// column fitted beside it, 0.073 +- 0.099 against 0.465 +- 0.103, is within 3 sigma of the
/// difference, but the right motor's zero fits it (chi^2 0.55 against 7.5 for one load).
bool loadOnBothMotorsFitsBetter(const AsymmetryOrLoad& r) {
  return r.chi2_both <= r.chi2_one;
}

/// A motor asymmetry not named because one load on both motors fits the two coefficients b
/// (sd) better (oneLoadOnBothMotors) is "cannot tell" when neither reading is rejected by them
/// (both chi^2 <= kReadingRejectedChi2): the note for info.cannot_tell, with both readings
/// and what to drive to tell them apart; empty when one reading is rejected (then the choice
/// is the data's). A drive at one speed per manoeuvre gives a one-motor viscous term and an
/// equal load on both motors nearly the same columns, so a small asymmetry's coefficients on
/// the two motors are both within noise of equal and of (x, 0) (MuJoCo seed 7 single 132242,
/// a right asymmetry 1.17: right 0.129 +- 0.056, left 0.066 +- 0.040, chi^2 0.83 against 2.7).
std::string untoldAsymmetryOrLoad(const double b[2], const double sd[2], const AsymmetryOrLoad& r) {
  // chi^2 with one degree of freedom at the 5 % level: a reading of the two motors'
  // coefficients (two numbers, one free parameter) whose chi^2 exceeds it is rejected by them.
  const double kReadingRejectedChi2 = stats::chi2Quantile(0.95, 1);
  if (r.chi2_both > kReadingRejectedChi2 || r.chi2_one > kReadingRejectedChi2) return {};
  const char* side = r.side == 0 ? "right" : "left";
  const char* other = r.side == 0 ? "left" : "right";
  return fmt::format(
      "motor_asymmetry/{0} or a load on both motors: this drive cannot tell a {0} motor "
      "asymmetry (viscous friction ratio {2:.3f} +- {3:.3f}, the {1} motor unchanged: chi^2 "
      "{4:.2f}) from the same extra load on both motors (viscous friction x {5:.3f} +- {6:.3f} "
      "on each, or a drag along the heading: chi^2 {7:.2f}); neither reading is rejected "
      "(chi^2_1 5 % level {8:.2f}); the motor asymmetry is not named. To tell: straight runs at "
      "several speeds, forward and back (a viscous term of one motor raises that motor's "
      "current alone, a load on both raises both alike), and turns on the spot both ways (a "
      "one-motor term acts on that motor alone; a drag along the heading acts on neither)",
      side, other, 1 + b[r.side], sd[r.side], r.chi2_one, 1 + r.c, r.sd_c, r.chi2_both,
      kReadingRejectedChi2);
}

/// The fit of the design D with the candidates' columns `extra` beside it (df's rows, HAC
/// covariance), and a column's coefficient with its 1-sigma sd.
LinearFit fitBeside(const Eigen::MatrixXd& D, std::initializer_list<const Candidate*> extra,
                    const DynRows& df, int lags) {
  Eigen::MatrixXd X(D.rows(), D.cols() + static_cast<Eigen::Index>(extra.size()));
  X.leftCols(D.cols()) = D;
  Eigen::Index q = D.cols();
  for (const Candidate* c : extra) X.col(q++) = df.design().times(c->S.col(0));
  return fitLinear(X, df.y, df.groups, lags);
}
void coefficientOf(const LinearFit& f, Eigen::Index q, double& b, double& sd) {
  b = f.beta(q), sd = std::sqrt(std::max(0.0, f.cov(q, q)));
}

/// A motor asymmetry's column and the other motor's, fitted together (b, sd), are one extra
/// load on both motors, not an asymmetry: equal (equalOnBothMotors) and better fitted by one
/// load on both than by one on either motor alone (loadOnBothMotorsFitsBetter; without sds
/// equalOnBothMotors decides). If so, `untold` is the note when the drive cannot tell the two
/// readings (untoldAsymmetryOrLoad; empty when it can).
bool oneLoadOnBothMotors(const double b[2], const double sd[2], std::string& untold) {
  if (!equalOnBothMotors(b, sd)) return false;
  if (!(sd[0] > 0) || !(sd[1] > 0)) {
    untold.clear();
    return true;
  }
  const AsymmetryOrLoad r = asymmetryOrLoad(b, sd);
  if (!loadOnBothMotorsFitsBetter(r)) return false;
  untold = untoldAsymmetryOrLoad(b, sd, r);
  return true;
}

/// Whether the selection accepted a motor asymmetry on BOTH sides with equal coefficients
/// (equalOnBothMotors): the same extra viscous friction on both motors. Accepted on ONE side
/// (the other's held-out check failed, e.g. on the held-out rows' other physics): the other
/// side's column is fitted beside the accepted design (df's fit rows) and compared so, and a
/// load on both motors must fit them better than one on the accepted side alone
/// (loadOnBothMotorsFitsBetter; MuJoCo seed 7 square 699374, a viscous drag, was named a left
/// motor asymmetry 1.081). `untold`: the note when the drive cannot tell the two readings
/// (untoldAsymmetryOrLoad), else unchanged.
bool symmetricAsymmetry(const Selection& sel, const std::vector<Candidate>& cands,
                        const DynRows& df, int lags, std::string& untold) {
  double b[2] = {0, 0}, sd[2] = {0, 0};
  int found = 0, side_found = -1;
  for (std::size_t a = 0; a < sel.accepted.size(); ++a) {
    const std::string& n = cands[sel.accepted[a]].name;
    const int side = n == "motor_asymmetry/right" ? 0 : (n == "motor_asymmetry/left" ? 1 : -1);
    if (side < 0) continue;
    coefficientOf(sel.fit, sel.ranges[a].first, b[side], sd[side]);
    ++found, side_found = side;
  }
  if (found == 2) return equalOnBothMotors(b, sd);
  if (found != 1) return false;
  const int other =
      candidateIndex(cands, side_found == 0 ? "motor_asymmetry/left" : "motor_asymmetry/right");
  if (other < 0) return false;
  const Eigen::MatrixXd D = acceptedDesign(df.design(), cands, sel.accepted);
  const LinearFit f = fitBeside(D, {&cands[other]}, df, lags);
  if (!f.ok) return false;
  for (std::size_t a = 0; a < sel.accepted.size(); ++a)
    if (cands[sel.accepted[a]].effect == "motor_asymmetry")
      coefficientOf(f, sel.ranges[a].first, b[side_found], sd[side_found]);
  coefficientOf(f, D.cols(), b[1 - side_found], sd[1 - side_found]);
  return oneLoadOnBothMotors(b, sd, untold);
}

/// The terms of motor `ch`'s sparse fit that are reported as `unmodeled`: a friction finding
/// (index friction_finding in rep.findings, -1: none) first takes the terms that are the shape
/// of its friction law (addFrictionShape), and terms below the channel's unexplained structure
/// (SparseResult::cannot_tell) go to info.cannot_tell. sr.accepted false: nothing is left.
void reportableTerms(SparseResult& sr, const std::string& ch, int friction_finding,
                     DiagnosisReport& rep) {
  if (const int fi = friction_finding; fi >= 0) {  // the friction law's shape first
    const SparseResult shape = sparseSubset(sr, frictionShapeTerm);
    if (!shape.terms.empty()) addFrictionShape(rep.findings[fi], shape, ch);
    sr = sparseSubset(sr, [](int j) { return !frictionShapeTerm(j); });
    if (sr.terms.empty()) {
      sr.accepted = false;
      return;
    }
  }
  std::vector<int> untold;  // in the fit, not reported
  for (const auto& c : sr.cannot_tell) {
    if (std::find(sr.terms.begin(), sr.terms.end(), c["term"].get<int>()) == sr.terms.end())
      continue;  // went into the friction shape
    untold.push_back(c["term"].get<int>());
    rep.info["cannot_tell"].push_back(fmt::format(
        "{}: a term {:+.3g}*{} predicts held-out data better, but its held-out contribution "
        "{:.3g} A is below the {:.3g} A of structure the model still leaves unexplained on "
        "this channel, which could produce it; not reported. To tell: drive where that term "
        "is excited and the rest is not (e.g. speed changes on straight runs for vdot, turns "
        "at constant speed for omega terms)",
        ch, c["coefficient"].get<double>(), dynLibNames()[untold.back()],
        c["heldout_contribution_rms"].get<double>(), c["unexplained_rms"].get<double>()));
  }
  sr = sparseSubset(
      sr, [&](int j) { return std::find(untold.begin(), untold.end(), j) == untold.end(); });
  if (sr.terms.empty()) sr.accepted = false;
}

/// Column j of the stage 2 term library on rows [r0, r0 + n) of d. The other motor's measured
/// current (column 13) is kept out: it reads as zero (stlsq skips zero columns).
Eigen::VectorXd unmodeledColumn(const DynRows& d, int j, int r0, int n) {
  if (j == 13) return Eigen::VectorXd::Zero(n);
  return d.libColumn(j, r0, n);
}

/// Stage 2 terms outside the catalogue: STLSQ per motor over the term library, on the residuals
/// of the catalogue fit on the fit rows and the validation rows of motor s2 (0 right, 1 left),
/// `residuals(s2)`: made when that motor is searched and released after (memory).
std::array<SparseResult, 2> dynamicUnmodeled(
    const DynRows& df2, const DynRows& dv2,
    const std::function<std::pair<Eigen::VectorXd, Eigen::VectorXd>(int)>& residuals, int lags,
    const config::WheelchairConfig& cfg, const DiagnosisOptions& opt) {
  std::array<SparseResult, 2> out;
  int nRf = static_cast<int>(df2.y.size() / 2), nRv2 = static_cast<int>(dv2.y.size() / 2);
  const int nlib = static_cast<int>(dynLibNames().size());
  for (int s2 = 0; s2 < 2; ++s2) {
    // This motor's rows of the library. i_self (column 12) is the measured quantity itself:
    // keep it out (it would absorb everything); the other motor's measured current (column 13)
    // carries the other equation's error (what both channels share, e.g. a forward drag, and its
    // noise): as a regressor it borrows that error instead of describing a physical term, so it
    // is kept out as well (issue 16; its physics - the coupling through the chassis - is spanned
    // by vdot and omegadot).
    const Library L{
        nRf, nlib, [&](int j, int r0, int n) { return unmodeledColumn(df2, j, s2 * nRf + r0, n); }};
    const Library Lv{nRv2, nlib, [&](int j, int r0, int n) {
                       return unmodeledColumn(dv2, j, s2 * nRv2 + r0, n);
                     }};
    const auto [rf, rv] = residuals(s2);
    out[s2] =
        stlsq(L, rf, half(df2.groups, nRf, s2 == 1), Lv, rv, half(dv2.groups, nRv2, s2 == 1), lags,
              opt, opt.min_relevance * cfg.motors.current_noise_A, 12, df2.noise_var, [](int j) {
                return j == 10 ? 11 : j == 11 ? 10 : -1;
              });
  }
  return out;
}

/// true: the column x lies nearly in the span of D (uncentred R^2 >= 0.9): |x - D D^+ x|^2 <=
/// 0.1 |x|^2. Beyond that the split between x and D is not identifiable from the drive (the
/// joint fit would trade large opposite coefficients).
bool inSpan(const Eigen::ColPivHouseholderQR<Eigen::MatrixXd>& qrD, const Eigen::MatrixXd& D,
            const Eigen::VectorXd& x) {
  const double n2 = x.squaredNorm();
  if (!(n2 > 0)) return true;
  if (D.cols() == 0) return false;
  return (x - D * qrD.solve(x)).squaredNorm() <= 0.1 * n2;
}

/// |cosine| of two library columns on a motor's rows above which the drive cannot tell the two
/// terms apart (harmoniseUntold).
constexpr double kUntoldCosine = 0.98;

/// Two out-of-catalogue terms the drive cannot tell apart, one found on each motor (e.g. on a
/// `square` drive whose turns on the spot all go one way at one rate, omega and omega^2 are
/// the same column up to a factor: |cosine| >= kUntoldCosine on both motors' rows): which
/// motor gets which is the noise's choice, and two different laws on the two motors read as
/// two physical effects (a yaw-rate term on one motor, a centripetal term on the other) where
/// the data show one. One law is used on both motors: the one whose single-column fits of both
/// motors' residuals (motorResidual(s2): the fit rows' residual of the right, s2 = 0, or left
/// motor) leave the smaller sum of squares; the motor
/// that had the other gets it in its place (coefficient: its least-squares fit there). Returns
/// what could not be told (for info.cannot_tell), empty when nothing was changed.
template <class MotorResidual>
std::string harmoniseUntold(std::array<SparseResult, 2>& u, const DynRows& df2,
                            const MotorResidual& motorResidual) {
  if (!(u[0].accepted && u[1].accepted)) return {};
  const int nR = static_cast<int>(df2.y.size() / 2);
  auto has = [&](int s2, int lib) {
    return std::find(u[s2].terms.begin(), u[s2].terms.end(), lib) != u[s2].terms.end();
  };
  // heading halves (10, 11) are one term; measured currents (12, 13) are no law
  auto law = [](int lib) { return lib < 10 || lib > 13; };
  std::array<std::optional<Eigen::VectorXd>, 2> r;  // each motor's residual, once needed
  for (int a : u[0].terms)
    for (int b : u[1].terms) {
      if (a == b || !law(a) || !law(b) || has(1, a) || has(0, b)) continue;
      double cos_min = 1;
      for (int s2 = 0; s2 < 2; ++s2) {
        const Eigen::VectorXd xa = df2.libColumn(a, s2 * nR, nR),
                              xb = df2.libColumn(b, s2 * nR, nR);
        const double na = xa.squaredNorm(), nb = xb.squaredNorm();
        cos_min =
            na > 0 && nb > 0 ? std::min(cos_min, std::abs(xa.dot(xb)) / std::sqrt(na * nb)) : 0.0;
      }
      if (cos_min < kUntoldCosine) continue;
      double rss[2] = {0, 0};  // a, b on both motors
      for (int s2 = 0; s2 < 2; ++s2) {
        const Eigen::VectorXd xa = df2.libColumn(a, s2 * nR, nR),
                              xb = df2.libColumn(b, s2 * nR, nR);
        if (!r[s2]) r[s2] = motorResidual(s2);
        const double na = xa.squaredNorm(), nb = xb.squaredNorm(), rr = r[s2]->squaredNorm();
        rss[0] += rr - std::pow(xa.dot(*r[s2]), 2) / na;
        rss[1] += rr - std::pow(xb.dot(*r[s2]), 2) / nb;
      }
      const int keep = rss[0] <= rss[1] ? a : b, drop = keep == a ? b : a, s2 = keep == a ? 1 : 0;
      SparseResult& sr = u[s2];
      const auto it = std::find(sr.terms.begin(), sr.terms.end(), drop);
      const Eigen::Index q = it - sr.terms.begin();
      const Eigen::VectorXd x = df2.libColumn(keep, s2 * nR, nR);
      const double coef = x.dot(*r[s2]) / x.squaredNorm();
      if (sr.coef(q) != 0) sr.se(q) *= std::abs(coef / sr.coef(q));
      sr.coef(q) = coef;
      *it = keep;
      sr.cv.erase(std::to_string(drop));
      const auto& nm = dynLibNames();
      return fmt::format(
          "out-of-catalogue terms {} ({} motor) and {} ({} motor): the same column on this drive "
          "(|cosine| {:.3f} on both motors' rows), which one acts cannot be told; reported as "
          "{} on both motors (the better fit of both). To tell: drive where they differ (e.g. "
          "turns at several rates and in both directions for omega vs omega^2)",
          nm[drop], s2 == 0 ? "right" : "left", nm[keep], s2 == 0 ? "left" : "right", cos_min,
          nm[keep]);
    }
  return {};
}

/// One motor's residual y - D beta (s2 = 0: right, the first half of the rows; 1: left) made
/// from its own rows only (not both motors' whole vectors, nor the whole products, held through
/// the search: memory). Row by row the same doubles as y - D beta: Eigen's matrix-vector
/// product of a few columns sums each row over the columns in order, whichever rows it is
/// given (not so its small-size products: a motor of fewer than 64 rows is cut from the whole
/// product).
Eigen::VectorXd motorResidual(const Eigen::VectorXd& y, const Eigen::MatrixXd& D,
                              const Eigen::VectorXd& beta, int s2) {
  const Eigen::Index n = y.size() / 2;
  if (n < 64) return (y - D * beta).segment(s2 * n, n);
  Eigen::VectorXd r = D.middleRows(s2 * n, n) * beta;
  r = y.segment(s2 * n, n) - r;
  return r;
}

/// An out-of-catalogue column of the joint fit: library column `lib` on the right (sides 0) or
/// left (1) motor's rows, or antisymmetric (2: + right, - left).
struct JointColumn {
  int lib, sides;
};

/// The unmodeled terms u carry the joint fit's coefficients: each motor's terms become the
/// columns `cols` on its rows (coefficient and sd of column k + c of f; an antisymmetric
/// column's coefficient negated on the left motor); a motor without any is no longer accepted.
void carryJointCoefficients(const std::vector<JointColumn>& cols, const LinearFit& f,
                            Eigen::Index k, std::array<SparseResult, 2>& u) {
  for (int s2 = 0; s2 < 2; ++s2) {
    SparseResult& sr = u[s2];
    std::vector<int> terms;
    std::vector<double> coef, se;
    for (size_t c = 0; c < cols.size(); ++c)
      if (cols[c].sides == s2 || cols[c].sides == 2) {
        const Eigen::Index q = k + static_cast<Eigen::Index>(c);
        terms.push_back(cols[c].lib);
        coef.push_back((cols[c].sides == 2 && s2 == 1 ? -1.0 : 1.0) * f.beta(q));
        se.push_back(std::sqrt(std::max(0.0, f.cov(q, q))));
      }
    sr.accepted = sr.accepted && !terms.empty();
    sr.terms = terms;
    sr.coef = Eigen::Map<Eigen::VectorXd>(coef.data(), coef.size());
    sr.se = Eigen::Map<Eigen::VectorXd>(se.data(), se.size());
  }
}

/// The catalogue's coefficients estimated jointly with the out-of-catalogue terms (issue 16).
/// Physics the model (6) lacks (on a multibody: the centre of mass ahead of the axle costs
/// -(m d c / 2) omega^2 on both motors) is correlated with catalogue columns (omega^2 >= 0 and
/// sgn(u) mostly > 0): fitted alone, a catalogue term absorbs part of it (Coulomb friction
/// 10-15 % low on MuJoCo drives) and the per-motor sparse search then finds the rest of the
/// catalogue term itself (`sgn(u)`). Here the terms the sparse search found are refitted
/// together with the catalogue design D on both motors' rows:
///  - a term found on one motor that D nearly spans there (inSpan) is the catalogue's: dropped;
///  - a term found on both motors whose sum over the motors D spans (D is symmetric, e.g.
///    coulomb_friction/both, ground_slope) enters as its antisymmetric part (+ right, - left):
///    the symmetric part is the catalogue's (a slope's cos(phi) on both motors is the slope,
///    the centre of mass' turn across the slope is the difference);
///  - terms below stlsq_threshold_sigma in the joint fit are dropped one at a time.
/// Then the sparse search runs again on the residual of the joint catalogue coefficients and the
/// joint fit is repeated once. Without out-of-catalogue terms nothing changes.
struct JointDynamicFit {
  Eigen::VectorXd beta;
  Eigen::MatrixXd cov;
  std::array<SparseResult, 2> unmodeled;
  bool refitted = false;  ///< the catalogue was refitted with out-of-catalogue terms
  std::string untold;     ///< harmoniseUntold's note (empty: none)
};
JointDynamicFit jointDynamicFit(const Selection& sel, const Eigen::MatrixXd& Df,
                                const Eigen::MatrixXd& Dv, const DynRows& df2, const DynRows& dv2,
                                int lags, const config::WheelchairConfig& cfg,
                                const DiagnosisOptions& opt) {
  JointDynamicFit j{sel.fit.beta, sel.fit.cov, {}, false, {}};
  const int nR = static_cast<int>(df2.y.size() / 2);
  // Df's QR (an n x k copy) is made after the search, not held through it (memory).
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qrD;
  for (int pass = 0; pass < 2; ++pass) {
    // Each motor's residuals, made when it is searched (motorResidual).
    auto residuals = [&](int s2) {
      return std::pair<Eigen::VectorXd, Eigen::VectorXd>{motorResidual(df2.y, Df, j.beta, s2),
                                                         motorResidual(dv2.y, Dv, j.beta, s2)};
    };
    j.unmodeled = dynamicUnmodeled(df2, dv2, residuals, lags, cfg, opt);
    j.untold = harmoniseUntold(j.unmodeled, df2,
                               [&](int s2) { return motorResidual(df2.y, Df, j.beta, s2); });
    if (Df.cols() == 0 || !(j.unmodeled[0].accepted || j.unmodeled[1].accepted)) break;
    if (pass == 0) qrD.compute(Df);
    std::vector<JointColumn> cols;
    auto has = [&](int s2, int lib) {
      const auto& t = j.unmodeled[s2].terms;
      return j.unmodeled[s2].accepted && std::find(t.begin(), t.end(), lib) != t.end();
    };
    auto sideCol = [&](int s2, int lib) {
      Eigen::VectorXd x = Eigen::VectorXd::Zero(df2.y.size());
      x.segment(s2 * nR, nR) = df2.libColumn(lib, s2 * nR, nR);
      return x;
    };
    // Every library term but the measured currents (12 i_self, 13 i_other: kept out of the
    // search, dynamicUnmodeled). v*|v| (14) and sgn(omega) (15), a forward drag and a dry yaw
    // moment, load both motors: they enter when found on both (before, they were dropped here
    // whenever the catalogue had a term, and a forward quadratic drag read as Coulomb friction;
    // found on one motor only, on MuJoCo v*|v| stood in for the centre of mass' v*omega).
    // cos(phi) (10) and sin(phi) (11) are one heading-dependent term (amplitude and phase, as
    // in stlsqWith): found on a motor by either half, both enter, so that the world frame's
    // orientation does not decide which half a motor carries (a slope's centre-of-mass current
    // -A sin(h - phi) on one motor, +A sin(h - phi) on the other).
    auto found = [&](int s2, int lib) {
      return (lib == 10 || lib == 11) ? has(s2, 10) || has(s2, 11) : has(s2, lib);
    };
    for (int lib = 0; lib < static_cast<int>(dynLibNames().size()); ++lib) {
      if (lib == 12 || lib == 13) continue;
      const bool r = found(0, lib), l = found(1, lib);
      if (lib >= 14 && !(r && l)) continue;
      // A heading term on one motor only, next to a catalogue term of both motors with that
      // heading dependence (a slope): gravity on the chair is a forward force (both motors
      // alike: the slope's) and a yaw moment (opposite), never one motor's load; a one-motor
      // column, half of each, would move part of the slope into one motor.
      const bool pair = (r && l) || ((lib == 10 || lib == 11) && (r || l));
      if (pair && inSpan(qrD, Df, sideCol(0, lib) + sideCol(1, lib)))
        cols.push_back({lib, 2});
      else
        for (int s2 = 0; s2 < 2; ++s2)
          if ((s2 == 0 ? r : l) && !inSpan(qrD, Df, sideCol(s2, lib))) cols.push_back({lib, s2});
    }
    // Rows [r0, r0 + nb) of the joint design [Df, the unmodeled columns] (never stored whole):
    // a column of sides 0 or 1 is sideCol(sides, lib), of sides 2 sideCol(0) - sideCol(1).
    auto jointRows = [&](long r0, long nb, Eigen::MatrixXd& A) {
      A.resize(nb, Df.cols() + static_cast<Eigen::Index>(cols.size()));
      A.leftCols(Df.cols()) = Df.middleRows(r0, nb);
      for (size_t c = 0; c < cols.size(); ++c) {
        auto x = A.col(Df.cols() + static_cast<Eigen::Index>(c));
        x.setZero();
        for (int s2 = 0; s2 < 2; ++s2) {  // this block's rows of motor s2
          if (cols[c].sides != 2 && cols[c].sides != s2) continue;
          const long a = std::max<long>(r0, s2 * nR), b = std::min<long>(r0 + nb, (s2 + 1) * nR);
          if (a >= b) continue;
          const Eigen::VectorXd lib =
              df2.libColumn(cols[c].lib, static_cast<int>(a), static_cast<int>(b - a));
          if (cols[c].sides == 2 && s2 == 1)
            x.segment(a - r0, b - a) = Eigen::VectorXd::Zero(b - a) - lib;  // 0 - x
          else
            x.segment(a - r0, b - a) = lib;
        }
      }
    };
    LinearFit f;
    for (;;) {  // joint fit; the weakest unmodeled column below the threshold goes
      f = fitLinear(jointRows, Df.cols() + static_cast<long>(cols.size()), df2.y, df2.groups, lags);
      if (!f.ok) {
        if (cols.empty()) break;
        cols.pop_back();
        continue;
      }
      double worst = std::numeric_limits<double>::infinity();
      size_t wk = 0;
      for (size_t c = 0; c < cols.size(); ++c) {
        const Eigen::Index q = Df.cols() + static_cast<Eigen::Index>(c);
        const double t = std::abs(f.beta(q)) / std::sqrt(std::max(1e-300, f.cov(q, q)));
        if (t < worst) worst = t, wk = c;
      }
      if (cols.empty() || worst >= opt.stlsq_threshold_sigma) break;
      cols.erase(cols.begin() + static_cast<long>(wk));
    }
    if (!f.ok) break;
    j.beta = f.beta.head(Df.cols());
    j.cov = f.cov.topLeftCorner(Df.cols(), Df.cols());
    j.refitted = j.refitted || !cols.empty();
    carryJointCoefficients(cols, f, Df.cols(), j.unmodeled);
  }
  return j;
}

/// After the joint fit (jointDynamicFit), the accepted catalogue term (index into sel.accepted)
/// that no longer holds: its coefficients implausible, their contribution below the relevance
/// floor, or not significant at the Bonferroni level (Wald, HAC covariance). A term accepted
/// only because it absorbed out-of-catalogue physics (e.g. a motor asymmetry next to Coulomb
/// friction, both taking the centre of mass' omega^2 current) shrinks here. Stream delays are
/// kept (their rows were rebuilt with them). -1: all hold; else the one with the least evidence.
int failingAfterJointFit(const Selection& sel, const std::vector<Candidate>& cands,
                         const Eigen::MatrixXd& Df, double min_contribution_rms, double alpha_b) {
  int worst = -1;
  double worst_wald = std::numeric_limits<double>::infinity();
  for (size_t a = 0; a < sel.accepted.size(); ++a) {
    const Candidate& c = cands[sel.accepted[a]];
    if (c.effect == "sensor_delay") continue;
    const auto [i, k] = sel.ranges[a];
    const Eigen::VectorXd b = sel.fit.beta.segment(i, k);
    const Eigen::MatrixXd C = sel.fit.cov.block(i, i, k, k);
    const double wald = b.dot(C.ldlt().solve(b));
    const double rms = (Df.middleCols(i, k) * b).norm() / std::sqrt(std::max<double>(1, Df.rows()));
    const bool holds = (!c.plausible || c.plausible(b)) && rms >= min_contribution_rms &&
                       wald >= stats::chi2Quantile(1 - alpha_b, k);
    if (!holds && wald < worst_wald) worst = static_cast<int>(a), worst_wald = wald;
  }
  return worst;
}

/// Removes accepted term `a` from the selection and its columns from the designs; the remaining
/// catalogue terms refitted alone on (Df, y).
void removeAccepted(Selection& sel, int a, Eigen::MatrixXd& Df, Eigen::MatrixXd& Dv,
                    const DynRows& df2, int lags) {
  const auto [i, k] = sel.ranges[a];
  auto dropCols = [i = i, k = k](Eigen::MatrixXd& D) {
    Eigen::MatrixXd E(D.rows(), D.cols() - k);
    E << D.leftCols(i), D.rightCols(D.cols() - i - k);
    D = std::move(E);
  };
  dropCols(Df), dropCols(Dv);
  sel.accepted.erase(sel.accepted.begin() + a);
  sel.steps.erase(sel.steps.begin() + a);
  sel.ranges.erase(sel.ranges.begin() + a);
  for (size_t q = a; q < sel.ranges.size(); ++q) sel.ranges[q].first -= k;
  sel.fit = fitLinear(Df, df2.y, df2.groups, lags);
}

/// A one-column catalogue term of ONE motor (a motor asymmetry, Coulomb friction of one side)
/// the forward selection did not accept (for addSpannedTerms, which makes its column on the fit
/// and validation rows when it tests it: not kept through the unmodeled-term search, 8 B per
/// row each; memory, docs/benchmarks.md). Terms of both motors (payload, slope,
/// Coulomb friction of both) predict the same coefficient on both motors, which per-motor
/// descriptions need not have (MuJoCo: vdot +0.09 A s^2/m on one motor, +0.12 on the other,
/// unexplained): they are not re-tested.
struct SpareTerm {
  int cand = -1;
};
std::vector<SpareTerm> spareTerms(const Selection& sel, const std::vector<Candidate>& cands,
                                  const DynRows& df2) {
  std::vector<SpareTerm> out;
  for (int ci = 0; ci < static_cast<int>(cands.size()); ++ci) {
    const Candidate& c = cands[ci];
    if (c.S.cols() != 1 || c.effect == "sensor_delay" ||
        std::find(sel.accepted.begin(), sel.accepted.end(), ci) != sel.accepted.end())
      continue;
    const Eigen::VectorXd xf = df2.design().times(c.S.col(0));
    const Eigen::Index nR = xf.size() / 2;
    if (xf.head(nR).norm() > 0 && xf.tail(nR).norm() > 0) continue;  // one motor only
    out.push_back({ci});
  }
  return out;
}

/// Library terms (dynLibNames) that are a speed law: the rates v, omega, v*|v| and the friction
/// shapes of the rim speed u (frictionShapeTerm: 1, sgn(u), |u|, u^2). A motor asymmetry and a
/// load on both motors (viscous, dry or quadratic in speed) are made of these.
bool speedLawTerm(int j) {
  return j == 1 || j == 2 || j == 14 || frictionShapeTerm(j);
}

/// The out-of-catalogue terms found on each motor (`unmodeled`, the library terms `keep`
/// accepts) as columns over both motors' fit rows of df2 (zero on the other motor's rows).
template <class Keep>
Eigen::MatrixXd outOfCatalogueColumns(const std::array<SparseResult, 2>& unmodeled,
                                      const DynRows& df2, const Keep& keep) {
  const int nR = static_cast<int>(df2.y.size() / 2);
  int n = 0;
  for (int s2 = 0; s2 < 2; ++s2)
    if (unmodeled[s2].accepted)
      for (int lib : unmodeled[s2].terms) n += keep(lib) ? 1 : 0;
  Eigen::MatrixXd U = Eigen::MatrixXd::Zero(df2.y.size(), n);
  int k = 0;
  for (int s2 = 0; s2 < 2; ++s2)
    if (unmodeled[s2].accepted)
      for (int lib : unmodeled[s2].terms)
        if (keep(lib)) U.col(k++).segment(s2 * nR, nR) = df2.libColumn(lib, s2 * nR, nR);
  return U;
}

/// Whether both motors' asymmetry columns are spare (neither accepted) and, fitted together
/// beside the accepted design Df on the fit rows, are one load on both motors
/// (oneLoadOnBothMotors, the rule symmetricAsymmetry applies to one accepted side); `untold`
/// as there.
bool symmetricSpareAsymmetry(const std::vector<Candidate>& cands,
                             const std::vector<SpareTerm>& spare, const Eigen::MatrixXd& Df,
                             const DynRows& df2, int lags, std::string& untold) {
  int side_cand[2] = {-1, -1};  // right, left
  for (const SpareTerm& sp : spare) {
    const std::string& n = cands[sp.cand].name;
    if (n == "motor_asymmetry/right") side_cand[0] = sp.cand;
    if (n == "motor_asymmetry/left") side_cand[1] = sp.cand;
  }
  if (side_cand[0] < 0 || side_cand[1] < 0) return false;
  const LinearFit f = fitBeside(Df, {&cands[side_cand[0]], &cands[side_cand[1]]}, df2, lags);
  if (!f.ok) return false;
  double b[2], sd[2];
  for (int s2 = 0; s2 < 2; ++s2) coefficientOf(f, Df.cols() + s2, b[s2], sd[s2]);
  return oneLoadOnBothMotors(b, sd, untold);
}

/// A catalogue term rejected by the forward selection (typically by its held-out check, the
/// held-out residual being dominated by physics the catalogue lacks) that the out-of-catalogue
/// terms found then describe in full (its column nearly in their span, inSpan: e.g. `v` and
/// `omega` on the left motor in the ratio of u_L = v - omega l_w / 2, a left motor asymmetry)
/// is that catalogue term: it is added to the accepted set (its evidence the fit-data
/// likelihood ratio against the accepted terms) and the joint fit repeated, where
/// failingAfterJointFit still tests it. A motor asymmetry is not so added when the other
/// motor's asymmetry column, fitted beside it, takes an equal coefficient
/// (symmetricSpareAsymmetry): the same extra speed-dependent load on both motors is a load
/// along the heading (a drag), not an asymmetry, and the out-of-catalogue terms describe it
/// (MuJoCo 31337: quadratic drags 640403 and 220317 were named motor asymmetries). The two
/// columns are compared beside the accepted design AND the out-of-catalogue terms found but
/// the speed laws (speedLawTerm: the columns the two readings are made of): the other physics the
/// catalogue lacks (on a multibody the centre of mass' v*omega, omega^2 currents) left in the
/// residual inflates both sds until a one-motor term looks equal on both (MuJoCo seed 7 single
/// 132242, right asymmetry 1.17: right 0.129 +- 0.056, left 0.066 +- 0.040 beside the
/// catalogue alone, while the right motor's own search finds `v` 0.50 +- 0.014 and the left's
/// none). true if a term was added.
bool addSpannedTerms(Selection& sel, const std::vector<Candidate>& cands,
                     const std::vector<SpareTerm>& spare,
                     const std::array<SparseResult, 2>& unmodeled, Eigen::MatrixXd& Df,
                     Eigen::MatrixXd& Dv, const DynRows& df2, const DynRows& dv2, int lags) {
  const Eigen::MatrixXd U = outOfCatalogueColumns(unmodeled, df2, [](int) { return true; });
  if (U.cols() == 0) return false;
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qrU(U);
  bool added = false;
  std::string untold;  // the drive cannot tell the asymmetry from the load (once)
  // The other physics the catalogue lacks (the out-of-catalogue terms but the speed laws,
  // speedLawTerm, which are what an asymmetry or a load on both motors is made of) beside the
  // catalogue design: the two readings are compared on a residual without it.
  const Eigen::MatrixXd W =
      outOfCatalogueColumns(unmodeled, df2, [](int lib) { return !speedLawTerm(lib); });
  Eigen::MatrixXd DW(Df.rows(), Df.cols() + W.cols());
  DW << Df, W;
  const bool symmetric_load = symmetricSpareAsymmetry(cands, spare, DW, df2, lags, untold);
  for (const SpareTerm& sp : spare) {
    const Candidate& c = cands[sp.cand];
    bool conflict = false;
    for (int a : sel.accepted)
      for (const auto& n : c.conflicts) conflict = conflict || cands[a].name == n;
    for (int a : sel.accepted)
      for (const auto& n : cands[a].conflicts) conflict = conflict || c.name == n;
    if (conflict) continue;
    const Eigen::VectorXd xf = df2.design().times(c.S.col(0));
    if (!inSpan(qrU, U, xf)) continue;
    if (symmetric_load && c.effect == "motor_asymmetry") {
      sel.log.push_back(c.name +
                        ": described by the out-of-catalogue terms, but not named: both motors' "
                        "asymmetry columns fitted together take equal coefficients (a load on "
                        "both motors, not an asymmetry)");
      if (!untold.empty()) sel.cannot_tell.push_back(std::exchange(untold, {}));
      continue;
    }
    const LinearFit f0 = fitLinear(Df, df2.y, df2.groups, lags);
    Df.conservativeResize(Eigen::NoChange, Df.cols() + 1);
    Df.col(Df.cols() - 1) = xf;
    Dv.conservativeResize(Eigen::NoChange, Dv.cols() + 1);
    Dv.col(Dv.cols() - 1) = dv2.design().times(c.S.col(0));
    sel.fit = fitLinear(Df, df2.y, df2.groups, lags);
    SelectionStep st;
    st.candidate = sp.cand;
    st.rss0_fit = f0.rss, st.rss1_fit = sel.fit.rss;
    st.evidence = compareNested(f0.rss, sel.fit.rss, 1,
                                effectiveSampleSize(sel.fit.residual, df2.groups, lags));
    st.coef = sel.fit.beta.tail(1);
    sel.ranges.push_back({static_cast<int>(Df.cols()) - 1, 1});
    sel.accepted.push_back(sp.cand);
    sel.steps.push_back(st);
    sel.log.push_back(c.name + ": described in full by the out-of-catalogue terms found: named");
    added = true;
  }
  return added;
}

/// A catalogue term addSpannedTerms named (`named`: candidate indices) is kept only if it
/// predicts data it was not fitted on better (issue 16 item 2): blocked cross-validation
/// (blockedCvTerm, HeldOut.h; 10 time blocks over the fit rows followed by the validation rows,
/// both motors' rows of one instant next to each other, bootstrap blocks of 2 lags rows) of its
/// column, both beside the out-of-catalogue terms found on each motor (design [catalogue terms,
/// those terms]) and in their place (the catalogue terms alone: it was named because it
/// describes them). In both its mean held-out gain must be positive and its coefficient at
/// least z_{1 - alpha/2} times its block-to-block (jackknife) sd; alpha the family-wise level
/// (one confirmation per named term, not a search). Being nearly in the span of terms found on
/// the residual says it COULD be the catalogue term; the in-sample Wald test
/// (failingAfterJointFit) does not survive a model that misses physics. E.g. MuJoCo, slope 2.4
/// deg + Coulomb 0.55 A: a left motor asymmetry 1.033 is 5 sigma beside the centre-of-mass
/// terms (it corrects their shape) but alone its coefficient is -0.28 +- 0.19 (P(gain <= 0) =
/// 0.44): not kept; true asymmetries 1.17-1.46: 2.9-5 sd in their place, P 0.002-0.09, kept.
/// Returns the index into sel.accepted of the first such term not kept (`why`: the numbers),
/// else -1.
int unconfirmedNamedTerm(const Selection& sel, const std::vector<Candidate>& cands,
                         const std::vector<int>& named,
                         const std::array<SparseResult, 2>& unmodeled, const Eigen::MatrixXd& Df,
                         const Eigen::MatrixXd& Dv, const DynRows& df2, const DynRows& dv2,
                         int lags, double alpha, std::string& why) {
  const Eigen::Index nRf = df2.y.size() / 2, nRv = dv2.y.size() / 2, n = 2 * (nRf + nRv);
  std::vector<std::pair<int, int>> u;  // (motor, library term)
  for (int s2 = 0; s2 < 2; ++s2)
    if (unmodeled[s2].accepted)
      for (int lib : unmodeled[s2].terms) u.push_back({s2, lib});
  const Eigen::Index k = Df.cols() + static_cast<Eigen::Index>(u.size());
  // rows in time order: instant i's right-motor row, then its left-motor row
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n, k);
  Eigen::VectorXd y(n);
  auto place = [&](const Eigen::MatrixXd& D, const DynRows& d, Eigen::Index nR, Eigen::Index off) {
    for (int s2 = 0; s2 < 2; ++s2) {
      for (Eigen::Index i = 0; i < nR; ++i) {
        A.row(off + 2 * i + s2).head(D.cols()) = D.row(s2 * nR + i);
        y(off + 2 * i + s2) = d.y(s2 * nR + i);
      }
      for (size_t c = 0; c < u.size(); ++c) {
        if (u[c].first != s2) continue;
        const Eigen::VectorXd x =
            unmodeledColumn(d, u[c].second, static_cast<int>(s2 * nR), static_cast<int>(nR));
        for (Eigen::Index i = 0; i < nR; ++i) A(off + 2 * i + s2, D.cols() + c) = x(i);
      }
    }
  };
  place(Df, df2, nRf, 0);
  place(Dv, dv2, nRv, 2 * nRf);
  // The catalogue columns alone, block by block (no copy of A's left columns).
  const CvRows catalogueRows = [&A, &Df](Eigen::Index r0, Eigen::Index r1) {
    return Eigen::MatrixXd(A.block(r0, 0, r1 - r0, Df.cols()));
  };
  // Confirmation of a term already selected, one test per named term (not a search over the
  // catalogue: the family-wise alpha, not Bonferroni's): its held-out gain positive and its
  // coefficient beyond the block-to-block spread at 1 - alpha. The bootstrap's P(gain <= 0)
  // is reported, not required below alpha: true asymmetries 1.17-1.25 on MuJoCo excite have
  // P 0.002-0.09 at 2.9-5.2 sd; those named from the centre of mass' terms P >= 0.44, <= 1.5 sd.
  const double z = stats::normalQuantile(1 - alpha / 2);
  auto confirmed = [z](const BlockedCvTerm& cv) {
    return cv.testable && cv.mean_gain > 0 && std::abs(cv.coef) >= z * cv.coef_se;
  };
  for (size_t a = 0; a < sel.accepted.size(); ++a) {
    if (std::find(named.begin(), named.end(), sel.accepted[a]) == named.end()) continue;
    const int j = sel.ranges[a].first;
    // with the out-of-catalogue terms beside it, and in their place (the catalogue alone)
    const BlockedCvTerm with = blockedCvTerm(A, y, j, 10, 2 * std::max(1, lags));
    const BlockedCvTerm alone =
        blockedCvTerm(catalogueRows, A.rows(), Df.cols(), y, j, 10, 2 * std::max(1, lags));
    if (confirmed(with) && confirmed(alone)) continue;
    const BlockedCvTerm& cv = confirmed(with) ? alone : with;
    why = fmt::format(
        "{}: named from the out-of-catalogue terms, but not kept: {} it does not predict the "
        "time blocks it was not fitted on better (blocked cross-validation: mean gain {:.3g} A^2 "
        "per row, P(gain <= 0) = {:.3f}; coefficient {:.4g}, block-to-block sd {:.4g}; needed: "
        "gain > 0 and |coefficient| >= {:.3g} sd)",
        cands[sel.accepted[a]].name,
        confirmed(with) ? "in place of the out-of-catalogue terms" : "beside them", cv.mean_gain,
        cv.p_not_positive, cv.coef, cv.coef_se, z);
    return static_cast<int>(a);
  }
  return -1;
}

/// The motors (bit 0 right, bit 1 left) a component of channel `ch` (UnmodeledPhysics.h) acts on.
int componentMotors(const std::string& ch) {
  return ch == "current_right" ? 1 : ch == "current_left" ? 2 : 3;
}

/// The terms describeDynamicTerms left out because their own held-out prediction gets worse
/// (`dropped`) taken out of the motors' terms srs where no kept component of `physics` carries
/// them (issue 16 item 2: each term of an `unmodeled` finding judged on the held-out rows, not
/// only the finding as a whole); a motor left without terms is no longer accepted. What was left
/// out, with its numbers, goes to rep.info["rejected_heldout"].
void dropHeldOutWorse(std::array<SparseResult, 2>& srs,
                      const std::vector<DroppedComponent>& dropped, const nlohmann::json& physics,
                      DiagnosisReport& rep) {
  const auto& nm = dynLibNames();
  for (const DroppedComponent& w : dropped) {
    const std::string term = nm[w.term];
    const int motors = componentMotors(w.channel);
    rep.info["rejected_heldout"].push_back(
        {{"effect", "unmodeled"},
         {"term", term},
         {"channel", w.channel},
         {"rejected_by", "held-out rule, term " + term},
         {"reason", fmt::format("its own held-out prediction gets worse (realised likelihood "
                                "ratio {:.2f}, predicted {:.2f}): left out of the finding",
                                w.lr, w.expected_lr)}});
    for (int s2 = 0; s2 < 2; ++s2) {
      if (!(motors & (1 << s2))) continue;
      bool carried = false;
      for (const auto& c : physics) {  // (a heading component carries cos and sin)
        const std::string t = c["term"];
        carried = carried || ((componentMotors(c["channel"]) & (1 << s2)) &&
                              (t == term || (t == "cos(phi), sin(phi)" &&
                                             (term == "cos(phi)" || term == "sin(phi)"))));
      }
      if (carried) continue;
      srs[s2] = sparseSubset(srs[s2], [&](int j) { return j != w.term; });
      if (srs[s2].terms.empty()) srs[s2].accepted = false;
    }
  }
}

/// The out-of-catalogue terms of both motors (srs, from the joint fit) as findings: a friction
/// law's shape and terms below the unexplained structure set aside (reportableTerms), then
/// what the rest is physically, both motors' terms refitted jointly as forward / yaw /
/// one-motor components (UnmodeledPhysics.h) on the catalogue residuals rf (fit rows) and
/// rv_after (validation rows). friction[s]: rep.findings index of the friction on motor s.
void reportUnmodeled(std::array<SparseResult, 2> srs, const DynRows& df2, const DynRows& dv2,
                     const Eigen::VectorXd& rf, const Eigen::VectorXd& rv_after, int lags,
                     const config::WheelchairConfig& cfg, const DiagnosisOptions& opt,
                     const std::array<int, 2>& friction_finding, DiagnosisReport& rep) {
  const int nRf = static_cast<int>(df2.y.size() / 2), nRv2 = static_cast<int>(dv2.y.size() / 2);
  for (int s2 = 0; s2 < 2; ++s2)
    if (srs[s2].accepted)
      reportableTerms(srs[s2], s2 == 0 ? "current_right" : "current_left", friction_finding[s2],
                      rep);
  // What the kept terms are physically: both motors' terms refitted jointly as forward / yaw /
  // one-motor components (UnmodeledPhysics.h).
  std::vector<int> terms;
  for (const auto& sr : srs)
    if (sr.accepted)
      for (int j : sr.terms)
        if (std::find(terms.begin(), terms.end(), j) == terms.end()) terms.push_back(j);
  DynamicTermData td;
  td.column = [&](int j, int side, bool fit) {
    return fit ? unmodeledColumn(df2, j, side * nRf, nRf)
               : unmodeledColumn(dv2, j, side * nRv2, nRv2);
  };
  td.y_fit = rf, td.y_val = rv_after, td.groups_fit = df2.groups, td.lags = lags;
  td.groups_val = dv2.groups;
  td.min_expected_lr = opt.validation_min_expected_lr;
  td.worse_lr = stats::chi2Quantile(1 - opt.alpha, 1);
  std::vector<DroppedComponent> dropped;
  const nlohmann::json physics = describeDynamicTerms(terms, dynLibNames(), td, cfg, &dropped);
  dropHeldOutWorse(srs, dropped, physics, rep);
  for (int s2 = 0; s2 < 2; ++s2) {
    if (!srs[s2].accepted) continue;
    std::string ch = s2 == 0 ? "current_right" : "current_left";
    Finding f =
        unmodeledFinding(srs[s2], dynLibNames(), ch, ch + " - model", ch + " equation", "A", "A");
    for (const auto& c : physics) {  // the components this motor carries
      const std::string pc = c["channel"];
      if (pc == ch || pc == "forward" || pc == "yaw" || pc == "wheels") f.physics.push_back(c);
    }
    if (!f.physics.empty()) f.description += "; physically: " + physicsSummary(f.physics);
    rep.addFinding(f);
  }
}

/// The accepted one-column catalogue term (index into sel.accepted) that an out-of-catalogue
/// library term predicts better by blocked cross-validation (betterOutOfCatalogue,
/// UnmodeledPhysics.h), or -1; why goes to `log`. Stream delays are not tested (their rows are
/// rebuilt with them).
int supersededByOutOfCatalogue(const Selection& sel, const std::vector<Candidate>& cands,
                               const DynRows& df, int lags, double alpha_b,
                               std::vector<std::string>& log,
                               CatalogueAlternative* found = nullptr) {
  const int nR = static_cast<int>(df.y.size() / 2);
  DynamicTermData td;
  td.column = [&](int j, int side, bool) { return unmodeledColumn(df, j, side * nR, nR); };
  td.y_fit = df.y, td.groups_fit = df.groups, td.lags = lags;
  std::vector<int> lib;
  for (int j = 0; j < static_cast<int>(dynLibNames().size()); ++j)
    if (j != 12 && j != 13) lib.push_back(j);  // not the measured currents (dynamicUnmodeled)
  const Eigen::MatrixXd D = acceptedDesign(df.design(), cands, sel.accepted);
  const double crit = stats::chi2Quantile(1 - alpha_b, 1);
  for (std::size_t a = 0; a < sel.accepted.size(); ++a) {
    const Candidate& c = cands[sel.accepted[a]];
    if (c.effect == "sensor_delay" || sel.ranges[a].second != 1) continue;
    // The catalogue's one-column terms as dependence classes (UnmodeledPhysics.h).
    const std::string dep = c.effect == "coulomb_friction"  ? "sign_of_rate"
                            : c.effect == "motor_asymmetry" ? "rate"
                            : c.effect == "payload_mass"    ? "acceleration"
                                                            : "";
    const CatalogueAlternative alt =
        betterOutOfCatalogue(D, sel.ranges[a].first, dep, lib, dynLibNames(), td, crit);
    if (alt.term < 0) continue;
    log.push_back(fmt::format(
        "{}: not named, the out-of-catalogue term {} ({}) predicts the currents better "
        "(blocked cross-validation: likelihood ratio {:.1f} for it, {:.1f} for the catalogue "
        "term beside it; {:.1f} needed; the catalogue column is {:.0f} % in its span)",
        c.name, dynLibNames()[alt.term],
        alt.pattern == 2 ? "right motor" : (alt.pattern == 3 ? "left motor" : "both motors"),
        alt.lr_alt, alt.lr_c, crit, 100 * alt.r2));
    if (found) *found = alt;
    return static_cast<int>(a);
  }
  return -1;
}

/// A catalogue term superseded by an out-of-catalogue library term (selectCatalogue): the
/// candidate and the alternative (library index; pattern 0 both motors, 2 right, 3 left).
struct SupersededTerm {
  Candidate cand;
  int term = -1, pattern = 0;
};

/// The spare terms (spareTerms) without the superseded ones whose supersession the unmodeled
/// search confirmed. betterOutOfCatalogue compares the catalogue column with one library term
/// on the catalogue's residual, without the other physics the catalogue lacks (on a multibody
/// the centre of mass' v*omega and omega^2 currents); a one-motor u^2, which carries part of
/// that load, can then look better than a true motor asymmetry (u of that motor). The joint
/// search over the whole library (jointDynamicFit) settles it: if it keeps the alternative on
/// that motor, the load is the alternative's and the catalogue term stays out; if it does not
/// and describes the catalogue column in full instead (e.g. v and omega of the right motor in
/// the ratio of u_R = v + omega l_w / 2), the supersession was the comparison's artefact and the
/// term goes back to addSpannedTerms like any other rejected catalogue term (issue 16 item 4).
std::vector<SpareTerm> unconfirmedSupersessions(std::vector<SpareTerm> spare,
                                                const std::vector<Candidate>& cands,
                                                const std::vector<SupersededTerm>& gone,
                                                const std::array<SparseResult, 2>& unmodeled) {
  auto kept = [&](int s2, int lib) {
    const auto& t = unmodeled[s2].terms;
    return unmodeled[s2].accepted && std::find(t.begin(), t.end(), lib) != t.end();
  };
  spare.erase(std::remove_if(spare.begin(), spare.end(),
                             [&](const SpareTerm& sp) {
                               for (const SupersededTerm& g : gone) {
                                 if (g.cand.name != cands[sp.cand].name) continue;
                                 const bool r = kept(0, g.term), l = kept(1, g.term);
                                 return g.pattern == 2 ? r : (g.pattern == 3 ? l : (r || l));
                               }
                               return false;
                             }),
              spare.end());
  return spare;
}

/// Stage 2's catalogue selection (forwardSelect), selected again without a catalogue term the
/// data show is not that term: a motor asymmetry that is the same on both motors (a load the
/// catalogue does not have), or a term an out-of-catalogue term predicts better
/// (supersededByOutOfCatalogue; issue 16 item 3). cands and alpha_b follow the candidates left;
/// the superseded terms and what superseded them go to `gone` (unconfirmedSupersessions).
Selection selectCatalogue(const SelectionData& sd, std::vector<Candidate>& cands, const DynRows& df,
                          int lags, const DiagnosisOptions& opt, double& alpha_b,
                          std::vector<SupersededTerm>& gone) {
  Selection sel = forwardSelect(sd, cands, opt);
  std::vector<std::string> symmetric;
  std::string untold;  // the drive cannot tell the asymmetry from a load on both motors
  if (symmetricAsymmetry(sel, cands, df, lags, untold)) {
    // Both motors' viscous friction up by the same amount is no asymmetry: it is a load the
    // catalogue does not have (e.g. a drag proportional to speed). Not forced onto the
    // catalogue name: selected again without it, so the unmodeled terms describe it.
    std::vector<Candidate> rest;
    for (const auto& c : cands)
      if (c.effect != "motor_asymmetry") rest.push_back(c);
    cands = rest;
    alpha_b = selectionRule(opt, cands.size()).level();
    sel = forwardSelect(sd, cands, opt);
    symmetric.push_back(
        "motor_asymmetry: not named, the same extra viscous load on both motors (equal "
        "coefficients on both sides) is no asymmetry: a load the catalogue does not have");
  }
  // A catalogue term that an out-of-catalogue term predicts better is not forced onto the
  // catalogue (issue 16 item 3): selected again without it; the unmodeled search describes it.
  std::vector<std::string> superseded;
  while (opt.enable_unmodeled) {
    CatalogueAlternative alt;
    const int a = supersededByOutOfCatalogue(sel, cands, df, lags, alpha_b, superseded, &alt);
    if (a < 0) break;
    const std::string name = cands[sel.accepted[a]].name;
    gone.push_back({cands[sel.accepted[a]], alt.term, alt.pattern});
    cands.erase(std::remove_if(cands.begin(), cands.end(),
                               [&](const Candidate& c) { return c.name == name; }),
                cands.end());
    alpha_b = selectionRule(opt, cands.size()).level();
    sel = forwardSelect(sd, cands, opt);
  }
  sel.log.insert(sel.log.end(), symmetric.begin(), symmetric.end());
  sel.log.insert(sel.log.end(), superseded.begin(), superseded.end());
  if (!untold.empty()) sel.cannot_tell.push_back(untold);
  return sel;
}

/// The streams' columns set aside on a temporary file while stage 2 does not read them (memory:
/// the rows and the streams of a long drive together; docs/benchmarks.md, "Tenth round"). Stage
/// 2 never reads the gyro, Pozyx, ground truth nor the samples beyond the fit and held-out parts
/// (`idle`); the encoders and motor currents of the fit and held-out parts only while it makes
/// rows of them (`fit`, `val`; the fit parts' motor currents are never read after stage 2:
/// makeWholeStreams).
struct Stage2Spill {
  util::SpilledColumns idle{"diagnose: streams set aside during stage 2"};
  std::array<util::SpilledColumns, 2> rows{
      util::SpilledColumns{"diagnose: the fit parts' streams"},
      util::SpilledColumns{"diagnose: the held-out parts' streams"}};
  StageData& data;
  explicit Stage2Spill(StageData& d) : data(d) {
    for (auto* parts : {&data.fit, &data.val})
      for (Streams& s : *parts) idleColumns(s);
    for (auto& b : data.beyond)
      for (Streams& s : b) {
        idleColumns(s);
        for (auto* v : {&s.te, &s.sR, &s.sL, &s.tm, &s.iR, &s.iL}) idle.spill(*v);
      }
    setAside(false);
  }
  void idleColumns(Streams& s) {
    for (auto* v : {&s.tg, &s.gz}) idle.spill(*v);
    idle.spill(s.pozyx), idle.spill(s.gt);
  }
  /// The fit (true) or held-out (false) parts' encoders and motor currents onto the file (of
  /// the part k only, k >= 0).
  void setAside(bool fit, long k = -1) {
    std::vector<Streams>& parts = fit ? data.fit : data.val;
    for (std::size_t q = 0; q < parts.size(); ++q)
      if (k < 0 || static_cast<long>(q) == k)
        for (auto* v :
             {&parts[q].te, &parts[q].sR, &parts[q].sL, &parts[q].tm, &parts[q].iR, &parts[q].iL})
          rows[fit ? 0 : 1].spill(*v);
  }
  using MakeRows =
      std::function<DynRows(const std::vector<Streams>&, const std::function<void(std::size_t)>&)>;
  /// Rows of the fit (true) or held-out (false) parts made by `make`, their streams read back
  /// for it and each part's set aside again once copied (dynamicRows' `copied`).
  DynRows rowsOf(bool fit, const MakeRows& make) {
    rows[fit ? 0 : 1].restore();
    DynRows d = make(fit ? data.fit : data.val, [&](std::size_t k) { setAside(fit, long(k)); });
    setAside(fit);  // the parts without rows
    return d;
  }
  /// Everything back but the fit parts' motor currents (released).
  void restore() {
    rows[0].restore(), rows[1].restore(), idle.restore();
    for (Streams& s : data.fit)
      for (auto* v : {&s.tm, &s.iR, &s.iL}) std::vector<double>().swap(*v);
  }
};

/// The accepted catalogue terms (sel, their designs Df, Dv) estimated jointly with the
/// out-of-catalogue terms the sparse search finds (jointDynamicFit), repeated until stable:
/// a term addSpannedTerms named that does not predict in their place is removed
/// (unconfirmedNamedTerm), a term no longer significant beside them is removed
/// (failingAfterJointFit), and once, rejected catalogue terms the found terms describe in full
/// are named (addSpannedTerms). `unmodeled`: the last search's terms; what the drive cannot
/// tell apart goes to rep.info["cannot_tell"].
void catalogueWithUnmodeled(Selection& sel, std::vector<Candidate>& cands,
                            const std::vector<SupersededTerm>& superseded, Eigen::MatrixXd& Df,
                            Eigen::MatrixXd& Dv, const DynRows& df2, const DynRows& dv2, int lags,
                            double min_contribution_rms, double alpha_b,
                            const config::WheelchairConfig& cfg, const DiagnosisOptions& opt,
                            std::array<SparseResult, 2>& unmodeled, DiagnosisReport& rep) {
  // The unmodeled-term search reads the rows' signals (DynRows::libColumn).
  std::vector<SpareTerm> spare = spareTerms(sel, cands, df2);
  std::vector<int> named;  // candidates addSpannedTerms named (unconfirmedNamedTerm)
  std::string untold;      // the last joint fit's harmoniseUntold note
  for (bool retested = false;;) {
    JointDynamicFit joint = jointDynamicFit(sel, Df, Dv, df2, dv2, lags, cfg, opt);
    sel.fit.beta = joint.beta, sel.fit.cov = joint.cov;
    unmodeled = std::move(joint.unmodeled);
    untold = joint.untold;
    if (std::string why; !named.empty()) {
      if (const int a = unconfirmedNamedTerm(sel, cands, named, unmodeled, Df, Dv, df2, dv2, lags,
                                             opt.alpha, why);
          a >= 0) {
        sel.log.push_back(why);
        named.erase(std::find(named.begin(), named.end(), sel.accepted[a]));
        removeAccepted(sel, a, Df, Dv, df2, lags);
        continue;
      }
    }
    // No catalogue term left (e.g. the only one failed the joint fit): the out-of-catalogue
    // terms may still describe a rejected catalogue term in full (addSpannedTerms).
    if (!joint.refitted && !(Df.cols() == 0 && !retested)) break;
    int a = failingAfterJointFit(sel, cands, Df, min_contribution_rms, alpha_b);
    if (a < 0 && !retested) {
      retested = true;
      const std::size_t before = sel.accepted.size();
      if (addSpannedTerms(sel, cands, unconfirmedSupersessions(spare, cands, superseded, unmodeled),
                          unmodeled, Df, Dv, df2, dv2, lags)) {
        named.assign(sel.accepted.begin() + static_cast<std::ptrdiff_t>(before),
                     sel.accepted.end());
        continue;
      }
    }
    if (a < 0) break;
    sel.log.push_back(cands[sel.accepted[a]].name +
                      ": no longer significant and relevant when fitted jointly with the "
                      "out-of-catalogue terms");
    removeAccepted(sel, a, Df, Dv, df2, lags);
  }
  if (!untold.empty()) rep.info["cannot_tell"].push_back(untold);
}

bool dynamicStageOn(Stage2Spill& sp, const config::WheelchairConfig& cfg,
                    const DiagnosisOptions& opt, Corrections& corr, DiagnosisReport& rep);

/// Stage 2: the per-motor equation error of the drive model in current space, with the
/// stage 1 corrections applied. Sets corr.delay_motors. false: too little data. The streams
/// are set aside while not read (Stage2Spill); the fit parts' motor currents are released.
bool dynamicStage(StageData& data, const config::WheelchairConfig& cfg, const DiagnosisOptions& opt,
                  Corrections& corr, DiagnosisReport& rep) {
  Stage2Spill sp(data);
  const bool ok = dynamicStageOn(sp, cfg, opt, corr, rep);
  sp.restore();
  return ok;
}

bool dynamicStageOn(Stage2Spill& sp, const config::WheelchairConfig& cfg,
                    const DiagnosisOptions& opt, Corrections& corr, DiagnosisReport& rep) {
  auto cands = dynamicCandidates(cfg.vehicle.geom.body_mass_kg, opt.enable_delay);
  double alpha_b = selectionRule(opt, cands.size()).level();
  auto rowsWith = [&](const Corrections& c) {
    return [&cfg, &opt, c](const std::vector<Streams>& parts,
                           const std::function<void(std::size_t)>& copied) {
      return dynamicRows(parts, c, cfg, opt, copied);
    };
  };
  DynRows df = sp.rowsOf(true, rowsWith(corr));
  DynRows dv = sp.rowsOf(false, rowsWith(corr));
  // Stage 1 found nothing to correct: dv are the fully nominal model's rows too.
  const bool sensors_nominal = corr == Corrections{};
  int lags = static_cast<int>(std::ceil(2.0 * opt.grid_rate_hz / opt.cutoff_hz));
  if (!(df.y.size() > 50)) return false;
  SelectionData sd{
      df.y,      dv.y,      df.design(), dv.design(),
      df.groups, dv.groups, lags,        opt.min_relevance * cfg.motors.current_noise_A};
  std::vector<SupersededTerm> superseded;
  Selection sel = selectCatalogue(sd, cands, df, lags, opt, alpha_b, superseded);
  // The superseded terms stay candidates for addSpannedTerms (unconfirmedSupersessions),
  // appended: the selection's indices into cands are unchanged.
  for (const SupersededTerm& g : superseded) cands.push_back(g.cand);
  // The rows re-built with the re-estimated delay; without a delay df, dv themselves (no
  // copy: the rows are the bulk of diagnose's memory).
  DelayRefit<DynRows> refit;
  const DynRows* pf2 = &df;
  const DynRows* pv2 = &dv;
  if (const int di = acceptedIndex(sel, cands, "sensor_delay/motors"); di >= 0) {
    refit = refineDelay<DynRows>(sel, di, cands, opt, lags, sd.min_contribution_rms,
                                 [&](bool fit, double delay) {
                                   Corrections c2 = corr;
                                   c2.delay_motors = delay;
                                   return sp.rowsOf(fit, rowsWith(c2));
                                 });
    corr.delay_motors = refit.delay;
    pf2 = &refit.fit;
    pv2 = &refit.val;
  }
  // The selection's residual is not read after it (memory).
  sel.fit.residual = Eigen::VectorXd();
  std::array<SparseResult, 2> unmodeled;
  const DynRows& df2 = *pf2;
  const DynRows& dv2 = *pv2;
  // The accepted catalogue terms' designs (a few columns), then the catalogue estimated jointly
  // with what it does not contain (jointDynamicFit).
  Eigen::MatrixXd Df = acceptedDesign(df2.design(), cands, sel.accepted);
  Eigen::MatrixXd Dv = acceptedDesign(dv2.design(), cands, sel.accepted);
  if (opt.enable_unmodeled)
    catalogueWithUnmodeled(sel, cands, superseded, Df, Dv, df2, dv2, lags, sd.min_contribution_rms,
                           alpha_b, cfg, opt, unmodeled, rep);
  for (const std::string& why : sel.cannot_tell) rep.info["cannot_tell"].push_back(why);
  Eigen::VectorXd rv_after = dv2.y - Dv * sel.fit.beta;
  {
    // The fully nominal model (no sensor corrections either), as the report's figures show it.
    std::optional<DynRows> dn_rows;
    if (!sensors_nominal) dn_rows = sp.rowsOf(false, rowsWith(Corrections{}));
    dynamicChannels(df, dv, dv2, sensors_nominal ? dv : *dn_rows, rv_after, sel, lags, opt, rep);
  }
  std::vector<std::string> regimes;
  for (auto ch : {"current_right", "current_left"})
    for (auto& r : biasedRegimes(rep.channels[ch]["regimes_before"]))
      regimes.push_back(std::string(ch) + ":" + r);
  double sigma = std::sqrt(sel.fit.rss / std::max<Eigen::Index>(1, df2.y.size()));
  const effects::TermFit fit = termFit(sel, cands, cfg, refit.delay);
  bool asym_done = false;
  std::array<int, 2> friction{-1, -1};  // rep.findings index of the friction on each motor
  for (size_t a = 0; a < sel.accepted.size(); ++a) {
    const Candidate& c = cands[sel.accepted[a]];
    if (c.effect == "motor_asymmetry") {  // both sides make one finding
      if (asym_done) continue;
      asym_done = true;
    }
    int i = sel.ranges[a].first;
    int k = sel.ranges[a].second;
    Eigen::VectorXd b = sel.fit.beta.segment(i, k);
    Finding f =
        termFinding(c, sel.steps[a], alpha_b, regimes, "currents", "A", dv.y.size(), df.y.size());
    // (time, contribution) per fit row: the contribution Df_a b made block by block of rows
    // (row by row the same doubles, as in jointDynamicFit's residuals; the last block takes
    // the rest, so no block is small), tc sized once and handed over (memory: no whole
    // contribution vector, growth slack nor copy of tc).
    std::vector<std::pair<double, double>> tc;
    tc.reserve(static_cast<std::size_t>(Df.rows()));
    for (Eigen::Index r0 = 0, nb = 0; r0 < Df.rows(); r0 += nb) {
      nb = Df.rows() - r0 < 2 * stats::kDesignBlockRows ? Df.rows() - r0 : stats::kDesignBlockRows;
      const Eigen::VectorXd contrib = Df.middleCols(i, k).middleRows(r0, nb) * b;
      for (Eigen::Index q = 0; q < nb; ++q)
        tc.push_back({df2.grid.t[df2.step(static_cast<int>(r0 + q))], contrib(q)});
    }
    f.segments = activeSegments(std::move(tc), sigma);
    f.channels = {"current_right", "current_left"};
    describeFinding(f, c, sel, a, fit);
    rep.addFinding(f);
    if (c.effect == "coulomb_friction") {  // the motors it acts on
      const int idx = static_cast<int>(rep.findings.size()) - 1;
      if (c.name != "coulomb_friction/left") friction[0] = idx;
      if (c.name != "coulomb_friction/right") friction[1] = idx;
    }
  }
  if (opt.enable_unmodeled)
    reportUnmodeled(unmodeled, df2, dv2, df2.y - Df * sel.fit.beta, rv_after, lags, cfg, opt,
                    friction, rep);
  return true;
}

/// Dead reckoning against ground truth on the held-out parts, before and after the
/// corrections (before makeWholeStreams(), which consumes them).
void heldOutTrajectories(const StageData& data, const Corrections& corr,
                         const config::WheelchairConfig& cfg, DiagnosisReport& rep) {
  Corrections none;
  nlohmann::json tb = trajectoryJson(data.val, none, cfg), ta = trajectoryJson(data.val, corr, cfg);
  if (!tb.empty()) rep.validation["trajectory_heldout"] = {{"before", tb}, {"after", ta}};
}

/// Dead reckoning against ground truth on the whole recordings before and after the
/// corrections, and the corrections.
void verifyTrajectories(const StageData& data, const Corrections& corr,
                        const config::WheelchairConfig& cfg, DiagnosisReport& rep) {
  Corrections none;
  nlohmann::json fb = trajectoryJson(data.all, none, cfg), fa = trajectoryJson(data.all, corr, cfg);
  if (!fb.empty()) rep.validation["trajectory_full_recordings"] = {{"before", fb}, {"after", fa}};
  rep.validation["corrections"] = {{"encoder_scale_right", corr.enc_scale[0]},
                                   {"encoder_scale_left", corr.enc_scale[1]},
                                   {"gyro_scale", corr.gyro_scale},
                                   {"gyro_bias_rad_s", corr.gyro_bias},
                                   {"delay_imu_s", corr.delay_imu},
                                   {"delay_encoders_s", corr.delay_enc},
                                   {"delay_motors_s", corr.delay_motors}};
}

}  // namespace

namespace {

/// Frees the samples the diagnosis reads only through the streams (IMU, motor currents) or not
/// at all (joystick: the command-response analyser is not part of diagnose()).
void releaseStreamSamples(io::Recording& r) {
  std::vector<io::ImuSample>().swap(r.imu);  // (`= {}` would keep the capacity)
  std::vector<io::MotorSample>().swap(r.motors);
  std::vector<io::JoystickSample>().swap(r.joystick);
}

/// Frees what the odometric calibration reads of a recording and the sensor-fault and
/// trajectory checks read from the streams (encoders, Pozyx, ground truth).
void releaseCalibrationSamples(io::Recording& r) {
  std::vector<io::EncoderSample>().swap(r.encoders);
  std::vector<io::PozyxSample>().swap(r.pozyx);
  std::vector<io::GroundTruthPoseSample>().swap(r.ground_truth);
}

/// The diagnosis on the streams `data` of the recordings (diagnose()): the recordings are read
/// only for their encoders, ground truth and sonar after the streams are made.
/// `owned` (fit_recs and val_recs themselves, or null): the recordings may be released as
/// they stop being read (memory).
DiagnosisReport diagnoseStreams(const std::vector<io::Recording>& fit_recs,
                                const std::vector<io::Recording>& val_recs, StageData& data,
                                const config::WheelchairConfig& cfg, const DiagnosisOptions& opt,
                                std::chrono::steady_clock::time_point tstart,
                                std::array<std::vector<io::Recording>*, 2> owned = {}) {
  DiagnosisReport rep;
  if (!data.any_enc) throw std::runtime_error("diagnose: no encoder data in the fit recordings");
  rep.info["streams"] = {
      {"encoders", data.any_enc}, {"gyro", data.any_gyro}, {"motors", data.any_mot}};
  rep.info["validation"] =
      val_recs.empty()
          ? fmt::format("held-out last {:.0f}% of each recording", 100 * (1 - opt.fit_fraction))
          : fmt::format("{} --validate recording(s)", val_recs.size());
  Corrections corr;
  nlohmann::json skipped = nlohmann::json::object();
  if (data.any_gyro)
    kinematicStage(data, cfg, opt, corr, rep);
  else
    skipped["stage1"] = "no gyro stream: kinematic consistency not checked";
  if (!data.any_mot)
    skipped["stage2"] = "no motor currents: dynamics not checked";
  else if (!dynamicStage(data, cfg, opt, corr, rep))
    skipped["stage2"] = "too little overlapping encoder and motor-current data";
  if (!skipped.empty()) rep.info["skipped"] = skipped;

  // odometric geometry against ground truth (with or without a gyro)
  {
    // a named slope's downhill heading (start frame): its yaw creep is tested (slopeYawCreep)
    const Finding* slope = rep.find("ground_slope");
    const double downhill_rad =
        slope && slope->parameters.value("downhill_heading_deg", nlohmann::json()).is_number()
            ? slope->parameters["downhill_heading_deg"].get<double>() * M_PI / 180
            : std::nan("");
    KinematicCalibration kc =
        calibrateKinematics(fit_recs, val_recs, cfg, opt, &corr, downhill_rad);
    foldRadiusIntoEncoderScale(kc, corr, rep);
    addKinematicCalibration(kc, cfg, rep);
  }
  // From here the recordings are read only for the fit recordings' sonar (the rest reads the
  // streams): of owned recordings the fit ones' encoders, Pozyx and ground truth and the
  // --validate ones are released (memory, docs/benchmarks.md, "Ninth round, stage 1").
  if (owned[0])
    for (io::Recording& r : *owned[0]) releaseCalibrationSamples(r);
  if (owned[1])
    for (io::Recording& r : *owned[1]) r = io::Recording();

  // sensor faults (not physics): sonar dropouts, Pozyx outliers; on the whole streams, which
  // consume the held-out parts
  heldOutTrajectories(data, corr, cfg, rep);
  makeWholeStreams(data);
  {
    SensorFaultOptions so;
    so.alpha = opt.alpha;
    SensorFaultReport sf = detectSensorFaults(fit_recs, cfg, corr, so, &data.all);
    for (auto& f : sf.findings) rep.addFinding(f);
    rep.info["sensor_faults"] = sf.info;
  }
  verifyTrajectories(data, corr, cfg, rep);
  enforceHeldOutRule(rep);  // issue 16: no finding whose held-out prediction gets worse
  rep.info["runtime_s"] =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - tstart).count();
  return rep;
}

}  // namespace

DiagnosisReport diagnose(const std::vector<io::Recording>& fit_recs,
                         const std::vector<io::Recording>& val_recs,
                         const config::WheelchairConfig& cfg, const DiagnosisOptions& opt) {
  const auto tstart = std::chrono::steady_clock::now();
  StageData data = splitStreams(fit_recs, val_recs.size(), opt, [&](bool fit, std::size_t i) {
    return makeStreams(fit ? fit_recs[i] : val_recs[i], cfg);
  });
  return diagnoseStreams(fit_recs, val_recs, data, cfg, opt, tstart);
}

DiagnosisReport diagnose(std::vector<io::Recording>&& fit_recs,
                         std::vector<io::Recording>&& val_recs, const config::WheelchairConfig& cfg,
                         const DiagnosisOptions& opt) {
  const auto tstart = std::chrono::steady_clock::now();
  StageData data = splitStreams(fit_recs, val_recs.size(), opt, [&](bool fit, std::size_t i) {
    io::Recording& r = fit ? fit_recs[i] : val_recs[i];
    Streams s = makeStreams(r, cfg);
    releaseStreamSamples(r);
    return s;
  });
  return diagnoseStreams(fit_recs, val_recs, data, cfg, opt, tstart, {&fit_recs, &val_recs});
}

DiagnosisReport diagnose(DiagnosisInput&& fit, DiagnosisInput&& val,
                         const config::WheelchairConfig& cfg, const DiagnosisOptions& opt) {
  const auto tstart = std::chrono::steady_clock::now();
  if (fit.streams.size() != fit.recs.size() || val.streams.size() != val.recs.size())
    throw std::logic_error("diagnose: a DiagnosisInput needs one Streams per recording");
  StageData data = splitStreams(fit.recs, val.recs.size(), opt, [&](bool f, std::size_t i) {
    return std::move((f ? fit : val).streams[i]);
  });
  return diagnoseStreams(fit.recs, val.recs, data, cfg, opt, tstart, {&fit.recs, &val.recs});
}

namespace {

/// Whether a finding becomes a [model_extensions] effect (not a sensor fault, an unmodeled
/// term, a command-response finding or the odometric geometry, which is written as [vehicle]).
bool isModelExtension(const Finding& f) {
  return !(f.effect == "unmodeled" || f.effect == kWheelGeometryEffect || f.is_fault ||
           f.command_response);
}

}  // namespace

std::vector<effects::EffectSpec> findingsAsEffects(const DiagnosisReport& rep) {
  std::vector<effects::EffectSpec> out;
  for (auto& f : rep.findings) {
    if (!isModelExtension(f)) continue;
    effects::EffectSpec e;
    e.id = f.effect;
    for (auto it = f.parameters.begin(); it != f.parameters.end(); ++it) {
      if (effects::findEffect(e.id)) {
        bool known = false;
        for (auto& p : effects::findEffect(e.id)->info().params) known |= p.name == it.key();
        if (!known) continue;
      }
      if (it->is_number())
        e.params[it.key()] = fmt::format("{:.8g}", it->get<double>());
      else if (it->is_string())
        e.params[it.key()] = it->get<std::string>();
    }
    out.push_back(e);
  }
  return out;
}

config::WheelchairConfig correctedConfig(const config::WheelchairConfig& cfg,
                                         const DiagnosisReport& rep) {
  config::WheelchairConfig out = cfg;
  auto effects = findingsAsEffects(rep);
  out.set("model_extensions", "count", std::to_string(effects.size()));
  int k = 0;
  for (auto& f : rep.findings) {
    if (!isModelExtension(f)) continue;
    ++k;
    out.set("model_extensions", fmt::format("effect_{}", k), effects::formatEffect(effects[k - 1]));
    std::string u;
    for (auto it = f.uncertainty.begin(); it != f.uncertainty.end(); ++it)
      if (it->is_number())
        u += fmt::format("{}{}={:.6g}", u.empty() ? "" : ",", it.key(), it->get<double>());
    out.set("model_extensions", fmt::format("sigma_{}", k), u);
  }
  for (const auto& [section, keys] : rep.config_updates)
    for (const auto& [key, value] : keys) out.set(section, key, value);
  int u = 0;
  for (auto& f : rep.findings)
    if (f.effect == "unmodeled" && !f.command_response)
      out.set("model_extensions", fmt::format("unmodeled_{}", ++u), f.parameters.dump());
  return out;
}

}  // namespace wheelchair::diagnosis
