#include "libwheelchair/identification/Identification.h"
#include "libwheelchair/io/RawlogStream.h"
#include "libwheelchair/signals/IntervalStream.h"
#include "libwheelchair/stats/BlockedLeastSquares.h"
#include "libwheelchair/stats/Distributions.h"
#include "libwheelchair/stats/LeastSquares.h"
#include "libwheelchair/util/ScratchRecords.h"

#include "libwheelchair/model/VehicleParams.h"

#include <fmt/format.h>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace wheelchair::identification {

using stats::LsOptions;
using stats::LsSolution;
using stats::ResidualStats;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
const char* kThetaNames[5] = {"theta_1", "theta_2", "theta_3", "theta_4", "theta_5"};
const char* kThetaMeaning[5] = {"1/(eta_G k_m)", "J_m/(eta_G k_m)", "I_w,zz/(eta_G k_m)",
                                "I_zz/(eta_G k_m)", "B_m/k_m"};
const char* kThetaUnit[5] = {"A/(N m)", "A s^2", "A s^2", "A s^2", "A s/rad"};

nlohmann::json num(double x) {
  return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json();
}

Estimate fromFunctional(const LsSolution& s, const Eigen::VectorXd& w, const std::string& why_not) {
  Estimate e;
  if (!s.isEstimable(w)) {
    e.reason = why_not;
    return e;
  }
  e.identifiable = true;
  e.value = s.estimate(w);
  e.se = s.standardError(w);
  e.se_naive = s.standardErrorNaive(w);
  return e;
}

// Marks an estimable but useless estimate (relative standard error above 50 %) as not
// identifiable: never print a confident wrong number.
void guardPrecision(Estimate& e, const std::string& what) {
  if (!e.identifiable) return;
  if (!(std::abs(e.value) > 0) || !(e.se < 0.5 * std::abs(e.value))) {
    e.reason = fmt::format(
        "{} is estimable in principle but the data do not determine it (estimate {:.4g}, "
        "standard error {:.4g}): the drive hardly excites it",
        what, e.value, e.se);
    e.identifiable = false;
    e.value = e.se = e.se_naive = kNaN;
  }
}

RegressionReport report(const LsSolution& s, std::vector<std::string> cols) {
  RegressionReport r;
  r.columns = std::move(cols);
  r.rank = s.rank;
  r.condition_number = s.condition_number;
  r.condition_number_identifiable = s.condition_number_identifiable;
  for (int k = 0; k < s.singular_values.size(); ++k)
    r.singular_values_rel.push_back(s.singular_values(k) / s.singular_values(0));
  r.residual = s.residual;
  return r;
}

nlohmann::json residualJson(const ResidualStats& r, const char* unit) {
  return {{"unit", unit},
          {"rows", r.n_rows},
          {"dof", r.dof},
          {"rms", num(r.rms)},
          {"mean", num(r.mean)},
          {"max_abs", num(r.max_abs)},
          {"rms_of_observations", num(r.rms_y)},
          {"r_squared", num(r.r_squared)},
          {"lag1_autocorrelation", num(r.lag1_autocorr)},
          {"effective_rows", num(r.n_effective)}};
}

}  // namespace

// ---------------------------------------------------------------------------------------

namespace {
[[maybe_unused]] const bool kRegistered =
    config::registerOptionsOf<IdentificationOptions>("identification") &&
    config::registerOptions([] {
      return std::vector<config::Options>{
          config::Options("identified")
              .anyKey(
                  "written by `wheelchair identify --write-config`: the identified values, their "
                  "standard errors and sources (results, not read back)")};
    });
}  // namespace

config::Options IdentificationOptions::options(const std::string& section) {
  using config::Range;
  const Range pos = Range::above(0), nonneg = Range::atLeast(0);
  return config::Options(section, "least-squares identification (docs/identification.md)")
      .real("rate_hz", rate_hz, "common time base (Hz)", pos)
      .real("cutoff_hz", cutoff_hz, "zero-phase Butterworth cut-off, all signals (Hz)", pos)
      .oneOf("omega_source", omega_source, {"encoders", "gyro"}, "angular velocity from")
      .real("standstill_speed_m_s", standstill_speed_m_s,
            "standstill when both rim speeds are below (m/s)", nonneg)
      .real("edge_trim_s", edge_trim_s, "dropped at both ends of every segment (s)", nonneg)
      .real("max_gap_s", max_gap_s, "a longer stream gap splits a segment (s)", pos)
      .real("min_excitation_snr", min_excitation_snr, "excitation rms / noise floor (-)", nonneg)
      .real("hac_lag_factor", hac_lag_factor, "HAC bandwidth factor (-)", pos)
      .real("confidence", confidence, "two-sided confidence level (-)", Range{0, 1, true, true})
      .real("rank_tol", rank_tol, "relative singular-value threshold (-)", nonneg)
      .real("qs_max_vdot_m_s2", qs_max_vdot_m_s2, "quasi-steady: |vdot| below (m/s^2)", nonneg)
      .real("qs_max_omegadot_rad_s2", qs_max_omegadot_rad_s2,
            "quasi-steady: |omegadot| below (rad/s^2)", nonneg)
      .real("qs_min_duration_s", qs_min_duration_s, "quasi-steady: lasting at least (s)", nonneg)
      .real("qs_min_wheel_speed_m_s", qs_min_wheel_speed_m_s,
            "quasi-steady: motor rim speed beyond (m/s)", nonneg)
      .flag("update_torque_constant", update_torque_constant,
            "--write-config: k_m from the back-EMF fit");
}

void IdentificationOptions::loadFromConfig(const mrpt::config::CConfigFileBase& ini,
                                           const std::string& sec) {
  options(sec).load(ini);
  validate(config::keyLocation(ini, sec, ""));
}

void IdentificationOptions::validate(const std::string& sec) const {
  if (!(rate_hz > 0) || !(cutoff_hz > 0) || cutoff_hz >= 0.5 * rate_hz)
    throw std::runtime_error(
        fmt::format("{} cutoff_hz must be > 0 and below half of rate_hz (got {} and {})", sec,
                    cutoff_hz, rate_hz));
  if (omega_source != "encoders" && omega_source != "gyro")
    throw std::runtime_error(
        fmt::format("{} omega_source must be 'encoders' or 'gyro' (got '{}')", sec, omega_source));
  if (!(confidence > 0 && confidence < 1))
    throw std::runtime_error(fmt::format("{} confidence must be in (0, 1)", sec));
}

int IdentificationOptions::hacLags() const {
  return std::max(1, static_cast<int>(std::lround(hac_lag_factor * rate_hz / cutoff_hz)));
}

signals::IntervalSignalOptions IdentificationOptions::intervalSignalOptions() const {
  signals::IntervalSignalOptions s;
  s.rate_hz = rate_hz;
  s.cutoff_hz = cutoff_hz;
  s.gyro_omega = omega_source == "gyro";
  s.standstill_speed_m_s = standstill_speed_m_s;
  s.edge_trim_s = edge_trim_s;
  s.max_gap_s = max_gap_s;
  return s;
}

nlohmann::json IdentificationOptions::toJson() const {
  return {{"rate_hz", rate_hz},
          {"cutoff_hz", cutoff_hz},
          {"filter", "2nd-order Butterworth applied forward and backward (zero phase)"},
          {"omega_source", omega_source},
          {"standstill_speed_m_s", standstill_speed_m_s},
          {"edge_trim_s", edge_trim_s},
          {"max_gap_s", max_gap_s},
          {"min_excitation_snr", min_excitation_snr},
          {"hac_lag_factor", hac_lag_factor},
          {"confidence", confidence},
          {"rank_tol", rank_tol},
          {"qs_max_vdot_m_s2", qs_max_vdot_m_s2},
          {"qs_max_omegadot_rad_s2", qs_max_omegadot_rad_s2},
          {"qs_min_duration_s", qs_min_duration_s},
          {"qs_min_wheel_speed_m_s", qs_min_wheel_speed_m_s},
          {"update_torque_constant", update_torque_constant}};
}

nlohmann::json Estimate::toJson(double z) const {
  if (!identifiable)
    return {{"value", nullptr}, {"se", nullptr}, {"identifiable", false}, {"reason", reason}};
  nlohmann::json j = {{"value", num(value)},
                      {"se", num(se)},
                      {"se_naive_iid", num(se_naive)},
                      {"identifiable", true},
                      {"interval", {num(value - z * se), num(value + z * se)}}};
  if (!reason.empty()) j["note"] = reason;
  return j;
}

nlohmann::json RegressionReport::toJson() const {
  return {{"columns", columns},
          {"rank", rank},
          {"condition_number_scaled", num(condition_number)},
          {"condition_number_identifiable_subspace", num(condition_number_identifiable)},
          {"singular_values_relative", singular_values_rel}};
}

Eigen::Matrix<double, 5, 1> d1Weights(const model::Geometry& g) {
  const double r = g.wheel_radius_m, rG = g.gear_ratio, rho = r / rG;
  Eigen::Matrix<double, 5, 1> w;
  w << rho * (g.wheel_mass_kg + g.body_mass_kg / 2), 1 / rho, 1 / (r * rG), 0, 0;
  return w;
}

Eigen::Matrix<double, 5, 1> d2Weights(const model::Geometry& g) {
  const double r = g.wheel_radius_m, rG = g.gear_ratio, rho = r / rG, lw = g.track_width_m;
  Eigen::Matrix<double, 5, 1> w;
  w << rho * g.wheel_mass_kg * lw / 2, lw / (2 * rho), lw / (2 * r * rG), rho / lw, 0;
  return w;
}

// ---------------------------------------------------------------------------------------

namespace {

/// A used sample (moving, away from segment edges) as the fits read it.
struct UsedRow {
  int recording, seg;
  long k;
  double t, u_r, u_l, v, omega, vdot, omegadot, i_r, i_l, U_r, U_l;
};

/// Used rows held in memory (~100 B each) before the rest go to a scratch file.
constexpr std::size_t kRowsInMemory = 1 << 15;
/// Rows per block of the blocked least squares.
constexpr std::size_t kFitRows = 2048;

/// A quasi-steady stretch: the used rows [begin, end) (consecutive samples of one segment).
struct SteadyRun {
  std::size_t begin = 0, end = 0;
  double dur_s = 0;
};

/// What the fits need of the conditioned samples, collected sample by sample in order (the
/// conditioning may be streamed): counts, excitation sums, quasi-steady stretches, and the used
/// rows (util::ScratchRecords: memory bounded whatever the drive's length).
class RowCollector {
 public:
  explicit RowCollector(const IdentificationOptions& o) : o_(o) {}

  void add(const signals::IntervalRow& r) {
    ++n_grid;
    if (!r.interior)
      ++n_edge;
    else if (!r.moving)
      ++n_standstill;
    const bool use = r.interior && r.moving;
    const bool steady = use && std::abs(r.vdot) < o_.qs_max_vdot_m_s2 &&
                        std::abs(r.omegadot) < o_.qs_max_omegadot_rad_s2;
    if (!steady || r.segment != run_seg_) closeRun();
    if (!use) return;
    if (steady && run_len_ == 0) run_seg_ = r.segment, run_begin_ = used.size();
    if (steady) ++run_len_;
    used.add(UsedRow{r.recording, r.segment, r.k, r.t, r.u_r, r.u_l, r.v, r.omega, r.vdot,
                     r.omegadot, r.i_r, r.i_l, r.U_r, r.U_l});
    ss[0] += std::pow(r.v, 2);
    ss[1] += std::pow(r.omega, 2);
    ss[2] += std::pow(r.vdot, 2);
    ss[3] += std::pow(r.omegadot, 2);
  }
  /// Closes the last quasi-steady stretch (call once all samples are in).
  void finish() { closeRun(); }

  std::size_t n_grid = 0, n_edge = 0, n_standstill = 0;
  double ss[4] = {0, 0, 0, 0};  ///< sums of squares of v, omega, vdot, omegadot (used rows)
  std::vector<SteadyRun> runs;  ///< quasi-steady stretches of at least qs_min_duration_s
  util::ScratchRecords<UsedRow> used{"identify: the conditioned samples", kRowsInMemory};

 private:
  void closeRun() {
    if (run_len_ > 0) {
      const double dur = double(run_len_) / o_.rate_hz;
      if (dur >= o_.qs_min_duration_s) runs.push_back({run_begin_, run_begin_ + run_len_, dur});
    }
    run_len_ = 0;
    run_seg_ = -1;
  }
  const IdentificationOptions& o_;
  int run_seg_ = -1;
  std::size_t run_begin_ = 0, run_len_ = 0;
};

std::string nullDescription(const Eigen::VectorXd& vs, const std::vector<Excitation>& ex) {
  std::vector<int> part;
  for (int j = 0; j < 5; ++j)
    if (std::abs(vs(j)) > 0.05) part.push_back(j);
  auto has = [&](int j) { return std::find(part.begin(), part.end(), j) != part.end(); };
  const auto exc = [&](const std::string& s) {
    for (const auto& e : ex)
      if (e.signal == s) return e;
    return Excitation{};
  };
  if (part.size() == 1 && part[0] == 3)
    return fmt::format(
        "yaw inertia theta_4 = I_zz/(eta_G k_m) is not identifiable: the drive has no angular "
        "acceleration above the noise floor (omegadot SNR {:.2g} < threshold)",
        exc("omegadot").snr);
  if (part.size() == 1 && part[0] == 4)
    return "viscous term theta_5 = B_m/k_m is not identifiable: the wheels hardly move";
  if (part.size() == 2 && has(1) && has(2))
    return "theta_2 (motor rotor inertia) and theta_3 (wheel inertia) are not separable: their "
           "columns of Y are proportional for every drive (both multiply the rim acceleration "
           "udot_i); only the reflected rotating inertia (r_G/r) theta_2 + theta_3/(r r_G) is "
           "seen";
  std::string names;
  for (int j : part) names += (names.empty() ? "" : ", ") + std::string(kThetaNames[j]);
  std::string s = fmt::format(
      "the combination of {} along this direction leaves every current unchanged: columns of Y "
      "are linearly dependent on this drive (y_i1, y_i2, y_i3 are all combinations of vdot and "
      "s_i omegadot, y_i4 of omegadot); the currents only see D1 (coefficient of vdot)",
      names);
  s += exc("omegadot").excited ? ", D2 (coefficient of s_i omegadot)" : "";
  s += " and theta_5";
  if (!exc("vdot").excited) s += "; there is no linear acceleration above the noise floor";
  if (!exc("omegadot").excited) s += "; there is no angular acceleration above the noise floor";
  return s;
}

std::string thetaReason(int j, const std::vector<Excitation>& ex) {
  bool wdot = false, vdot = false;
  for (const auto& e : ex) {
    if (e.signal == "omegadot") wdot = e.excited;
    if (e.signal == "vdot") vdot = e.excited;
  }
  switch (j) {
    case 0:
      return std::string(
                 "theta_1 = 1/(eta_G k_m) is not identifiable from currents and motion: "
                 "it enters (2) only inside D1") +
             (wdot ? " and D2" : "") +
             ", together with the rotating-inertia terms theta_2, theta_3" +
             (wdot ? " and theta_4" : "") +
             " (the masses m_w, m_b are fixed by the configuration); see `combinations`";
    case 1:
    case 2:
      return "theta_2 and theta_3 are never separable (proportional columns of Y: both multiply "
             "udot_i) and are not separable from theta_1 either (all three multiply the linear "
             "acceleration); only D1 = 1/(2 a1) is identifiable";
    case 3:
      if (!wdot)
        return "yaw inertia theta_4 is not identifiable: the drive has no angular acceleration "
               "above the noise floor";
      return "theta_4 = I_zz/(eta_G k_m) enters only through D2 together with theta_1..theta_3; "
             "it is not separable without knowing eta_G k_m";
    default:
      return vdot || wdot ? "theta_5 not determined" : "the wheels hardly move";
  }
}

// Ratio fit y = k x through the origin over segments (weights = durations), with a
// cluster-robust standard error (each segment one cluster).
Estimate ratioThroughOrigin(const std::vector<double>& x, const std::vector<double>& y,
                            const std::vector<double>& w, const std::string& what) {
  Estimate e;
  const std::size_t n = x.size();
  if (n == 0) {
    e.reason = what + ": no quasi-steady segment with this wheel moving";
    return e;
  }
  double sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < n; ++i) sxx += w[i] * x[i] * x[i], sxy += w[i] * x[i] * y[i];
  if (!(sxx > 0)) {
    e.reason = what + ": motor speed is zero in every segment";
    return e;
  }
  e.identifiable = true;
  e.value = sxy / sxx;
  if (n >= 2) {
    double s = 0;
    for (std::size_t i = 0; i < n; ++i) s += std::pow(w[i] * x[i] * (y[i] - e.value * x[i]), 2);
    e.se = std::sqrt(s * double(n) / double(n - 1)) / sxx;
  } else {
    e.reason = "one segment only: no scatter to estimate the uncertainty from (se null)";
  }
  return e;
}

/// The counts of the samples (res.n_*); throws when too few are usable.
void countRows(const RowCollector& rc, IdentificationResult& res) {
  res.n_grid = rc.n_grid;
  res.n_edge = rc.n_edge;
  res.n_standstill = rc.n_standstill;
  res.n_used = rc.used.size();
  if (res.n_used < 50)
    throw std::runtime_error(fmt::format(
        "identify: only {} usable samples (moving, away from segment edges and gaps); need a "
        "recording with encoders and motor currents while the chair moves",
        res.n_used));
}

/// Excitation of v, omega, vdot, omegadot over the used samples (res.excitation, notes).
void measureExcitation(const RowCollector& rc, const PreparedData& noise,
                       const IdentificationOptions& o, IdentificationResult& res) {
  const struct {
    const char* name;
    double noise;
  } sig[4] = {{"v", noise.noise_v},
              {"omega", noise.noise_omega},
              {"vdot", noise.noise_vdot},
              {"omegadot", noise.noise_omegadot}};
  for (int j = 0; j < 4; ++j) {
    Excitation e;
    e.signal = sig[j].name;
    e.rms = std::sqrt(rc.ss[j] / double(rc.used.size()));
    e.noise = std::max(sig[j].noise, 1e-12);
    e.snr = e.rms / e.noise;
    e.excited = e.snr >= o.min_excitation_snr;
    res.excitation.push_back(e);
  }
  if (!res.excitation[3].excited)
    res.notes.push_back(fmt::format(
        "angular acceleration not excited (omegadot rms {:.3g} rad/s^2, noise floor {:.3g}, SNR "
        "{:.2g} < {}): yaw parameters (theta_4, D2, a2, a4) are not identifiable from this drive",
        res.excitation[3].rms, res.excitation[3].noise, res.excitation[3].snr,
        o.min_excitation_snr));
  if (!res.excitation[2].excited)
    res.notes.push_back(
        "linear acceleration not excited: D1, a1, a3 are not identifiable from this drive");
}

/// The regressions' view of the used samples. Unexcited signals are set to zero in the
/// regressors: their measured values are noise, and regressing on noise would produce a
/// confident, attenuated (wrong) coefficient.
struct Samples {
  util::ScratchRecords<UsedRow>& rows;
  bool ex[4];  ///< v, omega, vdot, omegadot excited
  /// 0 v, 1 omega, 2 vdot, 3 omegadot (0 when not excited).
  double val(const UsedRow& rw, int which) const {
    switch (which) {
      case 0:
        return ex[0] ? rw.v : 0.0;
      case 1:
        return ex[1] ? rw.omega : 0.0;
      case 2:
        return ex[2] ? rw.vdot : 0.0;
      default:
        return ex[3] ? rw.omegadot : 0.0;
    }
  }
  /// A least-squares problem of `cols` columns, `per_sample` rows per used sample (time step
  /// k, block = segment), made block by block from the rows: fill(row, X, y, r) writes the
  /// rows r .. r + per_sample - 1 of the block.
  template <typename Fill>
  stats::LsRowSource source(int cols, int per_sample, Fill fill) const {
    return [this, cols, per_sample, fill](const stats::LsBlockVisitor& visit) {
      std::vector<UsedRow> chunk;
      chunk.reserve(kFitRows);
      Eigen::MatrixXd X;
      Eigen::VectorXd y;
      std::vector<long> ti;
      std::vector<int> blk;
      const auto flush = [&] {
        const long m = long(chunk.size()) * per_sample;
        X.resize(m, cols);
        y.resize(m);
        ti.resize(std::size_t(m));
        blk.resize(std::size_t(m));
        for (std::size_t q = 0; q < chunk.size(); ++q) {
          const long r = long(q) * per_sample;
          fill(chunk[q], X, y, r);
          for (int i = 0; i < per_sample; ++i) {
            ti[std::size_t(r + i)] = chunk[q].k;
            blk[std::size_t(r + i)] = chunk[q].seg;
          }
        }
        visit(X, y, ti, blk);
        chunk.clear();
      };
      rows.replay(0, rows.size(), [&](const UsedRow& rw) {
        chunk.push_back(rw);
        if (chunk.size() == kFitRows) flush();
      });
      if (!chunk.empty()) flush();
    };
  }
};

/// Null space of the theta regression in a canonical basis: the SVD returns an arbitrary
/// rotation of it, so first pull out the directions with a known meaning (theta_2 vs theta_3,
/// theta_4 alone, theta_5 alone) when they lie in it, then describe what remains.
void nullDirections(const LsSolution& ts, double rG, IdentificationResult& res) {
  const int p = 5, nn = p - ts.rank;
  Eigen::MatrixXd Nb = ts.V.rightCols(nn);  // orthonormal, scaled coordinates
  std::vector<Eigen::VectorXd> cand;
  Eigen::VectorXd c(5);
  c << 0, 1, -rG * rG, 0, 0;  // y_i2 = r_G^2 y_i3
  cand.push_back(c);
  cand.push_back(Eigen::VectorXd::Unit(5, 3));
  cand.push_back(Eigen::VectorXd::Unit(5, 4));
  std::vector<Eigen::VectorXd> basis;
  for (const auto& d : cand) {
    if (Nb.cols() == 0) break;
    Eigen::VectorXd ds = d.cwiseProduct(ts.column_scale);
    ds /= ds.norm();
    const Eigen::VectorXd coef = Nb.transpose() * ds;
    if (coef.norm() < 1 - 1e-6) continue;
    basis.push_back(ds);
    // Remove ds from the remaining null basis.
    Eigen::MatrixXd R = Nb - ds * (ds.transpose() * Nb);
    Eigen::JacobiSVD<Eigen::MatrixXd> sv(R, Eigen::ComputeThinU);
    const int keep = static_cast<int>(Nb.cols()) - 1;
    Nb = sv.matrixU().leftCols(keep);
  }
  for (int k = 0; k < Nb.cols(); ++k) {  // the SVD's sign is arbitrary: largest entry > 0
    Eigen::VectorXd b = Nb.col(k);
    Eigen::Index imax = 0;
    b.cwiseQuotient(ts.column_scale).cwiseAbs().maxCoeff(&imax);
    if (b(imax) < 0) b = -b;
    basis.push_back(b);
  }
  for (const auto& vs : basis) {
    NullDirection nd;
    Eigen::VectorXd d = vs.cwiseQuotient(ts.column_scale);
    d /= d.norm();
    nd.direction.assign(d.data(), d.data() + 5);
    nd.direction_scaled.assign(vs.data(), vs.data() + 5);
    nd.singular_value_rel =  // ||X_s vs|| / sigma_max
        (ts.singular_values.asDiagonal() * (ts.V.transpose() * vs)).norm() / ts.singular_values(0);
    nd.description = nullDescription(vs, res.excitation);
    res.null_directions.push_back(nd);
  }
}

/// theta: the 5-column form (2), right and left rows stacked; theta_j, D1, D2 in `res`.
LsSolution fitTheta(const Samples& sm, const model::Geometry& g, const LsOptions& lso,
                    IdentificationResult& res) {
  const auto fill = [&sm, &g](const UsedRow& rw, Eigen::MatrixXd& X, Eigen::VectorXd& y, long r) {
    const auto Y = model::regressor(g, sm.val(rw, 0), sm.val(rw, 2), sm.val(rw, 1), sm.val(rw, 3));
    for (int i = 0; i < 2; ++i) {
      X.row(r + i) = Y.row(i);
      y(r + i) = i == 0 ? rw.i_r : rw.i_l;
    }
  };
  const LsSolution ts = stats::solveLeastSquaresBlocked(sm.source(5, 2, fill), 5, lso);
  res.theta_regression = report(ts, {"y_i1", "y_i2", "y_i3", "y_i4", "y_i5"});
  nullDirections(ts, g.gear_ratio, res);
  for (int j = 0; j < 5; ++j) {
    Eigen::VectorXd e = Eigen::VectorXd::Zero(5);
    e(j) = 1;
    res.theta[j] = fromFunctional(ts, e, thetaReason(j, res.excitation));
    guardPrecision(res.theta[j], kThetaNames[j]);
  }
  res.D1 = fromFunctional(ts, d1Weights(g),
                          "D1 needs linear acceleration: the drive has none above the noise floor");
  res.D2 = fromFunctional(
      ts, d2Weights(g), "D2 needs angular acceleration: the drive has none above the noise floor");
  guardPrecision(res.D1, "D1");
  guardPrecision(res.D2, "D2");
  return ts;
}

/// a1..a4 from theta (Appendix VI) with delta-method standard errors.
void aFromTheta(const LsSolution& ts, const model::Geometry& g, IdentificationResult& res) {
  const double r = g.wheel_radius_m, rG = g.gear_ratio, lw = g.track_width_m;
  const Eigen::VectorXd w1 = d1Weights(g), w2 = d2Weights(g);
  const double rho = r / rG;
  Eigen::VectorXd e5 = Eigen::VectorXd::Zero(5);
  e5(4) = 1;
  auto fromGrad = [&](double value, const Eigen::VectorXd& grad) {
    Estimate e;
    e.identifiable = true;
    e.value = value;
    e.se = ts.standardError(grad);
    e.se_naive = ts.standardErrorNaive(grad);
    return e;
  };
  const auto& D1 = res.D1;
  const auto& D2 = res.D2;
  const auto& t5 = res.theta[4];
  const std::string no1 = "a1 = 1/(2 D1) needs D1: " + D1.reason;
  const std::string no2 = "a2 = 1/(2 D2) needs D2: " + D2.reason;
  if (D1.identifiable)
    res.a_from_theta[0] = fromGrad(0.5 / D1.value, -0.5 / (D1.value * D1.value) * w1);
  else
    res.a_from_theta[0].reason = no1;
  if (D2.identifiable)
    res.a_from_theta[1] = fromGrad(0.5 / D2.value, -0.5 / (D2.value * D2.value) * w2);
  else
    res.a_from_theta[1].reason = no2;
  if (D1.identifiable && t5.identifiable)
    res.a_from_theta[2] =
        fromGrad(-t5.value / (rho * D1.value),
                 -e5 / (rho * D1.value) + t5.value / (rho * D1.value * D1.value) * w1);
  else
    res.a_from_theta[2].reason = "a3 = -theta_5 r_G/(r D1) needs D1 and theta_5: " +
                                 (D1.identifiable ? t5.reason : D1.reason);
  if (D2.identifiable && t5.identifiable)
    res.a_from_theta[3] = fromGrad(
        -t5.value * lw / (2 * rho * D2.value),
        -lw / (2 * rho * D2.value) * e5 + t5.value * lw / (2 * rho * D2.value * D2.value) * w2);
  else
    res.a_from_theta[3].reason = "a4 = -theta_5 l_w r_G/(2 r D2) needs D2 and theta_5: " +
                                 (D2.identifiable ? t5.reason : D2.reason);
}

/// Moves a segment out of its vector (freed when the holder goes).
struct IntervalSegmentHolder {
  explicit IntervalSegmentHolder(PreparedSegment& from) : s(std::move(from)) {}
  PreparedSegment s;
};

/// a1..a4 directly from the ODE form (6).
void fitDirect(const Samples& sm, const LsOptions& lso, IdentificationResult& res) {
  for (int eq = 0; eq < 2; ++eq) {
    const bool excited = eq == 0 ? sm.ex[2] : sm.ex[3];
    const int ia = eq == 0 ? 0 : 1, ib = eq == 0 ? 2 : 3;  // current gain, damping
    if (!excited) {
      const std::string why = eq == 0
                                  ? "the drive has no linear acceleration above the noise floor"
                                  : "the drive has no angular acceleration above the noise floor";
      res.a_direct[ia].reason = res.a_direct[ib].reason = why;
      continue;
    }
    const auto fill = [&sm, eq](const UsedRow& rw, Eigen::MatrixXd& X, Eigen::VectorXd& y, long r) {
      X(r, 0) = eq == 0 ? rw.i_r + rw.i_l : rw.i_r - rw.i_l;
      X(r, 1) = eq == 0 ? sm.val(rw, 0) : sm.val(rw, 1);
      y(r) = eq == 0 ? rw.vdot : rw.omegadot;
    };
    const LsSolution sol = stats::solveLeastSquaresBlocked(sm.source(2, 1, fill), 2, lso);
    (eq == 0 ? res.direct_v : res.direct_omega) =
        report(sol, eq == 0 ? std::vector<std::string>{"i_R + i_L", "v"}
                            : std::vector<std::string>{"i_R - i_L", "omega"});
    const char* nm[4] = {"a1", "a2", "a3", "a4"};
    for (int c = 0; c < 2; ++c) {
      Eigen::VectorXd e = Eigen::VectorXd::Zero(2);
      e(c) = 1;
      const int idx = c == 0 ? ia : ib;
      res.a_direct[idx] = fromFunctional(sol, e, "column not excited");
      guardPrecision(res.a_direct[idx], nm[idx]);
    }
  }
}

/// Per side: i_i = D1_i vdot + s_i D2_i omegadot + theta5_i (r_G/r) u_i.
void fitPerSide(const Samples& sm, const model::Geometry& g, const LsOptions& lso,
                IdentificationResult& res) {
  const double r = g.wheel_radius_m, rG = g.gear_ratio, lw = g.track_width_m;
  for (int side = 0; side < 2; ++side) {
    const double sgn = side == 0 ? 1.0 : -1.0;
    const auto fill = [&sm, side, sgn, r, rG, lw](const UsedRow& rw, Eigen::MatrixXd& X,
                                                  Eigen::VectorXd& y, long q) {
      X(q, 0) = sm.val(rw, 2);
      X(q, 1) = sgn * sm.val(rw, 3);
      X(q, 2) = rG / r * (sm.val(rw, 0) + sgn * lw / 2 * sm.val(rw, 1));
      y(q) = side == 0 ? rw.i_r : rw.i_l;
    };
    const LsSolution sol = stats::solveLeastSquaresBlocked(sm.source(3, 1, fill), 3, lso);
    res.per_side[side] = report(sol, {"vdot", "s_i omegadot", "(r_G/r) u_i"});
    auto& m = res.motor[side];
    Eigen::Vector3d e0(1, 0, 0), e1(0, 1, 0), e2(0, 0, 1);
    m.D1 = fromFunctional(sol, e0, "no linear acceleration above the noise floor");
    m.D2 = fromFunctional(sol, e1, "no angular acceleration above the noise floor");
    m.theta5 = fromFunctional(sol, e2, "the wheel hardly moves");
    guardPrecision(m.D1, "D1 of this side");
    guardPrecision(m.D2, "D2 of this side");
    guardPrecision(m.theta5, "theta_5 of this side");
  }
}

/// Per-motor k/eta (eq. 4) and back-EMF constant from the voltage / speed data of each side.
struct QuasiSteadyData {
  std::array<std::vector<double>, 2> xs, y_ratio, y_emf, wts;
};

/// One quasi-steady stretch (used rows [run.begin, run.end)): its means (and the data of each
/// used side).
QuasiSteadySegment quasiSteadySegment(util::ScratchRecords<UsedRow>& rows, const SteadyRun& run,
                                      bool has_voltage, const config::WheelchairConfig& cfg,
                                      const IdentificationOptions& o, QuasiSteadyData& d) {
  const double r = cfg.vehicle.geom.wheel_radius_m, rG = cfg.vehicle.geom.gear_ratio;
  QuasiSteadySegment q;
  const double m = double(run.end - run.begin);
  std::array<double, 2> umin{1e300, 1e300}, umax{-1e300, -1e300};
  bool first = true;
  rows.replay(run.begin, run.end, [&](const UsedRow& s) {
    if (first) q.recording = s.recording, q.t_start_s = s.t, first = false;
    q.t_end_s = s.t;
    q.v_m_s += s.v / m;
    q.omega_rad_s += s.omega / m;
    const double u[2] = {s.u_r, s.u_l};
    const double cur[2] = {s.i_r, s.i_l};
    const double U[2] = {s.U_r, s.U_l};
    for (int i = 0; i < 2; ++i) {
      q.current_A[i] += cur[i] / m;
      q.voltage_V[i] += U[i] / m;
      q.motor_speed_rad_s[i] += rG / r * u[i] / m;
      umin[i] = std::min(umin[i], u[i]);
      umax[i] = std::max(umax[i], u[i]);
    }
  });
  for (int i = 0; i < 2; ++i) {
    q.used[i] = has_voltage &&
                (umin[i] >= o.qs_min_wheel_speed_m_s || umax[i] <= -o.qs_min_wheel_speed_m_s);
    if (!q.used[i]) continue;
    d.xs[i].push_back(q.motor_speed_rad_s[i]);
    d.y_ratio[i].push_back(q.voltage_V[i]);
    d.y_emf[i].push_back(q.voltage_V[i] - cfg.vehicle.armature_resistance_ohm * q.current_A[i]);
    d.wts[i].push_back(run.dur_s);
  }
  return q;
}

/// Quasi-steady segments: per-motor k/eta (eq. 4) and back-EMF constant.
void fitQuasiSteady(RowCollector& rc, bool has_voltage, const config::WheelchairConfig& cfg,
                    const IdentificationOptions& o, IdentificationResult& res) {
  QuasiSteadyData d;
  for (const auto& run : rc.runs)
    res.segments.push_back(quasiSteadySegment(rc.used, run, has_voltage, cfg, o, d));
  for (int i = 0; i < 2; ++i) {
    auto& m = res.motor[i];
    m.n_segments = static_cast<int>(d.xs[i].size());
    if (!has_voltage) {
      m.k_over_eta.reason = m.back_emf_k.reason =
          "the recordings hold no V_RC voltage (all zero): motor constants need it";
      continue;
    }
    m.k_over_eta = ratioThroughOrigin(d.xs[i], d.y_ratio[i], d.wts[i], "k/eta (eq. 4)");
    m.back_emf_k = ratioThroughOrigin(d.xs[i], d.y_emf[i], d.wts[i], "back-EMF constant");
  }
  if (res.segments.empty())
    res.notes.push_back(fmt::format(
        "no quasi-steady segment (|vdot| < {} m/s^2, |omegadot| < {} rad/s^2 for >= {} s while "
        "moving): per-motor constants not identified",
        o.qs_max_vdot_m_s2, o.qs_max_omegadot_rad_s2, o.qs_min_duration_s));
}

/// identify() on the collected samples; `conditioned` gives the noise floors and whether any
/// voltage was recorded (its segments are not read).
IdentificationResult identifyRows(RowCollector& rc, const PreparedData& conditioned,
                                  const config::WheelchairConfig& cfg,
                                  const IdentificationOptions& o,
                                  const std::vector<std::string>& sources) {
  rc.finish();
  IdentificationResult res;
  res.options = o;
  res.config_origin = cfg.origin();
  res.sources = sources;
  res.hac_lags = o.hacLags();
  res.z = stats::normalQuantile(0.5 + o.confidence / 2);
  const auto& g = cfg.vehicle.geom;

  countRows(rc, res);
  measureExcitation(rc, conditioned, o, res);
  const Samples sm{rc.used,
                   {res.excitation[0].excited, res.excitation[1].excited, res.excitation[2].excited,
                    res.excitation[3].excited}};
  LsOptions lso;
  lso.hac_lags = res.hac_lags;
  lso.rank_tol = o.rank_tol;
  const LsSolution ts = fitTheta(sm, g, lso, res);
  aFromTheta(ts, g, res);
  fitDirect(sm, lso, res);
  fitPerSide(sm, g, lso, res);
  fitQuasiSteady(rc, conditioned.has_voltage, cfg, o, res);

  res.notes.push_back(fmt::format(
      "standard errors: Newey-West HAC (Bartlett kernel, {} lags = {} x rate/cutoff) over "
      "per-time-step scores; intervals are value +- {:.3f} se ({:.0f} % two-sided); on average "
      "they are {:.2f} x the iid standard errors (se_naive_iid, reported only for comparison)",
      res.hac_lags, o.hac_lag_factor, res.z, 100 * o.confidence,
      std::sqrt(double(ts.residual.n_rows) / std::max(1.0, ts.residual.n_effective))));
  if (!sm.ex[0] && !sm.ex[1])
    res.notes.push_back("the chair hardly moves: nothing is identifiable");
  return res;
}

/// The rows of conditioned segments into `rc`, each segment released once read.
void collectSegments(PreparedData& data, RowCollector& rc) {
  for (std::size_t si = 0; si < data.segments.size(); ++si) {
    IntervalSegmentHolder seg(data.segments[si]);
    for (std::size_t k = 0; k < seg.s.t.size(); ++k)
      rc.add(signals::intervalRow(seg.s, static_cast<int>(si), k));
  }
}

}  // namespace

IdentificationResult identify(const std::vector<io::Recording>& recs,
                              const config::WheelchairConfig& cfg, const IdentificationOptions& o,
                              const std::vector<std::string>& sources) {
  PreparedData data = signals::prepareIntervalMeans(recs, cfg, o.intervalSignalOptions());
  RowCollector rc(o);
  collectSegments(data, rc);
  return identifyRows(rc, data, cfg, o, sources);
}

IdentificationResult identify(std::vector<io::Recording>&& recs,
                              const config::WheelchairConfig& cfg, const IdentificationOptions& o,
                              const std::vector<std::string>& sources) {
  PreparedData data = signals::prepareIntervalMeans(recs, cfg, o.intervalSignalOptions());
  std::vector<io::Recording>().swap(recs);  // released before the fits (their peak)
  RowCollector rc(o);
  collectSegments(data, rc);
  return identifyRows(rc, data, cfg, o, sources);
}

IdentificationResult identifyStreamed(const std::vector<std::string>& paths,
                                      const config::WheelchairConfig& cfg,
                                      const IdentificationOptions& o,
                                      const std::vector<std::string>& sources) {
  RowCollector rc(o);
  signals::IntervalConditioner cond(cfg, o.intervalSignalOptions(),
                                    [&rc](const signals::IntervalRow& r) { rc.add(r); });
  for (std::size_t ri = 0; ri < paths.size(); ++ri) {
    io::RawlogSampleReader in(paths[ri]);
    cond.beginRecording(static_cast<int>(ri));
    io::AnySample s;
    std::size_t k = 0;
    while (in.next(s, k)) cond.add(s);
    cond.endRecording();
  }
  const PreparedData summary = cond.finish();
  return identifyRows(rc, summary, cfg, o, sources);
}

// ---------------------------------------------------------------------------------------

nlohmann::json IdentificationResult::toJson() const {
  using nlohmann::json;
  json j;
  j["tool"] = "wheelchair identify";
  j["config"] = config_origin;
  j["recordings"] = sources;
  j["options"] = options.toJson();
  j["confidence"] = {
      {"level", options.confidence},
      {"z", z},
      {"se_method", fmt::format("Newey-West HAC, Bartlett kernel, {} lags", hac_lags)}};
  j["samples"] = {{"grid", n_grid},
                  {"used", n_used},
                  {"excluded_standstill", n_standstill},
                  {"excluded_segment_edges", n_edge},
                  {"standstill_rule", fmt::format("both filtered rim speeds |u_R|, |u_L| < {} m/s",
                                                  options.standstill_speed_m_s)}};
  json ex = json::object();
  for (const auto& e : excitation)
    ex[e.signal] = {
        {"rms", e.rms}, {"noise_floor", e.noise}, {"snr", e.snr}, {"excited", e.excited}};
  j["excitation"] = ex;

  json tr = theta_regression.toJson();
  tr["residual"] = residualJson(theta_regression.residual, "A");
  json nds = json::array();
  for (const auto& nd : null_directions)
    nds.push_back({{"direction_theta", nd.direction},
                   {"direction_scaled", nd.direction_scaled},
                   {"singular_value_relative", nd.singular_value_rel},
                   {"description", nd.description}});
  tr["not_identifiable_directions"] = nds;
  j["theta_regression"] = tr;

  json th = json::object();
  for (int k = 0; k < 5; ++k) {
    json e = theta[k].toJson(z);
    e["meaning"] = kThetaMeaning[k];
    e["unit"] = kThetaUnit[k];
    th[kThetaNames[k]] = e;
  }
  j["theta"] = th;
  json c1 = D1.toJson(z), c2 = D2.toJson(z);
  c1["definition"] = "(r/r_G)(m_w + m_b/2) theta_1 + (r_G/r) theta_2 + theta_3/(r r_G) = 1/(2 a1)";
  c1["unit"] = "A s^2/m";
  c2["definition"] =
      "(r/r_G)(m_w l_w/2 theta_1 + theta_4/l_w) + (l_w/2)((r_G/r) theta_2 + theta_3/(r r_G)) = "
      "1/(2 a2)";
  c2["unit"] = "A s^2/rad";
  j["combinations"] = {{"D1", c1}, {"D2", c2}};

  const char* an[4] = {"a1", "a2", "a3", "a4"};
  const char* au[4] = {"m/s^2 per A", "rad/s^2 per A", "1/s", "1/s"};
  json ft = json::object(), dr = json::object();
  for (int k = 0; k < 4; ++k) {
    ft[an[k]] = a_from_theta[k].toJson(z);
    ft[an[k]]["unit"] = au[k];
    dr[an[k]] = a_direct[k].toJson(z);
    dr[an[k]]["unit"] = au[k];
  }
  json dv = direct_v.toJson(), dw = direct_omega.toJson();
  if (!direct_v.columns.empty()) dv["residual"] = residualJson(direct_v.residual, "m/s^2");
  if (!direct_omega.columns.empty())
    dw["residual"] = residualJson(direct_omega.residual, "rad/s^2");
  j["ode"] = {{"from_theta", ft},
              {"direct", dr},
              {"direct_regression_v", dv},
              {"direct_regression_omega", dw}};

  json pm = json::object();
  const char* sn[2] = {"right", "left"};
  for (int i = 0; i < 2; ++i) {
    json rs = per_side[i].toJson();
    rs["residual"] = residualJson(per_side[i].residual, "A");
    rs["D1"] = motor[i].D1.toJson(z);
    rs["D2"] = motor[i].D2.toJson(z);
    rs["theta_5"] = motor[i].theta5.toJson(z);
    pm[sn[i]] = {{"k_over_eta_eq4", motor[i].k_over_eta.toJson(z)},
                 {"back_emf_constant_Nm_A", motor[i].back_emf_k.toJson(z)},
                 {"quasi_steady_segments_used", motor[i].n_segments},
                 {"regression", rs}};
  }
  auto ratio = [&](const Estimate& a, const Estimate& b) -> json {
    if (!a.identifiable || !b.identifiable) return nullptr;
    return a.value / b.value;
  };
  pm["ratio_right_over_left"] = {{"k_over_eta", ratio(motor[0].k_over_eta, motor[1].k_over_eta)},
                                 {"back_emf_k", ratio(motor[0].back_emf_k, motor[1].back_emf_k)},
                                 {"theta_5", ratio(motor[0].theta5, motor[1].theta5)},
                                 {"D1", ratio(motor[0].D1, motor[1].D1)}};
  j["per_motor"] = pm;

  json segs = json::array();
  for (const auto& q : segments)
    segs.push_back({{"recording", q.recording},
                    {"t_start_s", q.t_start_s},
                    {"t_end_s", q.t_end_s},
                    {"v_m_s", q.v_m_s},
                    {"omega_rad_s", q.omega_rad_s},
                    {"current_A", q.current_A},
                    {"voltage_V", q.voltage_V},
                    {"motor_speed_rad_s", q.motor_speed_rad_s},
                    {"used_right", q.used[0]},
                    {"used_left", q.used[1]}});
  j["quasi_steady_segments"] = segs;
  j["notes"] = notes;
  return j;
}

// ---------------------------------------------------------------------------------------

config::WheelchairConfig identifiedConfig(const config::WheelchairConfig& base,
                                          const IdentificationResult& res,
                                          std::vector<std::string>* changes) {
  config::WheelchairConfig cfg = base;
  auto& v = cfg.vehicle;
  const auto& g = v.geom;
  const double r = g.wheel_radius_m, rG = g.gear_ratio, rho = r / rG, lw = g.track_width_m;
  const double k0 = v.torque_constant_Nm_A, eta0 = v.gearbox_efficiency;
  const double B0 = v.motor_viscous_Nm_s_rad, Izz0 = v.yaw_inertia_kg_m2;
  std::vector<std::string> log;
  auto note = [&](const std::string& key, double from, double to, const std::string& why) {
    log.push_back(fmt::format("[vehicle] {}: {:.6g} -> {:.6g} ({})", key, from, to, why));
  };

  double k = k0;
  {
    double sum = 0;
    int cnt = 0;
    for (const auto& m : res.motor)
      if (m.back_emf_k.identifiable) sum += m.back_emf_k.value, ++cnt;
    if (res.options.update_torque_constant && cnt > 0) k = sum / cnt;
  }
  const double J_rot = v.motor_inertia_kg_m2 / rho + v.wheel_inertia_kg_m2 / (r * rG);
  double etak = eta0 * k0;  // keeps the old eta_G k_m when D1 is not identified
  if (res.D1.identifiable && res.D1.value > 0)
    etak = (rho * (g.wheel_mass_kg + g.body_mass_kg / 2) + J_rot) / res.D1.value;
  v.torque_constant_Nm_A = k;
  v.gearbox_efficiency = etak / k;
  if (k != k0) note("torque_constant_Nm_A", k0, k, "mean back-EMF constant of the two motors");
  if (v.gearbox_efficiency != eta0)
    note("gearbox_efficiency", eta0, v.gearbox_efficiency,
         res.D1.identifiable ? "eta_G k_m reproduces the identified D1 = 1/(2 a1)"
                             : "keeps eta_G k_m with the new k_m");
  if (v.gearbox_efficiency > 1)
    log.push_back(fmt::format(
        "warning: gearbox_efficiency {:.3g} > 1: the configured masses/inertias or k_m do not "
        "match the data; the model only uses the product eta_G k_m = {:.4g}",
        v.gearbox_efficiency, etak));
  if (res.D2.identifiable) {
    const double Izz =
        lw / rho * (res.D2.value * etak - rho * g.wheel_mass_kg * lw / 2 - lw / 2 * J_rot);
    if (Izz > 0) {
      v.yaw_inertia_kg_m2 = Izz;
      note("yaw_inertia_kg_m2", Izz0, Izz, "reproduces the identified D2 = 1/(2 a2)");
    } else {
      log.push_back("yaw_inertia_kg_m2 kept: the identified D2 would need I_zz <= 0");
    }
  }
  if (res.theta[4].identifiable) {
    v.motor_viscous_Nm_s_rad = res.theta[4].value * k;
    note("motor_viscous_Nm_s_rad", B0, v.motor_viscous_Nm_s_rad, "B_m = theta_5 k_m");
  } else if (k != k0) {
    v.motor_viscous_Nm_s_rad = B0 * k / k0;
    note("motor_viscous_Nm_s_rad", B0, v.motor_viscous_Nm_s_rad, "keeps B_m/k_m with the new k_m");
  }
  cfg.syncToIni();

  // [identified]: the estimates themselves (a1..a4 consistent with [vehicle] above).
  const auto a = model::odeCoefficients(g, model::lumpedTheta(v));
  auto put = [&](const std::string& key, double x) {
    cfg.set("identified", key, fmt::format("{}", x));
  };
  put("a1", a.a1);
  put("a2", a.a2);
  put("a3", a.a3);
  put("a4", a.a4);
  const char* an[4] = {"a1", "a2", "a3", "a4"};
  for (int i = 0; i < 4; ++i) {
    if (res.a_from_theta[i].identifiable) put(std::string(an[i]) + "_se", res.a_from_theta[i].se);
    cfg.set("identified", std::string(an[i]) + "_identified",
            res.a_from_theta[i].identifiable ? "1" : "0");
    if (res.a_direct[i].identifiable) put(std::string(an[i]) + "_direct", res.a_direct[i].value);
  }
  const char* sn[2] = {"right", "left"};
  for (int i = 0; i < 2; ++i) {
    if (res.motor[i].back_emf_k.identifiable)
      put(fmt::format("back_emf_k_{}_Nm_A", sn[i]), res.motor[i].back_emf_k.value);
    if (res.motor[i].k_over_eta.identifiable)
      put(fmt::format("k_over_eta_{}", sn[i]), res.motor[i].k_over_eta.value);
  }
  std::string src;
  for (const auto& s : res.sources) src += (src.empty() ? "" : " ") + s;
  cfg.set("identified", "sources", src.empty() ? "-" : src);
  cfg.set("identified", "cutoff_hz", fmt::format("{}", res.options.cutoff_hz));
  if (changes) *changes = log;
  return cfg;
}

}  // namespace wheelchair::identification
