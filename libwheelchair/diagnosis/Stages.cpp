#include "libwheelchair/diagnosis/Stages.h"
#include "libwheelchair/stats/Selection.h"
#include "libwheelchair/stats/Statistics.h"

#include "libwheelchair/diagnosis/Diagnosis.h"
#include "libwheelchair/model/DriveDynamics.h"
#include "libwheelchair/sensors/Encoders.h"
#include "libwheelchair/sensors/Filtering.h"
#include "libwheelchair/signals/DriveSignals.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <initializer_list>
#include <numeric>
#include <stdexcept>

#include <fmt/format.h>

namespace wheelchair::diagnosis {

using stats::compareNested;
using stats::effectiveSampleSize;
using stats::fitLinear;
using stats::Groups;
using stats::LinearFit;

namespace {

/// Positions of the samples of v in time order (stable), the first of equal times only: the
/// order of a stable sort of v, without copying the samples (a long drive's IMU; memory).
template <class T, class F>
std::vector<std::size_t> sortedUniqueIndex(const std::vector<T>& v, F time) {
  std::vector<std::size_t> idx(v.size());
  std::iota(idx.begin(), idx.end(), std::size_t{0});
  std::stable_sort(idx.begin(), idx.end(),
                   [&](std::size_t a, std::size_t b) { return time(v[a]) < time(v[b]); });
  std::size_t m = 0;
  for (std::size_t k : idx)
    if (m == 0 || time(v[k]) > time(v[idx[m - 1]])) idx[m++] = k;
  idx.resize(m);
  return idx;
}

template <class T, class F>
std::vector<T> sortedUnique(const std::vector<T>& v, F time) {
  const std::vector<std::size_t> order = sortedUniqueIndex(v, time);
  std::vector<T> out;
  out.reserve(order.size());
  for (std::size_t k : order) out.push_back(v[k]);
  return out;
}

/// Appends to `out` the samples of `in` later than out's last (both sorted by time).
template <class T, class F>
void appendLater(std::vector<T>& out, const std::vector<T>& in, F time) {
  for (const T& x : in)
    if (out.empty() || time(x) > time(out.back())) out.push_back(x);
}

/// Cumulative trapezoid of the piecewise-linear signal x(t[k]) = (raw[k] - bias) / scale (t
/// sorted, s; e.g. the corrected gyro z, rad/s), evaluated anywhere (held outside); sample k is
/// at t[k] - shift. Neither x nor the whole cumulative sum is stored (memory: a long drive's
/// gyro is 8 B a sample for each, docs/benchmarks.md, "Ninth round, stage 1"): x is made from
/// raw when read, the cumulative sums C[k] = C[k-1] + (x[k] + x[k-1]) / 2 (t[k] - t[k-1]) (the
/// same doubles in the same order as a stored one) as queries reach them, and release(q)
/// drops those no query at or after time q reads (queries must then not go back before q).
/// E.g. init(tg, gz, 0, 1, 0); integral(a, b) = the integral of gz over [a, b] (rad).
struct LinearIntegral {
  const std::vector<double>* t = nullptr;
  const std::vector<double>* raw = nullptr;
  double bias = 0, scale = 1;
  double shift = 0;      // sample k is at t[k] - shift
  std::deque<double> C;  // C[k] for k in [base, base + C.size())
  std::size_t base = 0;
  void init(const std::vector<double>& tt, const std::vector<double>& rr, double b, double sc,
            double sh) {
    t = &tt, raw = &rr, bias = b, scale = sc, shift = sh;
    C.assign(1, 0.0), base = 0;
  }
  double x(std::size_t k) const { return ((*raw)[k] - bias) / scale; }
  /// C[k] (k >= base), the sums up to k made on the way.
  double cumulative(std::size_t k) {
    auto& T = *t;
    for (std::size_t m = base + C.size(); m <= k; ++m)
      C.push_back(C.back() + 0.5 * (x(m) + x(m - 1)) * (T[m] - T[m - 1]));
    if (k < base) throw std::logic_error("LinearIntegral: query before a released time");
    return C[k - base];
  }
  /// Frees the sums no query at or after time tq reads.
  void release(double tq) {
    auto& T = *t;
    const std::size_t k = std::upper_bound(T.begin(), T.end(), tq + shift) - T.begin();
    const std::size_t keep = k > 0 ? k - 1 : 0;  // F(q >= tq) reads C[upper_bound(q) - 1]
    while (base < keep && C.size() > 1) C.pop_front(), ++base;
  }
  double value(double tq) const {  // value of x at tq (linear)
    double q = tq + shift;
    auto& T = *t;
    if (q <= T.front()) return x(0);
    if (q >= T.back()) return x(T.size() - 1);
    size_t k = std::upper_bound(T.begin(), T.end(), q) - T.begin();
    double a = (q - T[k - 1]) / (T[k] - T[k - 1]);
    const double x0 = x(k - 1);
    return x0 + a * (x(k) - x0);
  }
  double F(double tq) {
    double q = tq + shift;
    auto& T = *t;
    if (q <= T.front()) return 0.0;
    if (q >= T.back()) return cumulative(T.size() - 1);
    size_t k = std::upper_bound(T.begin(), T.end(), q) - T.begin();
    double h = q - T[k - 1];
    double xq = value(tq);
    return cumulative(k - 1) + 0.5 * (x(k - 1) + xq) * h;
  }
  double integral(double a, double b) { return F(b) - F(a); }
  /// Largest sample gap inside [a, b] (sample times shifted), infinite if not covered.
  double maxGap(double a, double b) const {
    auto& T = *t;
    double qa = a + shift, qb = b + shift;
    if (qa < T.front() || qb > T.back()) return 1e300;
    size_t i = std::upper_bound(T.begin(), T.end(), qa) - T.begin();
    size_t j = std::lower_bound(T.begin(), T.end(), qb) - T.begin();
    double g = 0;
    for (size_t k = std::max<size_t>(i, 1); k <= j && k < T.size(); ++k)
      g = std::max(g, T[k] - T[k - 1]);
    return g;
  }
};

/// Filter response variance factor of filtfiltButter2 at (fc, fs): sum of squared impulse
/// response (variance of filtered white noise of unit variance).
double filteredNoiseFactor(double fc, double fs) {
  int n = static_cast<int>(20 * fs / fc) + 1;
  std::vector<double> x(n, 0.0);
  x[n / 2] = 1.0;
  auto y = sensors::filtfiltButter2(x, fc, fs);
  double s = 0;
  for (double v : y) s += v * v;
  return s;
}

}  // namespace

namespace {

/// The Pozyx and ground-truth streams of `rec` and the span of `s` (its encoders' first and
/// last time, else the recording's `start_s`, `end_s`).
void finishStreams(const io::Recording& rec, double start_s, double end_s, Streams& s) {
  s.pozyx = sortedUnique(rec.pozyx, [](const io::PozyxSample& a) { return a.t_s; });
  s.gt = sortedUnique(rec.ground_truth, [](const io::GroundTruthPoseSample& a) { return a.t_s; });
  s.t_begin = start_s;
  s.t_end = end_s;
  if (!s.te.empty()) s.t_begin = s.te.front(), s.t_end = s.te.back();
}

}  // namespace

Streams makeStreams(const io::Recording& rec, const config::WheelchairConfig& cfg) {
  Streams s;
  signals::DriveStreams d = signals::driveStreams(rec, cfg);
  s.te = std::move(d.te), s.sR = std::move(d.s[0]), s.sL = std::move(d.s[1]);
  s.tm = std::move(d.tm), s.iR = std::move(d.i[0]), s.iL = std::move(d.i[1]);
  const std::vector<std::size_t> gyro_order =
      sortedUniqueIndex(rec.imu, [](const io::ImuSample& a) { return a.t_s; });
  s.tg.reserve(gyro_order.size()), s.gz.reserve(gyro_order.size());  // no growth slack
  for (std::size_t k : gyro_order) {
    const io::ImuSample& g = rec.imu[k];
    if (std::isfinite(g.gyro_z_rad_s)) s.tg.push_back(g.t_s), s.gz.push_back(g.gyro_z_rad_s);
  }
  finishStreams(rec, rec.startTime(), rec.endTime(), s);
  return s;
}

Streams makeStreams(const io::Recording& rec, StreamColumns&& cols,
                    const config::WheelchairConfig& cfg) {
  Streams s;
  {
    signals::DriveStreams d;
    signals::encoderDistances(rec.encoders, cfg, d);
    s.te = std::move(d.te), s.sR = std::move(d.s[0]), s.sL = std::move(d.s[1]);
  }
  // The rule driveStreams applies to the motor samples and the gyro's above (stable time
  // order, first sample of a stamp, non-finite values dropped), on the columns themselves.
  signals::sortUniqueFinite(cols.tm, {&cols.iR, &cols.iL});
  s.tm = std::move(cols.tm), s.iR = std::move(cols.iR), s.iL = std::move(cols.iL);
  signals::sortUniqueFinite(cols.tg, {&cols.gz});
  s.tg = std::move(cols.tg), s.gz = std::move(cols.gz);
  finishStreams(rec, cols.start_s, cols.end_s, s);
  return s;
}

namespace {

/// joinStreams(parts, with_motors); with `release` (the parts' owner: parts[i] == &(*release)[i])
/// each column of the parts is freed once joined, so the parts and the result are never both
/// held whole (memory, docs/benchmarks.md, "Ninth round, stage 1").
Streams joinInto(const std::vector<const Streams*>& parts, bool with_motors,
                 std::vector<Streams>* release) {
  Streams o;
  if (parts.empty()) return o;
  using Column = std::vector<double> Streams::*;
  // A stream's columns (time first): of each part the samples later than every sample taken
  // so far, each output sized once to what it receives.
  auto join = [&](std::initializer_list<Column> cols, bool keep) {
    const Column tc = *cols.begin();
    std::vector<std::vector<char>> take(parts.size());
    std::size_t n = 0;
    double last = 0;
    for (std::size_t p = 0; keep && p < parts.size(); ++p) {
      const std::vector<double>& t = parts[p]->*tc;
      take[p].assign(t.size(), 0);
      for (std::size_t k = 0; k < t.size(); ++k)
        if (n == 0 || t[k] > last) take[p][k] = 1, last = t[k], ++n;
    }
    for (Column c : cols) {
      std::vector<double>& out = o.*c;
      if (keep) out.reserve(n);
      for (std::size_t p = 0; p < parts.size(); ++p) {
        const std::vector<double>& in = parts[p]->*c;
        for (std::size_t k = 0; keep && k < in.size(); ++k)
          if (take[p][k]) out.push_back(in[k]);
        if (release) std::vector<double>().swap((*release)[p].*c);
      }
    }
  };
  join({&Streams::te, &Streams::sR, &Streams::sL}, true);
  join({&Streams::tg, &Streams::gz}, true);
  join({&Streams::tm, &Streams::iR, &Streams::iL}, with_motors);
  std::size_t np = 0, nt = 0;
  for (const Streams* p : parts) np += p->pozyx.size(), nt += p->gt.size();
  o.pozyx.reserve(np), o.gt.reserve(nt);
  for (const Streams* p : parts) {
    appendLater(o.pozyx, p->pozyx, [](const io::PozyxSample& x) { return x.t_s; });
    appendLater(o.gt, p->gt, [](const io::GroundTruthPoseSample& x) { return x.t_s; });
  }
  o.t_begin = parts.front()->t_begin;
  o.t_end = parts.back()->t_end;
  if (release) release->clear();
  return o;
}

}  // namespace

Streams joinStreams(const std::vector<const Streams*>& parts, bool with_motors) {
  return joinInto(parts, with_motors, nullptr);
}

Streams joinStreams(std::vector<Streams>&& parts, bool with_motors) {
  std::vector<const Streams*> ptrs;
  for (const Streams& p : parts) ptrs.push_back(&p);
  return joinInto(ptrs, with_motors, &parts);
}

namespace {

/// The crops of `s` for `ranges` (cropStreams); with `release` (= &s) each column of s is
/// freed once its crops are made (the time column of a stream last).
std::vector<Streams> cropInto(const Streams& s,
                              const std::vector<std::pair<double, double>>& ranges,
                              Streams* release) {
  std::vector<Streams> out(ranges.size());
  using Column = std::vector<double> Streams::*;
  // A stream's columns (time first) cropped to every range: every output sized once to what
  // it receives (push_back alone leaves up to as much again unused on a long drive: memory,
  // docs/benchmarks.md).
  auto crop = [&](std::initializer_list<Column> cols) {
    const std::vector<double>& t = s.*(*cols.begin());
    std::vector<std::size_t> n(ranges.size());
    for (std::size_t r = 0; r < ranges.size(); ++r) {
      const auto [a, b] = ranges[r];
      n[r] = static_cast<std::size_t>(
          std::count_if(t.begin(), t.end(), [&](double x) { return x >= a && x <= b; }));
    }
    for (auto c = std::rbegin(cols); c != std::rend(cols); ++c) {  // the time column last
      for (std::size_t r = 0; r < ranges.size(); ++r) {
        const auto [a, b] = ranges[r];
        std::vector<double>& o = out[r].*(*c);
        o.reserve(n[r]);
        for (std::size_t k = 0; k < t.size(); ++k)
          if (t[k] >= a && t[k] <= b) o.push_back((s.*(*c))[k]);
      }
      if (release) std::vector<double>().swap(release->*(*c));
    }
  };
  crop({&Streams::te, &Streams::sR, &Streams::sL});
  crop({&Streams::tg, &Streams::gz});
  crop({&Streams::tm, &Streams::iR, &Streams::iL});
  for (std::size_t r = 0; r < ranges.size(); ++r) {
    const auto [a, b] = ranges[r];
    auto in = [&](const auto& p) { return p.t_s >= a && p.t_s <= b; };
    Streams& o = out[r];
    o.pozyx.reserve(static_cast<std::size_t>(std::count_if(s.pozyx.begin(), s.pozyx.end(), in)));
    o.gt.reserve(static_cast<std::size_t>(std::count_if(s.gt.begin(), s.gt.end(), in)));
    for (auto& p : s.pozyx)
      if (in(p)) o.pozyx.push_back(p);
    for (auto& p : s.gt)
      if (in(p)) o.gt.push_back(p);
    o.t_begin = std::max(a, s.t_begin);
    o.t_end = std::min(b, s.t_end);
  }
  return out;
}

}  // namespace

Streams cropStreams(const Streams& s, double a, double b) {
  return std::move(cropInto(s, {{a, b}}, nullptr).front());
}

std::vector<Streams> cropStreams(Streams&& s,
                                 const std::vector<std::pair<double, double>>& ranges) {
  std::vector<Streams> out = cropInto(s, ranges, &s);
  s = Streams();
  return out;
}

KinRows kinematicRows(const std::vector<Streams>& recs, const Corrections& c,
                      const config::WheelchairConfig& cfg, const DiagnosisOptions& opt) {
  // Memory (docs/benchmarks.md, "Ninth round, stage 1"): no corrected copy of the encoder
  // times or of the gyro, no stored cumulative gyro integral (LinearIntegral makes it as the
  // windows move forward), the rows sized from an upper bound of their count (no growth slack).
  KinRows k;
  const double lw = cfg.vehicle.geom.track_width_m;
  const auto& cols = kinematicColumns();
  const std::size_t ncol = cols.size();
  std::vector<double> y, X;  // X row-major, ncol per row
  std::vector<std::vector<double>*> per_row{&k.t0, &k.t1, &k.v, &k.omega, &k.phi};
  double gyro_dt_sum = 0;
  int gyro_dt_n = 0;
  for (const auto& s : recs) {
    if (!s.hasEncoders() || !s.hasGyro()) continue;
    auto te = [&](std::size_t i) { return s.te[i] - c.delay_enc; };
    // the median encoder spacing of the corrected times (a copy only when they are shifted)
    double dte = 0;
    if (c.delay_enc == 0) {
      dte = sensors::medianSpacing(s.te);
    } else {
      std::vector<double> tc(s.te.size());
      for (size_t i = 0; i < tc.size(); ++i) tc[i] = te(i);
      dte = sensors::medianSpacing(tc);
    }
    double dtg = sensors::medianSpacing(s.tg);
    if (!(dte > 0) || !(dtg > 0)) continue;
    // gyro stamps lag truth by delay_imu: truth time t is at stamp t + delay_imu
    LinearIntegral G;
    G.init(s.tg, s.gz, c.gyro_bias, c.gyro_scale, c.delay_imu);
    gyro_dt_sum += dtg, gyro_dt_n++;
    int step = std::max(1, static_cast<int>(std::lround(opt.window_s / dte)));
    {  // at most one row per `step` encoder samples
      const std::size_t n = y.size() + s.te.size() / static_cast<std::size_t>(step);
      y.reserve(n), X.reserve(n * ncol);
      for (auto* v : per_row) v->reserve(n);
    }
    const double h = std::max(opt.window_s, dtg);
    int begin = static_cast<int>(y.size());
    for (size_t i = 0; i + step < s.te.size(); i += step) {
      size_t j = i + step;
      double t0 = te(i), t1 = te(j);
      G.release(t0 - h);  // the earliest time this window and the later ones read
      bool gap = false;
      for (size_t m = i + 1; m <= j; ++m)
        if (te(m) - te(m - 1) > opt.max_gap_s) gap = true;
      double dR = (s.sR[j] - s.sR[i]) / c.enc_scale[0];
      double dL = (s.sL[j] - s.sL[i]) / c.enc_scale[1];
      double dphi_enc = (dR - dL) / lw;
      // heading in the start frame (cumulative distances are kept from the recording start)
      double phi_mid =
          0.5 * ((s.sR[i] + s.sR[j]) / c.enc_scale[0] - (s.sL[i] + s.sL[j]) / c.enc_scale[1]) / lw;
      if (gap || G.maxGap(t0, t1) > opt.max_gap_s) {
        if (static_cast<int>(y.size()) > begin)
          k.groups.push_back({begin, static_cast<int>(y.size())});
        begin = static_cast<int>(y.size());
        continue;
      }
      double ig = G.integral(t0, t1);
      y.push_back(ig - dphi_enc);
      // The gyro's rate change over the window (the delay column, -d (omega(t1) - omega(t0))
      // to first order): the gyro's mean over +-h (h = one window) around each end, not one
      // sample each. With single samples the regressor carries the gyro's sample noise (errors
      // in variables): on stretches without turns (the held-out last 30 % of a `square` drive)
      // that noise alone made a delay's predicted held-out gain look testable (even averaged
      // over +-50 ms: LR 23 > 9) while the realised gain was negative, so real 40-95 ms gyro
      // delays were rejected. Averaged over +-one window such stretches are seen as not
      // testing the term (LR 5 < 9).
      auto meanRate = [&](double tc) { return G.integral(tc - h, tc + h) / (2 * h); };
      const effects::KinematicWindow w{t1 - t0, dR, dL, lw, meanRate(t1) - meanRate(t0)};
      for (const auto& c : cols) X.push_back(c.value(w));
      k.t0.push_back(t0), k.t1.push_back(t1);
      k.v.push_back(0.5 * (dR + dL) / (t1 - t0));
      k.omega.push_back(dphi_enc / (t1 - t0));
      k.phi.push_back(phi_mid);
    }
    if (static_cast<int>(y.size()) > begin) k.groups.push_back({begin, static_cast<int>(y.size())});
  }
  k.y = Eigen::Map<Eigen::VectorXd>(y.data(), y.size());
  std::vector<double>().swap(y);
  k.X.resize(k.y.size(), ncol);
  for (Eigen::Index i = 0; i < k.y.size(); ++i)
    for (size_t j = 0; j < ncol; ++j) k.X(i, j) = X[i * ncol + j];
  std::vector<double>().swap(X);
  const double tick_m = cfg.vehicle.geom.wheel_radius_m * cfg.encoders.params.wheelRadPerTick();
  double dtg = gyro_dt_n ? gyro_dt_sum / gyro_dt_n : 0.01;
  k.noise_var_per_s = cfg.imu.gyro_noise_rad_s * cfg.imu.gyro_noise_rad_s * dtg;
  k.noise_var_const = 2.0 * tick_m * tick_m / 6.0 / (lw * lw);
  return k;
}

namespace {

/// Every effect's columns of one stage, in registry order.
template <class Column>
std::vector<Column> registryColumns(std::vector<Column> (effects::Effect::*of)() const) {
  std::vector<Column> out;
  for (const effects::Effect* e : effects::effectRegistry())
    for (auto& col : (e->*of)()) out.push_back(col);
  return out;
}

template <class Column>
int indexOf(const std::vector<Column>& cols, const std::string& name) {
  for (std::size_t j = 0; j < cols.size(); ++j)
    if (cols[j].name == name) return static_cast<int>(j);
  throw std::logic_error("no diagnosis column '" + name + "'");
}

}  // namespace

const std::vector<effects::KinematicColumn>& kinematicColumns() {
  static const auto c = registryColumns(&effects::Effect::kinematicColumns);
  return c;
}

const std::vector<effects::DriveColumn>& driveColumns() {
  static const auto c = registryColumns(&effects::Effect::driveColumns);
  return c;
}

int columnIndex(effects::Stage stage, const std::string& name) {
  return stage == effects::Stage::kinematic ? indexOf(kinematicColumns(), name)
                                            : indexOf(driveColumns(), name);
}

std::vector<Candidate> stageCandidates(effects::Stage stage, const effects::TermOptions& o) {
  const int ncol = static_cast<int>(stage == effects::Stage::kinematic ? kinematicColumns().size()
                                                                       : driveColumns().size());
  std::vector<Candidate> out;
  for (const effects::Effect* e : effects::effectRegistry())
    for (const auto& term : e->residualTerms(o)) {
      if (term.stage != stage) continue;
      Eigen::MatrixXd S = Eigen::MatrixXd::Zero(ncol, term.coefficients.size());
      for (std::size_t k = 0; k < term.coefficients.size(); ++k)
        for (const auto& col : term.coefficients[k]) S(columnIndex(stage, col), k) = 1.0;
      out.push_back({term.name, e->id(), S, term.conflicts, term.plausible});
    }
  return out;
}

const std::vector<std::string>& dynLibNames() {
  static const std::vector<std::string> n = {
      "1",      "v",       "omega",   "vdot",       "omegadot",     "sgn(u)",
      "|u|",    "u^2",     "v*omega", "omega^2",    "cos(phi)",     "sin(phi)",
      "i_self", "i_other", "v*|v|",   "sgn(omega)", "castor_swivel"};
  return n;
}

/// tanh width of the castors' swivel-rate sign (rad/s).
constexpr double kSwivelRateWidth_rad_s = 0.3;

std::vector<double> castorSwivelMoment(const std::vector<double>& t_s,
                                       const std::vector<double>& v_m_s,
                                       const std::vector<double>& omega_rad_s,
                                       const CastorGeometry& g) {
  const std::size_t n = std::min({t_s.size(), v_m_s.size(), omega_rad_s.size()});
  std::vector<double> out(n, 0.0);
  const double d = g.relaxation_m;
  if (!(d > 0)) return out;
  double b[2] = {0.0, 0.0};  // swivel angles of the left (y > 0) and right castor (rad)
  for (std::size_t i = 0; i < n; ++i) {
    const double v = v_m_s[i], w = omega_rad_s[i];
    const double dt = i > 0 ? std::max(0.0, t_s[i] - t_s[i - 1]) : 0.0;
    double m = 0;
    for (int k = 0; k < 2; ++k) {
      const double y = k == 0 ? g.half_spacing_m : -g.half_spacing_m;
      const double vx = v - w * y, vy = w * g.x_m;
      auto rate = [&](double a) { return (vy * std::cos(a) - vx * std::sin(a)) / d - w; };
      // Explicit sub-steps, each turning the castor by at most ~0.05 rad (stable: the castor
      // relaxes at |v| / d, ~20 1/s at 1.5 m/s over 0.08 m).
      const double vmax = std::hypot(vx, vy) / d + std::abs(w);
      const int sub = std::clamp(static_cast<int>(std::ceil(dt * vmax / 0.05)), 1, 1000);
      // After a reversal the castor sits at its unstable balance (the rate is odd in the
      // motion): a real castor is never exactly there; nudged, it swings round.
      const double slope = -(vy * std::sin(b[k]) + vx * std::cos(b[k])) / d;
      if (slope > 0 && std::abs(rate(b[k])) < 0.01 * slope) b[k] += 0.01;
      for (int q = 0; q < sub; ++q) b[k] += rate(b[k]) * dt / sub;
      m += std::tanh(rate(b[k]) / kSwivelRateWidth_rad_s) *
           ((g.x_m * std::cos(b[k]) + y * std::sin(b[k])) / d - 1.0);
    }
    out[i] = m;
  }
  return out;
}

namespace {

/// Releases the memory of each vector.
void release(std::initializer_list<std::vector<double>*> xs) {
  for (std::vector<double>* x : xs) std::vector<double>().swap(*x);
}

/// Gives each output column its final size `n` if it has none yet (its first segment): an
/// output's memory is taken only when it is first written, after the segment's signals read
/// before it are released (memory: the rows of a ten-hour drive's fit part and its segment do
/// not all exist at once, docs/benchmarks.md "Tenth round").
void sized(std::initializer_list<std::vector<double>*> xs, int n) {
  for (std::vector<double>* x : xs)
    if (x->empty()) x->resize(n);
}

/// The rows of one resampled segment (its grid samples [seg.i0, seg.i1)) written into d's
/// outputs (d.y sized already, the others sized here when first written: nR per grid sample,
/// 2 nR per row) from right-motor row bR on, the left motor's from bR + nR on. Each
/// signal of the segment is released once read and each temporary made only when needed
/// (memory: the segment of a ten-hour drive is ~1.3 M grid steps, 10 MB per signal).
/// lw: track width (m); eps: the Coulomb smoothing speed (m/s); fc, fs: cutoff, grid rate (Hz).
void segmentRows(signals::DriveSegment& seg, int bR, int nR, const model::DriveTrain& dt, double lw,
                 double eps, double fc, double fs, const CastorGeometry& castors, DynRows& d) {
  const std::vector<double>& tg = seg.t;
  const int n = static_cast<int>(tg.size()), i0 = seg.i0, i1 = seg.i1;
  auto& G = d.grid;
  // sgn(u): nonlinear, from lightly filtered rim speeds, then filtered like everything else
  const double fc2 = std::min(2.5 * fc, 0.45 * fs);
  std::array<std::vector<double>, 2> sg;
  for (int s = 0; s < 2; ++s) {
    std::vector<double> u2 = sensors::filtfiltButter2(seg.u[s], fc2, fs);
    release({&seg.u[s]});
    for (double& x : u2) x = std::tanh(x / eps);
    sg[s] = sensors::filtfiltButter2(u2, fc, fs);
  }
  std::vector<double> phi(n);
  for (int i = 0; i < n; ++i) phi[i] = (seg.p[0][i] - seg.p[1][i]) / lw;
  release({&seg.p[0], &seg.p[1]});
  // The kinematics, the nominal model's currents and the rim speeds.
  const auto &uRf = seg.u_f[0], &uLf = seg.u_f[1], &udR = seg.a_f[0], &udL = seg.a_f[1];
  std::array<std::vector<double>, 2> pred{std::vector<double>(n), std::vector<double>(n)};
  std::vector<double> vs(n), ws(n);  // the castors' swivel moment reads the whole segment's
  sized({&G.t, &G.v, &G.omega, &G.vdot, &G.omegadot, &G.phi}, nR);
  sized({&d.u}, 2 * nR);
  for (int i = 0; i < n; ++i) {
    const double v = 0.5 * (uRf[i] + uLf[i]), w = (uRf[i] - uLf[i]) / lw;
    vs[i] = v, ws[i] = w;
    const double vd = 0.5 * (udR[i] + udL[i]), wd = (udR[i] - udL[i]) / lw;
    const Eigen::Vector2d ip = dt.currents({v, w, phi[i]}, vd, wd);
    pred[0][i] = ip(0), pred[1][i] = ip(1);
    if (i < i0 || i >= i1) continue;
    const int r = bR + i - i0;
    G.t[r] = tg[i], G.v[r] = v, G.omega[r] = w, G.vdot[r] = vd, G.omegadot[r] = wd;
    G.phi[r] = phi[i];
    d.u[r] = uRf[i], d.u[r + nR] = uLf[i];
  }
  release({&seg.u_f[0], &seg.u_f[1], &seg.a_f[0], &seg.a_f[1]});
  {
    const std::vector<double> castor = castorSwivelMoment(tg, vs, ws, castors);
    release({&vs, &ws});
    sized({&d.castor}, nR);
    for (int i = i0; i < i1; ++i) d.castor[bR + i - i0] = castor[i];
  }
  // The heading's cos and sin, filtered.
  for (int c = 0; c < 2; ++c) {
    std::vector<double> x(n);
    for (int i = 0; i < n; ++i) x[i] = c == 0 ? std::cos(phi[i]) : std::sin(phi[i]);
    x = sensors::filtfiltButter2(x, fc, fs);
    std::vector<double>& out = c == 0 ? G.cos_phi : G.sin_phi;
    sized({&out}, nR);
    for (int i = i0; i < i1; ++i) out[bR + i - i0] = x[i];
  }
  release({&phi});
  // Per motor: y, the smoothed sign, the model current's derivative, the current.
  for (int s = 0; s < 2; ++s) {
    const std::vector<double> dp = sensors::centralDerivative(tg, pred[s]);
    const std::vector<double>& im = seg.i_f[s];
    sized({&d.sgn_u, &d.dcurrent_model, &d.current}, 2 * nR);
    for (int i = i0; i < i1; ++i) {
      const int k = bR + i - i0 + s * nR;
      d.y(k) = im[i] - pred[s][i];
      d.sgn_u[k] = sg[s][i];
      d.dcurrent_model[k] = dp[i];
      d.current[k] = im[i];  // io, the other motor's, is the other side's row
    }
    release({&pred[s], &seg.i_f[s], &sg[s]});
  }
}

}  // namespace

DynRows dynamicRows(const std::vector<Streams>& recs, const Corrections& c,
                    const config::WheelchairConfig& cfg, const DiagnosisOptions& opt,
                    const std::function<void(std::size_t)>& copied) {
  DynRows d;
  const auto& P = cfg.vehicle;
  const auto& g = P.geom;
  const double lw = g.track_width_m, r = g.wheel_radius_m, rG = g.gear_ratio;
  model::DriveTrain dt = model::DriveTrain::symmetric(P);
  const double theta5 = P.motor_viscous_Nm_s_rad / P.torque_constant_Nm_A;
  const double alpha = 1.0 / (P.gearbox_efficiency * P.torque_constant_Nm_A);
  const double eps = dt.coulomb_smoothing_m_s > 0 ? dt.coulomb_smoothing_m_s : 0.01;
  const double Mg2 = (g.body_mass_kg + 2 * g.wheel_mass_kg) * 9.81 / 2.0;
  const double fs = opt.grid_rate_hz, fc = opt.cutoff_hz;
  d.theta5 = theta5, d.alpha = alpha, d.wheel_radius_m = r, d.gear_ratio = rG;
  d.half_weight_N = Mg2;
  signals::DriveSignalOptions so;
  so.grid_rate_hz = fs, so.cutoff_hz = fc, so.max_gap_s = opt.max_gap_s;
  so.edge_trim_s = opt.edge_trim_s;
  // Every recording's resampled segments first (~11 doubles per grid step), so that the rows
  // (2 per grid step, ~30 doubles each) are written once into outputs of their final size:
  // no per-row temporaries, no growth slack (docs/benchmarks.md, "Memory").
  std::vector<signals::DriveSegment> segs;
  for (std::size_t k = 0; k < recs.size(); ++k) {
    const Streams& s = recs[k];
    if (!s.hasEncoders() || !s.hasMotors()) continue;
    // The recording with the sensor corrections applied.
    signals::DriveStreams ds;
    ds.te.resize(s.te.size()), ds.tm.resize(s.tm.size());
    for (size_t i = 0; i < s.te.size(); ++i) ds.te[i] = s.te[i] - c.delay_enc;
    for (size_t i = 0; i < s.tm.size(); ++i) ds.tm[i] = s.tm[i] - c.delay_motors;
    ds.s = {s.sR, s.sL};
    for (auto& v : ds.s[0]) v /= c.enc_scale[0];
    for (auto& v : ds.s[1]) v /= c.enc_scale[1];
    ds.i = {s.iR, s.iL};
    if (copied) copied(k);  // s is not read after this
    for (signals::DriveSegment& seg : signals::prepare(ds, so)) segs.push_back(std::move(seg));
  }
  int nR = 0;
  for (const auto& seg : segs) nR += seg.i1 - seg.i0;
  d.y.resize(2 * nR);  // uninitialised: its memory is taken as it is written
  const CastorGeometry castors{opt.castor_x_m, opt.castor_half_spacing_m, opt.castor_relaxation_m};
  int row_R = 0;  // next right-motor row; its left-motor row is row_R + nR
  for (signals::DriveSegment& seg : segs) {
    segmentRows(seg, row_R, nR, dt, lw, eps, fc, fs, castors, d);
    d.groups.push_back({row_R, row_R + seg.i1 - seg.i0});
    row_R += seg.i1 - seg.i0;
    seg = signals::DriveSegment{};  // consumed: its memory goes back before the next one
  }
  const std::size_t nseg = d.groups.size();
  for (std::size_t q = 0; q < nseg; ++q)
    d.groups.push_back({d.groups[q].first + nR, d.groups[q].second + nR});
  d.noise_var = cfg.motors.current_noise_A * cfg.motors.current_noise_A *
                filteredNoiseFactor(fc, cfg.motors.rate_hz > 0 ? cfg.motors.rate_hz : 100.0);
  return d;
}

/// tanh width of the library's sgn(omega) (rad/s): a dry moment's sign, on the filtered rate.
constexpr double kSgnOmegaWidth_rad_s = 0.02;

Eigen::VectorXd DynRows::libColumn(int j, int r0, int n) const {
  if (j < 0 || j >= 17)
    throw std::out_of_range("DynRows::libColumn: no column " + std::to_string(j));
  const int nR = static_cast<int>(y.size() / 2);
  Eigen::VectorXd c(n);
  for (int q = 0; q < n; ++q) {
    const int k = r0 + q, i = k < nR ? k : k - nR;  // row, grid sample
    const double uk = u[k], vk = grid.v[i], wk = grid.omega[i];
    const double row[17] = {1.0,
                            vk,
                            wk,
                            grid.vdot[i],
                            grid.omegadot[i],
                            sgn_u[k],
                            std::abs(uk),
                            uk * uk,
                            vk * wk,
                            wk * wk,
                            grid.cos_phi[i],
                            grid.sin_phi[i],
                            current[k],
                            current[k < nR ? k + nR : k - nR],
                            vk * std::abs(vk),
                            std::tanh(wk / kSgnOmegaWidth_rad_s),
                            castor[i]};
    c(q) = row[j];
  }
  return c;
}

void DynRows::designBlock(long r0, long nb, Eigen::MatrixXd& out) const {
  const auto& cols = driveColumns();
  const int ncol = static_cast<int>(cols.size());
  out.resize(nb, ncol);
  for (long q = 0; q < nb; ++q) {
    const int k = static_cast<int>(r0 + q), i = step(k);
    const effects::DriveSample sample{
        side(k),           u[k],   sgn_u[k], grid.vdot[i],   grid.cos_phi[i], grid.sin_phi[i],
        dcurrent_model[k], theta5, alpha,    wheel_radius_m, gear_ratio,      half_weight_N};
    for (int j = 0; j < ncol; ++j) out(q, j) = cols[j].value(sample);
  }
}

CatalogueDesign DynRows::design() const {
  return {static_cast<long>(y.size()), static_cast<long>(driveColumns().size()),
          [this](long r0, long nb, Eigen::MatrixXd& out) { designBlock(r0, nb, out); }};
}

void CatalogueDesign::block(long r0, long nb, Eigen::MatrixXd& out) const {
  if (X_)
    out = X_->middleRows(r0, nb);
  else
    block_(r0, nb, out);
}

void CatalogueDesign::blockTimes(long r0, long nb, const Eigen::MatrixXd& S,
                                 Eigen::MatrixXd& out) const {
  if (X_) {
    out.noalias() = X_->middleRows(r0, nb) * S;
    return;
  }
  Eigen::MatrixXd B;
  block_(r0, nb, B);
  out.noalias() = B * S;
}

Eigen::MatrixXd CatalogueDesign::times(const Eigen::MatrixXd& S) const {
  Eigen::MatrixXd D(rows_, S.cols()), B;
  for (long r0 = 0; r0 < rows_; r0 += stats::kDesignBlockRows) {
    const long nb = std::min(stats::kDesignBlockRows, rows_ - r0);
    blockTimes(r0, nb, S, B);
    D.middleRows(r0, nb) = B;
  }
  return D;
}

namespace {

/// The number of design columns of the accepted terms (the sum of their selectors' widths).
int acceptedWidth(const std::vector<Candidate>& cands, const std::vector<int>& accepted) {
  int k = 0;
  for (int a : accepted) k += static_cast<int>(cands[a].S.cols());
  return k;
}

}  // namespace

Eigen::MatrixXd acceptedDesign(const CatalogueDesign& X, const std::vector<Candidate>& cands,
                               const std::vector<int>& accepted) {
  return X.times(acceptedSelector(X, cands, accepted));
}

Eigen::MatrixXd acceptedSelector(const CatalogueDesign& X, const std::vector<Candidate>& cands,
                                 const std::vector<int>& accepted) {
  Eigen::MatrixXd S(X.cols(), acceptedWidth(cands, accepted));
  int c = 0;
  for (int a : accepted) {
    S.middleCols(c, cands[a].S.cols()) = cands[a].S;
    c += static_cast<int>(cands[a].S.cols());
  }
  return S;
}

stats::DesignRows acceptedRows(const CatalogueDesign& X, const std::vector<Candidate>& cands,
                               const std::vector<int>& accepted) {
  return [X, S = acceptedSelector(X, cands, accepted)](long r0, long nb, Eigen::MatrixXd& out) {
    X.blockTimes(r0, nb, S, out);
  };
}

LinearFit fitAccepted(const CatalogueDesign& X, const Eigen::VectorXd& y,
                      const std::vector<Candidate>& cands, const std::vector<int>& accepted,
                      const stats::Groups& groups, int lags) {
  return fitLinear(acceptedRows(X, cands, accepted), acceptedWidth(cands, accepted), y, groups,
                   lags);
}

Eigen::VectorXd acceptedPrediction(const CatalogueDesign& X, const std::vector<Candidate>& cands,
                                   const std::vector<int>& accepted, const Eigen::VectorXd& coef) {
  const Eigen::MatrixXd S = acceptedSelector(X, cands, accepted);
  Eigen::VectorXd p(X.rows());
  Eigen::MatrixXd B;
  for (long r0 = 0; r0 < X.rows(); r0 += stats::kDesignBlockRows) {
    const long nb = std::min(stats::kDesignBlockRows, X.rows() - r0);
    X.blockTimes(r0, nb, S, B);
    p.segment(r0, nb).noalias() = B * coef;
  }
  return p;
}

stats::SelectionRule selectionRule(const DiagnosisOptions& opt, std::size_t m) {
  return {opt.alpha, static_cast<int>(m), opt.min_bic_drop};
}

namespace {

/// true: candidate c cannot be accepted together with the accepted terms `acc`.
bool conflictsWith(const Candidate& c, const std::vector<int>& acc,
                   const std::vector<Candidate>& cands) {
  for (int a : acc) {
    for (auto& n : c.conflicts)
      if (cands[a].name == n) return true;
    for (auto& n : cands[a].conflicts)
      if (c.name == n) return true;
  }
  return false;
}

/// The held-out check of a trial term: the validation rows' RSS without it (prediction p0v =
/// D0v b0 of the validation rows, RSS rss0v) and with it (p1v = D1v b1), the realised and the
/// predicted likelihood-ratio gain (n_eff log(rss0 / rss1); n_eff log(1 + |p1v - p0v|^2 /
/// rss1)), recorded in `st`. Empty, or why the term is rejected.
/// A term the held-out rows cannot test by its predicted gain (expected LR below
/// validation_min_expected_lr) is still judged by what it does there: a realised LR below
/// -chi2_1(1 - alpha) (`alpha`: the selection's per-candidate level) makes the held-out
/// prediction significantly worse, so it counts as tested and failed (if the term were right,
/// the realised LR would scatter about the expected one, sd ~ 2 sqrt(expected): below
/// -chi2_1(0.99) = -6.6 at expected 9 is beyond 2.6 sd). E.g. expected 8.2, realised -19:
/// rejected.
std::string heldOutCheck(const SelectionData& d, const Eigen::VectorXd& p0v, double rss0v,
                         const Eigen::VectorXd& p1v, const DiagnosisOptions& opt, double alpha,
                         SelectionStep& st) {
  const stats::HeldOutGain g = stats::heldOutGain(d.y_val, p0v, rss0v, p1v, d.g_val, d.lags);
  st.rss0_val = rss0v, st.rss1_val = g.rss1, st.n_eff_val = g.n_eff;
  st.lr_val = g.lr, st.lr_val_expected = g.lr_expected;
  st.val_tested = st.lr_val_expected >= opt.validation_min_expected_lr;
  if (st.val_tested && st.lr_val < opt.validation_fraction_of_expected * st.lr_val_expected)
    return "does not improve the held-out data as predicted";
  if (!st.val_tested && st.lr_val < -stats::chi2Quantile(1 - alpha, 1)) {
    st.val_tested = true;  // the held-out rows did test it: it failed
    return fmt::format(
        "makes the held-out prediction significantly worse (realised likelihood "
        "ratio {:.1f} < -{:.1f}, predicted {:.1f})",
        st.lr_val, stats::chi2Quantile(1 - alpha, 1), st.lr_val_expected);
  }
  return {};
}

}  // namespace

Selection forwardSelect(const SelectionData& d, const std::vector<Candidate>& cands,
                        const DiagnosisOptions& opt, const std::vector<int>& forced) {
  Selection sel;
  const stats::SelectionRule rule = selectionRule(opt, cands.size());
  const bool have_val = d.y_val.size() > 10;
  auto contributionRms = [&](int ci, const Eigen::VectorXd& coef) {
    return acceptedPrediction(d.X_fit, cands, {ci}, coef).norm() /
           std::sqrt(std::max<double>(1, d.y_fit.size()));
  };
  // Forward steps: the fit of the accepted terms (f0) and each candidate's trial.
  LinearFit f0;
  Eigen::VectorXd p0v;  // the accepted terms' prediction of the validation rows
  double rss0v = 0;
  std::vector<SelectionStep> trial_step(cands.size());
  std::vector<LinearFit> trial_fit(cands.size());
  stats::SelectionHooks h;
  h.step = [&](const std::vector<int>& acc) {
    f0 = fitAccepted(d.X_fit, d.y_fit, cands, acc, d.g_fit, d.lags);
    p0v = have_val ? acceptedPrediction(d.X_val, cands, acc, f0.beta) : Eigen::VectorXd();
    rss0v = have_val ? (d.y_val - p0v).squaredNorm() : 0;
  };
  h.evaluate = [&](int ci, const std::vector<int>& acc) {
    stats::Trial t;
    const Candidate& c = cands[ci];
    t.skip = conflictsWith(c, acc, cands);
    if (t.skip) return t;
    std::vector<int> trial = acc;
    trial.push_back(ci);
    LinearFit& f1 = trial_fit[ci];
    f1 = fitAccepted(d.X_fit, d.y_fit, cands, trial, d.g_fit, d.lags);
    if (!f1.ok) {
      t.reject = "not identifiable on this data";
      return t;
    }
    double ne = effectiveSampleSize(f1.residual, d.g_fit, d.lags);
    f1.residual = Eigen::VectorXd();  // only beta is read later: one residual per candidate
    int k = static_cast<int>(c.S.cols());
    t.evidence = compareNested(f0.rss, f1.rss, k, ne);
    SelectionStep& st = trial_step[ci];
    st = SelectionStep{};
    st.candidate = ci;
    st.evidence = t.evidence;
    st.rss0_fit = f0.rss, st.rss1_fit = f1.rss;
    st.coef = f1.beta.tail(k);
    return t;
  };
  h.confirm = [&](int ci) -> std::string {
    const Candidate& c = cands[ci];
    SelectionStep& st = trial_step[ci];
    if (c.plausible && !c.plausible(st.coef)) return "physically implausible parameters";
    double crms = contributionRms(ci, st.coef);
    if (crms < d.min_contribution_rms)
      return "irrelevant: contribution rms " + std::to_string(crms) + " below " +
             std::to_string(d.min_contribution_rms);
    if (!have_val) return {};
    const LinearFit& f1 = trial_fit[ci];
    std::vector<int> trial = sel.accepted;
    trial.push_back(ci);
    return heldOutCheck(d, p0v, rss0v, acceptedPrediction(d.X_val, cands, trial, f1.beta), opt,
                        rule.level(), st);
  };
  h.accepted = [&](int ci) {
    sel.accepted.push_back(ci);
    sel.steps.push_back(trial_step[ci]);
  };
  // Backward elimination: a term accepted early may be made redundant by a later one.
  std::vector<int> f1_of;  // the accepted set the cached joint fit belongs to
  LinearFit f1;
  double ne1 = 0;
  h.removal = [&](int a, const std::vector<int>& acc) {
    stats::Trial t;
    if (a < static_cast<int>(forced.size())) {
      t.skip = true;
      return t;
    }
    if (f1_of != acc) {
      f1 = fitAccepted(d.X_fit, d.y_fit, cands, acc, d.g_fit, d.lags);
      ne1 = effectiveSampleSize(f1.residual, d.g_fit, d.lags);
      f1_of = acc;
    }
    int col = 0;
    for (int q = 0; q < a; ++q) col += static_cast<int>(cands[acc[q]].S.cols());
    const Candidate& c = cands[acc[a]];
    int k = static_cast<int>(c.S.cols());
    std::vector<int> rest = acc;
    rest.erase(rest.begin() + a);
    LinearFit r0 = fitAccepted(d.X_fit, d.y_fit, cands, rest, d.g_fit, d.lags);
    t.evidence = compareNested(r0.rss, f1.rss, k, ne1);
    Eigen::VectorXd coef = f1.beta.segment(col, k);
    if (contributionRms(acc[a], coef) < d.min_contribution_rms ||
        (c.plausible && !c.plausible(coef)))
      t.reject = "irrelevant or implausible given the others";
    return t;
  };
  h.removed = [&](int a) {
    sel.accepted.erase(sel.accepted.begin() + a);
    sel.steps.erase(sel.steps.begin() + (a - static_cast<int>(forced.size())));
  };
  sel.accepted = forced;
  std::vector<std::pair<int, std::string>> log;
  stats::selectTerms(static_cast<int>(cands.size()), rule, h, forced, &log);
  for (auto& [ci, why] : log) sel.log.push_back(cands[ci].name + ": " + why);
  sel.fit = fitAccepted(d.X_fit, d.y_fit, cands, sel.accepted, d.g_fit, d.lags);
  int c = 0;
  for (int a : sel.accepted) {
    int k = static_cast<int>(cands[a].S.cols());
    sel.ranges.push_back({c, k});
    c += k;
  }
  return sel;
}

}  // namespace wheelchair::diagnosis
