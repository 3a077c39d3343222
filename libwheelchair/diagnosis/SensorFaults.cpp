#include "libwheelchair/diagnosis/SensorFaults.h"

#include "libwheelchair/stats/Descriptive.h"
#include "libwheelchair/stats/Distributions.h"
#include "libwheelchair/stats/Selection.h"

#include <Eigen/Dense>

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace wheelchair::diagnosis {

namespace {

using stats::median;

/// Merges time points / intervals into segments (gaps < 1 s joined); at most 20 (longest).
std::vector<std::pair<double, double>> mergeSegments(std::vector<std::pair<double, double>> iv) {
  std::sort(iv.begin(), iv.end());
  std::vector<std::pair<double, double>> out;
  for (auto& s : iv) {
    if (!out.empty() && s.first - out.back().second < 1.0)
      out.back().second = std::max(out.back().second, s.second);
    else
      out.push_back(s);
  }
  if (out.size() > 20) {
    std::sort(out.begin(), out.end(),
              [](auto& a, auto& b) { return a.second - a.first > b.second - b.first; });
    out.resize(20);
    std::sort(out.begin(), out.end());
  }
  return out;
}

// ---------------------------------------------------------------- sonar

struct SonarStats {
  std::size_t readings = 0, zeros = 0, valid = 0, out_of_range = 0, zero_runs = 0;
  std::size_t tested_runs = 0, dropout_runs = 0, dropout_readings = 0;
  std::vector<double> run_lengths;
  std::vector<std::pair<double, double>> intervals;
  double noise_used_m = 0, noise_estimated_m = 0;
};

void sonarRecording(const io::Recording& rec, const config::WheelchairConfig& cfg,
                    const SensorFaultOptions& o, SonarStats& st) {
  std::vector<io::SonarSample> s = rec.sonar;
  std::stable_sort(s.begin(), s.end(), [](auto& a, auto& b) { return a.t_s < b.t_s; });
  const auto& sp = cfg.sonar;
  // Noise: configured, or larger if the data say so (second differences of consecutive valid
  // readings: var = 6 sigma^2 for white noise; the robust MAD ignores manoeuvres).
  std::vector<double> d2;
  auto inBand0 = [&](double r) { return r >= sp.min_range_m && r <= sp.max_range_m; };
  for (std::size_t i = 1; i + 1 < s.size(); ++i)
    if (inBand0(s[i - 1].range_m) && inBand0(s[i].range_m) && inBand0(s[i + 1].range_m) &&
        s[i + 1].t_s - s[i - 1].t_s <= 2 * o.sonar_max_track_gap_s)
      d2.push_back(std::abs(s[i + 1].range_m - 2 * s[i].range_m + s[i - 1].range_m));
  const double s_est = d2.size() >= 10 ? 1.4826 * median(d2) / std::sqrt(6.0) : 0.0;
  const double sig = std::max(sp.noise_m, s_est);
  st.noise_used_m = std::max(st.noise_used_m, sig);
  st.noise_estimated_m = std::max(st.noise_estimated_m, s_est);
  // A non-zero reading beyond the band by more than the Bonferroni quantile of the noise is
  // impossible for a healthy sensor.
  const double level = stats::SelectionRule{o.alpha, static_cast<int>(s.size())}.level();
  const double z = std::sqrt(stats::chi2Quantile(1 - level, 1));
  const double lo = sp.min_range_m - z * sig, hi = sp.max_range_m + z * sig;
  enum Kind { kZero, kValid, kBad };
  std::vector<Kind> kind(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) {
    const double r = s[i].range_m;
    kind[i] = r == 0 ? kZero : (std::isfinite(r) && r >= lo && r <= hi ? kValid : kBad);
    ++st.readings;
    if (kind[i] == kZero) ++st.zeros;
    if (kind[i] == kValid) ++st.valid;
    if (kind[i] == kBad) {
      ++st.out_of_range;
      st.intervals.push_back({s[i].t_s, s[i].t_s});
    }
  }
  // Zero runs and the target tracks around them.
  struct Run {
    std::size_t a, b;  // zero readings a..b
  };
  std::vector<Run> runs;
  for (std::size_t i = 0; i < s.size();) {
    if (kind[i] != kZero) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j + 1 < s.size() && kind[j + 1] == kZero) ++j;
    runs.push_back({i, j});
    i = j + 1;
  }
  st.zero_runs += runs.size();
  // A target track: consecutive valid readings without a jump (a jump = another target).
  auto track = [&](std::size_t start, int dir, std::vector<double>& t, std::vector<double>& r) {
    long k = static_cast<long>(start);
    while (k >= 0 && k < static_cast<long>(s.size()) &&
           static_cast<int>(t.size()) < o.sonar_track_readings && kind[k] == kValid) {
      if (!t.empty()) {
        const double dt = std::abs(s[k].t_s - t.back());
        if (dt > o.sonar_max_track_gap_s ||
            std::abs(s[k].range_m - r.back()) >
                z * sig * std::sqrt(2.0) + o.sonar_max_range_rate_m_s * dt)
          break;
      }
      t.push_back(s[k].t_s);
      r.push_back(s[k].range_m);
      k += dir;
    }
  };
  for (const Run& run : runs) {
    if (run.a == 0 || run.b + 1 >= s.size()) continue;
    const std::size_t p = run.a - 1, q = run.b + 1;
    if (kind[p] != kValid || kind[q] != kValid) continue;
    const double dur = s[q].t_s - s[p].t_s;
    if (dur > o.sonar_max_run_s) continue;
    // Both neighbours inside the band (not the edge of the range where echoes may vanish).
    if (!(s[p].range_m > sp.min_range_m + z * sig && s[p].range_m < sp.max_range_m - z * sig &&
          s[q].range_m > sp.min_range_m + z * sig && s[q].range_m < sp.max_range_m - z * sig))
      continue;
    std::vector<double> t, r;
    track(p, -1, t, r);
    std::vector<double> ta, ra;
    track(q, +1, ta, ra);
    t.insert(t.end(), ta.begin(), ta.end());
    r.insert(r.end(), ra.begin(), ra.end());
    if (t.size() < 3) continue;
    ++st.tested_runs;
    // One target across the run: a line through both tracks (weighted least squares; each
    // reading's variance = noise + random range acceleration over its distance from the run's
    // midpoint); its chi-square (n - 2 dof) must lie inside the 1 - alpha band.
    const double tm = 0.5 * (s[p].t_s + s[q].t_s);
    const int n = static_cast<int>(t.size());
    Eigen::MatrixXd A(n, 2);
    Eigen::VectorXd y(n), w(n);
    for (int k = 0; k < n; ++k) {
      const double g = t[k] - tm;
      A(k, 0) = 1, A(k, 1) = g, y(k) = r[k];
      w(k) = 1.0 / (sig * sig + std::pow(0.5 * o.sonar_range_accel_m_s2 * g * g, 2));
    }
    const Eigen::MatrixXd Aw = w.cwiseSqrt().asDiagonal() * A;
    const Eigen::VectorXd yw = w.cwiseSqrt().cwiseProduct(y);
    const Eigen::Vector2d b = Aw.colPivHouseholderQr().solve(yw);
    const double chi2 = (yw - Aw * b).squaredNorm();
    if (chi2 > stats::chi2Quantile(1 - o.alpha, n - 2)) continue;  // target changed
    ++st.dropout_runs;
    const std::size_t len = run.b - run.a + 1;
    st.dropout_readings += len;
    st.run_lengths.push_back(static_cast<double>(len));
    st.intervals.push_back({s[run.a].t_s, s[run.b].t_s});
  }
}

// ---------------------------------------------------------------- Pozyx

struct PozyxStats {
  std::size_t fixes = 0, tested = 0, outliers = 0;
  std::vector<double> outlier_times, outlier_mag;
  double noise_used_m = 0, noise_estimated_m = 0, threshold_chi2 = 0;
};

/// The odometric track (start frame) from corrected encoders and, when present, the gyro
/// heading, at the encoder samples: made sample by sample as it is read forward, neither the
/// track nor the cumulative gyro integral stored (memory: 5 doubles per encoder and gyro
/// sample of a long drive, docs/benchmarks.md, "Ninth round, stage 1"); the same doubles as
/// the stored track. moveTo(k) (k >= 1) makes samples k - 1 and k current; moving back starts
/// again from sample 0. E.g. moveTo(5); pose(1).x: x (m) at encoder sample 5.
class OdometryTrack {
 public:
  struct Pose {
    double x = 0, y = 0, phi = 0;  ///< m, m, rad
  };
  OdometryTrack(const Streams& s, const config::WheelchairConfig& cfg, const Corrections& c)
      : s_(s), c_(c), lw_(cfg.vehicle.geom.track_width_m), gyro_(s.tg.size() >= 2) {
    restart();
  }
  void moveTo(std::size_t k) {
    if (k < i_) restart();
    while (i_ < k) step();
  }
  /// Pose at sample k - 1 (0) and k (1) of the last moveTo(k).
  const Pose& pose(int which) const { return which == 0 ? prev_ : cur_; }

 private:
  void restart() {
    i_ = 0, cur_ = prev_ = Pose{};
    gk_ = 0, g_k_ = 0, g_k1_ = 0;
    if (gyro_) g_prev_ = headingAt(s_.te[0]);
  }
  /// One encoder sample forward.
  void step() {
    ++i_;
    const double dR = (s_.sR[i_] - s_.sR[i_ - 1]) / c_.enc_scale[0];
    const double dL = (s_.sL[i_] - s_.sL[i_ - 1]) / c_.enc_scale[1];
    double dphi = (dR - dL) / lw_;
    if (gyro_) {  // G(te[i]) - G(te[i - 1]), the latter kept from the step before
      const double g = headingAt(s_.te[i_]);
      dphi = g - g_prev_;
      g_prev_ = g;
    }
    const double ds = 0.5 * (dR + dL);
    prev_ = cur_;
    cur_.x += ds * std::cos(cur_.phi + 0.5 * dphi);
    cur_.y += ds * std::sin(cur_.phi + 0.5 * dphi);
    cur_.phi += dphi;
  }
  /// The cumulative corrected gyro integral G (rad; G = 0 at tg[0]) at time t, linear between
  /// the gyro samples; t must not decrease between calls (after restart()).
  double headingAt(double t) {
    const auto& tg = s_.tg;
    if (t <= tg.front()) return 0.0;
    if (t >= tg.back()) {
      gyroTo(tg.size() - 1);
      return g_k_;
    }
    const std::size_t k = std::upper_bound(tg.begin(), tg.end(), t) - tg.begin();
    gyroTo(k);
    const double a = (t - tg[k - 1]) / (tg[k] - tg[k - 1]);
    return g_k1_ + a * (g_k_ - g_k1_);
  }
  /// G at gyro sample k (g_k_) and k - 1 (g_k1_), summed forward from the current one.
  void gyroTo(std::size_t k) {
    for (; gk_ < k; ++gk_) {
      g_k1_ = g_k_;
      g_k_ = g_k_ + 0.5 * ((s_.gz[gk_ + 1] + s_.gz[gk_]) - 2 * c_.gyro_bias) / c_.gyro_scale *
                        (s_.tg[gk_ + 1] - s_.tg[gk_]);
    }
  }

  const Streams& s_;
  const Corrections& c_;
  double lw_;
  bool gyro_;
  std::size_t i_ = 0, gk_ = 0;
  Pose cur_, prev_;
  double g_k_ = 0, g_k1_ = 0, g_prev_ = 0;
};

void pozyxRecording(const Streams& s, const config::WheelchairConfig& cfg, const Corrections& corr,
                    const SensorFaultOptions& o, PozyxStats& st,
                    std::vector<std::array<double, 3>>& keep) {
  if (s.pozyx.size() < static_cast<std::size_t>(o.pozyx_min_window_fixes) || !s.hasEncoders())
    return;
  OdometryTrack tr(s, cfg, corr);
  const std::vector<double>& te = s.te;  // the track's times
  const double lx = cfg.pozyx.lever_x_m, ly = cfg.pozyx.lever_y_m;
  // Tag positions of the odometric track at the fix times.
  std::vector<double> t, qx, qy, zx, zy;
  for (auto* v : {&t, &qx, &qy, &zx, &zy}) v->reserve(s.pozyx.size());
  for (const auto& p : s.pozyx) {
    if (!(p.t_s >= te.front() && p.t_s <= te.back())) continue;
    if (!std::isfinite(p.x_m) || !std::isfinite(p.y_m)) continue;
    const std::size_t k =
        std::max<std::size_t>(1, std::upper_bound(te.begin(), te.end(), p.t_s) - te.begin());
    const std::size_t k1 = std::min(k, te.size() - 1);
    tr.moveTo(k1);
    const OdometryTrack::Pose &p0 = tr.pose(0), &p1 = tr.pose(1);
    const double a = te[k1] > te[k1 - 1] ? (p.t_s - te[k1 - 1]) / (te[k1] - te[k1 - 1]) : 0;
    const double x = p0.x + a * (p1.x - p0.x);
    const double y = p0.y + a * (p1.y - p0.y);
    const double ph = p0.phi + a * (p1.phi - p0.phi);
    t.push_back(p.t_s);
    qx.push_back(x + std::cos(ph) * lx - std::sin(ph) * ly);
    qy.push_back(y + std::sin(ph) * lx + std::cos(ph) * ly);
    zx.push_back(p.x_m), zy.push_back(p.y_m);
  }
  const std::size_t n = t.size();
  st.fixes += n;
  const double s_cfg = cfg.pozyx.noise_m;
  // Leave-one-out innovations against a robust local SE(2) alignment.
  std::vector<double> ex(n, 0), ey(n, 0), pred_var(n, 0);
  std::vector<char> tested(n, 0);
  std::size_t lo = 0, hi = 0;
  for (std::size_t i = 0; i < n; ++i) {
    while (t[lo] < t[i] - o.pozyx_window_s) ++lo;
    while (hi < n && t[hi] <= t[i] + o.pozyx_window_s) ++hi;
    if (static_cast<int>(hi - lo) - 1 < o.pozyx_min_window_fixes) continue;
    std::vector<double> w(hi - lo, 1.0);
    w[i - lo] = 0;  // leave the fix itself out
    double th = 0, Tx = 0, Ty = 0;
    for (int it = 0; it < 6; ++it) {
      double W = 0, qbx = 0, qby = 0, zbx = 0, zby = 0;
      for (std::size_t j = lo; j < hi; ++j) {
        const double wj = w[j - lo];
        W += wj, qbx += wj * qx[j], qby += wj * qy[j], zbx += wj * zx[j], zby += wj * zy[j];
      }
      if (W <= 0) break;
      qbx /= W, qby /= W, zbx /= W, zby /= W;
      double h00 = 0, h01 = 0, h10 = 0, h11 = 0;
      for (std::size_t j = lo; j < hi; ++j) {
        const double wj = w[j - lo];
        const double ax = qx[j] - qbx, ay = qy[j] - qby, bx = zx[j] - zbx, by = zy[j] - zby;
        h00 += wj * ax * bx, h01 += wj * ax * by, h10 += wj * ay * bx, h11 += wj * ay * by;
      }
      th = std::atan2(h01 - h10, h00 + h11);
      const double c = std::cos(th), sn = std::sin(th);
      Tx = zbx - (c * qbx - sn * qby);
      Ty = zby - (sn * qbx + c * qby);
      // Tukey biweight on the residuals (scale: robust, floored by the configured noise).
      std::vector<double> r(hi - lo);
      std::vector<double> ra;
      for (std::size_t j = lo; j < hi; ++j) {
        const double rx = zx[j] - (c * qx[j] - sn * qy[j] + Tx);
        const double ry = zy[j] - (sn * qx[j] + c * qy[j] + Ty);
        r[j - lo] = std::hypot(rx, ry);
        if (j != i) ra.push_back(std::abs(rx)), ra.push_back(std::abs(ry));
      }
      const double sc = std::max(s_cfg, 1.4826 * median(ra));
      const double cc = 4.685 * sc * std::sqrt(2.0);
      for (std::size_t j = lo; j < hi; ++j) {
        const double u = r[j - lo] / cc;
        w[j - lo] = j == i ? 0.0 : (u < 1 ? (1 - u * u) * (1 - u * u) : 0.0);
      }
    }
    const double c = std::cos(th), sn = std::sin(th);
    // Prediction variance of the left-out fix (in units of the fix noise): translation 1/W plus
    // the rotation's, |q_i - q_bar|^2 / sum w |q_j - q_bar|^2 (weighted LS alignment).
    {
      double W = 0, qbx = 0, qby = 0;
      for (std::size_t j = lo; j < hi; ++j)
        W += w[j - lo], qbx += w[j - lo] * qx[j], qby += w[j - lo] * qy[j];
      if (W > 0) {
        qbx /= W, qby /= W;
        double sdd = 0;
        for (std::size_t j = lo; j < hi; ++j)
          sdd += w[j - lo] * (std::pow(qx[j] - qbx, 2) + std::pow(qy[j] - qby, 2));
        const double di2 = std::pow(qx[i] - qbx, 2) + std::pow(qy[i] - qby, 2);
        pred_var[i] = 1.0 / W + (sdd > 0 ? di2 / sdd : 0.0);
      } else {
        pred_var[i] = 1.0;
      }
    }
    ex[i] = zx[i] - (c * qx[i] - sn * qy[i] + Tx);
    ey[i] = zy[i] - (sn * qx[i] + c * qy[i] + Ty);
    tested[i] = 1;
  }
  std::vector<double> ae;
  for (std::size_t i = 0; i < n; ++i)
    if (tested[i]) ae.push_back(std::abs(ex[i])), ae.push_back(std::abs(ey[i]));
  if (ae.empty()) return;
  const double s_est = 1.4826 * median(ae);
  const double sig = std::max(s_cfg, s_est);
  st.noise_used_m = std::max(st.noise_used_m, sig);
  st.noise_estimated_m = std::max(st.noise_estimated_m, s_est);
  for (std::size_t i = 0; i < n; ++i) {
    if (!tested[i]) continue;
    ++st.tested;
    const double var = sig * sig * (1 + pred_var[i]);
    keep.push_back({t[i], (ex[i] * ex[i] + ey[i] * ey[i]) / var, std::hypot(ex[i], ey[i])});
  }
}

/// The sonar's statistics over the recordings as report info and, when readings failed, a
/// sonar_dropout finding (ss.readings > 0).
void sonarFinding(const SonarStats& ss, SensorFaultReport& rep) {
  const std::size_t failed = ss.dropout_readings + ss.out_of_range;
  const std::size_t expected = ss.valid + failed;
  nlohmann::json info = {{"readings", ss.readings},
                         {"zero_readings", ss.zeros},
                         {"zero_fraction", double(ss.zeros) / ss.readings},
                         {"valid_readings", ss.valid},
                         {"zero_runs", ss.zero_runs},
                         {"zero_runs_tested", ss.tested_runs},
                         {"dropout_runs", ss.dropout_runs},
                         {"dropout_readings", ss.dropout_readings},
                         {"out_of_range_readings", ss.out_of_range},
                         {"noise_used_m", ss.noise_used_m},
                         {"noise_estimated_m", ss.noise_estimated_m}};
  rep.info["sonar"] = info;
  if (failed > 0) {
    Finding f;
    f.effect = "sonar_dropout";
    f.is_fault = true;
    f.channels = {"sonar"};
    const double p = expected > 0 ? double(failed) / expected : 0.0;
    std::vector<double> lens = ss.run_lengths;
    for (std::size_t k = 0; k < ss.out_of_range; ++k) lens.push_back(1);
    const double L =
        lens.empty() ? 1.0 : std::accumulate(lens.begin(), lens.end(), 0.0) / lens.size();
    double varL = 0;
    for (double l : lens) varL += (l - L) * (l - L);
    varL = lens.size() > 1 ? varL / (lens.size() - 1) : 0;
    const double nr = std::max<double>(1, lens.size());
    f.parameters = {{"probability", p}, {"burst_length", L}};
    // Failures come in bursts: binomial variance inflated by the mean burst length.
    f.uncertainty = {
        {"probability", std::sqrt(std::max(0.0, p * (1 - p)) * L / std::max<double>(1, expected))},
        {"burst_length", std::sqrt(varL / nr)}};
    f.evidence = info;
    f.evidence["test"] =
        "zero runs that interrupt a continuing target track (2-dof chi-square continuity test "
        "of the range tracks on both sides), plus non-zero readings outside the range band "
        "(Bonferroni)";
    f.segments = mergeSegments(ss.intervals);
    f.description = fmt::format(
        "the sonar fails on {:.1f}% of the readings where an echo was expected ({} of {}), in "
        "bursts of {:.1f} readings on average ({} runs of 0 inside a target track{}): a sensor "
        "fault (no echo / failed reading), not physics; those readings must be ignored",
        100 * p, failed, expected, L, ss.dropout_runs,
        ss.out_of_range ? fmt::format(", {} readings out of range", ss.out_of_range) : "");
    rep.findings.push_back(f);
  }
}

/// The Pozyx fixes' outlier test (count against Binomial(n, 1/n) and the largest against the
/// Bonferroni level) as report info and, when both reject, a pozyx_outliers finding
/// (ps.tested > 0; keep: t, d2, |e| per tested fix).
void pozyxFinding(PozyxStats& ps, const std::vector<std::array<double, 3>>& keep,
                  const SensorFaultOptions& o, SensorFaultReport& rep) {
  // A fault is an outlier PROCESS, not one extreme fix: count the fixes beyond the level
  // p0 = 1 / n (one expected under the null) and test the count against Binomial(n, p0).
  // One rare Gaussian fix (e.g. 4.9 sigma in 900) is then no finding; a UWB fault with
  // multipath fixes (many, each far beyond) is.
  const double n_tested = static_cast<double>(ps.tested);
  const double p0 = 1.0 / n_tested;
  ps.threshold_chi2 = -2.0 * std::log(p0);  // chi-square(2) upper quantile at p0
  std::vector<std::pair<double, double>> iv;
  for (auto& k : keep)
    if (k[1] > ps.threshold_chi2) {
      ++ps.outliers;
      ps.outlier_times.push_back(k[0]);
      ps.outlier_mag.push_back(k[2]);
      iv.push_back({k[0], k[0]});
    }
  // P(K >= k) = 1 - sum_{j < k} C(n, j) p0^j (1 - p0)^(n - j), pmf by recurrence.
  double below = 0, pmf = std::exp(n_tested * std::log1p(-p0));
  for (std::size_t j = 0; j < ps.outliers; ++j) {
    below += pmf;
    pmf *= (n_tested - j) / (j + 1.0) * p0 / (1 - p0);
  }
  const double count_p_value = std::max(0.0, 1.0 - below);
  // ... and at least one fix beyond the Bonferroni level alpha / n, which a cluster of
  // moderate exceedances from a local error of the odometric track does not reach. Either
  // test alone keeps a clean recording's false-alarm rate <= alpha; requiring both is stricter.
  const double bonferroni_chi2 =
      -2.0 * std::log(stats::SelectionRule{o.alpha, static_cast<int>(ps.tested)}.level());
  double max_d2 = 0;
  for (auto& k : keep) max_d2 = std::max(max_d2, k[1]);
  nlohmann::json info = {{"fixes", ps.fixes},
                         {"fixes_tested", ps.tested},
                         {"outliers", ps.outliers},
                         {"threshold_chi2_2dof", ps.threshold_chi2},
                         {"per_fix_level", p0},
                         {"expected_outliers_if_clean", n_tested * p0},
                         {"count_p_value", count_p_value},
                         {"largest_chi2", max_d2},
                         {"bonferroni_chi2", bonferroni_chi2},
                         {"alpha", o.alpha},
                         {"noise_used_m", ps.noise_used_m},
                         {"noise_estimated_m", ps.noise_estimated_m},
                         {"window_s", o.pozyx_window_s}};
  rep.info["pozyx"] = info;
  if (ps.outliers > 0 && count_p_value < o.alpha && max_d2 > bonferroni_chi2) {
    Finding f;
    f.effect = "pozyx_outliers";
    f.is_fault = true;
    f.channels = {"pozyx"};
    const double rate = double(ps.outliers) / ps.tested;
    const double mag = median(ps.outlier_mag);
    f.parameters = {{"rate", rate}, {"magnitude_m", mag}};
    double mad = 0;
    {
      std::vector<double> dev;
      for (double m : ps.outlier_mag) dev.push_back(std::abs(m - mag));
      mad = 1.4826 * median(dev);
    }
    f.uncertainty = {{"rate", std::sqrt(rate * (1 - rate) / ps.tested)},
                     {"magnitude_m", 1.2533 * mad / std::sqrt(double(ps.outliers))}};
    f.evidence = info;
    std::vector<double> times = ps.outlier_times;
    if (times.size() > 200) times.resize(200);
    f.evidence["outlier_times_s"] = times;
    f.segments = mergeSegments(iv);
    f.description = fmt::format(
        "{} of {} Pozyx fixes ({:.1f}%) lie far outside their noise ({:.2f} m) from the "
        "odometric track, displaced by {:.2f} m (median): non-line-of-sight / multipath UWB "
        "fixes, a sensor fault, not physics; gate them in the estimator",
        ps.outliers, ps.tested, 100 * rate, ps.noise_used_m, mag);
    rep.findings.push_back(f);
  }
}

}  // namespace

SensorFaultReport detectSensorFaults(const std::vector<io::Recording>& recs,
                                     const config::WheelchairConfig& cfg, const Corrections& corr,
                                     const SensorFaultOptions& o,
                                     const std::vector<Streams>* streams) {
  if (streams && streams->size() != recs.size())
    throw std::invalid_argument("detectSensorFaults: one Streams per recording needed");
  SensorFaultReport rep;
  SonarStats ss;
  for (const auto& r : recs) sonarRecording(r, cfg, o, ss);
  if (ss.readings > 0) sonarFinding(ss, rep);
  PozyxStats ps;
  std::vector<std::array<double, 3>> keep;  // t, d2, |e|
  for (std::size_t i = 0; i < recs.size(); ++i) {
    if (streams) {
      pozyxRecording((*streams)[i], cfg, corr, o, ps, keep);
    } else if (!recs[i].pozyx.empty()) {  // no fixes: the streams are not needed
      pozyxRecording(makeStreams(recs[i], cfg), cfg, corr, o, ps, keep);
    }
  }
  if (ps.tested > 0) pozyxFinding(ps, keep, o, rep);
  return rep;
}

SensorFaultReport detectSensorFaults(const std::vector<io::Recording>& recs,
                                     const config::WheelchairConfig& cfg, const Corrections& corr,
                                     const SensorFaultOptions& o) {
  return detectSensorFaults(recs, cfg, corr, o, nullptr);
}

}  // namespace wheelchair::diagnosis
