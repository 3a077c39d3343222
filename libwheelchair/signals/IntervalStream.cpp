#include "libwheelchair/signals/IntervalStream.h"

#include "libwheelchair/sensors/Encoders.h"
#include "libwheelchair/sensors/Filtering.h"
#include "libwheelchair/sensors/VoltageCircuit.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>

namespace wheelchair::signals {

// ---------------------------------------------------------------------------------------
// StreamingFiltfilt

namespace {
constexpr long kBlock = 8192;  // samples per backward-pass block
}  // namespace

StreamingFiltfilt::StreamingFiltfilt(int channels, double cutoff_hz, double rate_hz, long min_lag,
                                     Emit emit)
    : C_(channels), cutoff_hz_(cutoff_hz), rate_hz_(rate_hz), emit_(std::move(emit)) {
  f_ = sensors::butter2Lowpass(cutoff_hz, rate_hz);  // validates
  pad_ = static_cast<long>(sensors::filtfiltPadLength(1L << 40, cutoff_hz, rate_hz));
  block_ = kBlock;
  run_in_ = std::max({static_cast<long>(std::ceil(40 * rate_hz / cutoff_hz)), pad_ + 2, min_lag});
  first_ = 2 * (block_ + run_in_);  // shorter series: filtered whole
}

void StreamingFiltfilt::push(const double* x) {
  ++n_;
  if (!started_) {
    raw_.insert(raw_.end(), x, x + C_);
    if (n_ == first_) start();
    return;
  }
  raw_.insert(raw_.end(), x, x + C_);
  forward(x);
  while (n_ - e0_ >= block_ + run_in_) emitBlock(block_, false);
}

// The forward pass over the front reflection and the samples waiting so far.
void StreamingFiltfilt::start() {
  started_ = true;
  const auto& f = f_;
  const double g = f.dcGain();
  z1_.assign(C_, 0.0);
  z2_.assign(C_, 0.0);
  for (int c = 0; c < C_; ++c) {
    const double x0 = raw_[c];
    const double e0 = 2.0 * x0 - raw_[pad_ * C_ + c];  // ext[0]
    z1_[c] = (g - f.b0) * e0;
    z2_[c] = (f.b2 - f.a2 * g) * e0;
    for (long k = pad_; k >= 1; --k) {  // ext[0 .. pad-1] = 2 x0 - x[k]
      const double xi = 2.0 * x0 - raw_[k * C_ + c];
      const double yi = f.b0 * xi + z1_[c];
      z1_[c] = f.b1 * xi - f.a1 * yi + z2_[c];
      z2_[c] = f.b2 * xi - f.a2 * yi;
    }
  }
  const std::vector<double> waiting(raw_.begin(), raw_.end());
  for (long j = 0; j < n_; ++j) forward(&waiting[std::size_t(j * C_)]);
  while (n_ - e0_ >= block_ + run_in_) emitBlock(block_, false);
}

void StreamingFiltfilt::forward(const double* x) {
  const auto& f = f_;
  for (int c = 0; c < C_; ++c) {
    const double xi = x[c];
    const double yi = f.b0 * xi + z1_[c];
    z1_[c] = f.b1 * xi - f.a1 * yi + z2_[c];
    z2_[c] = f.b2 * xi - f.a2 * yi;
    fwd_.push_back(yi);
  }
}

// Backward pass over the forward outputs held (from the newest one, at its steady state, or
// over the end reflection when `last`), emitting the first `count`.
void StreamingFiltfilt::emitBlock(long count, bool last) {
  const auto& f = f_;
  const double g = f.dcGain();
  const long held = n_ - e0_;
  std::vector<double> out(static_cast<std::size_t>(count * C_)), tail;
  for (int c = 0; c < C_; ++c) {
    double y0 = fwd_[std::size_t((held - 1) * C_ + c)];
    tail.clear();  // forward outputs of the end reflection 2 x[n-1] - x[n-1-k]
    if (last) {
      double fz1 = z1_[c], fz2 = z2_[c];
      const double xl = raw_[std::size_t((held - 1) * C_ + c)];
      for (long k = 1; k <= pad_; ++k) {
        const double xi = 2.0 * xl - raw_[std::size_t((held - 1 - k) * C_ + c)];
        const double yi = f.b0 * xi + fz1;
        fz1 = f.b1 * xi - f.a1 * yi + fz2;
        fz2 = f.b2 * xi - f.a2 * yi;
        tail.push_back(yi);
      }
      y0 = tail.back();
    }
    double z1 = (g - f.b0) * y0, z2 = (f.b2 - f.a2 * g) * y0;
    const auto step = [&](double xi) {
      const double yi = f.b0 * xi + z1;
      z1 = f.b1 * xi - f.a1 * yi + z2;
      z2 = f.b2 * xi - f.a2 * yi;
      return yi;
    };
    for (auto it = tail.rbegin(); it != tail.rend(); ++it) step(*it);
    for (long j = held - 1; j >= 0; --j) {
      const double yi = step(fwd_[std::size_t(j * C_ + c)]);
      if (j < count) out[std::size_t(j * C_ + c)] = yi;
    }
  }
  emitFrom(out, count);
}

void StreamingFiltfilt::emitFrom(const std::vector<double>& out, long count) {
  std::vector<double> raw(static_cast<std::size_t>(C_));
  for (long j = 0; j < count; ++j) {
    for (int c = 0; c < C_; ++c) raw[std::size_t(c)] = raw_[std::size_t(j * C_ + c)];
    emit_(e0_ + j, raw.data(), &out[std::size_t(j * C_)]);
  }
  raw_.erase(raw_.begin(), raw_.begin() + count * C_);
  if (!fwd_.empty()) fwd_.erase(fwd_.begin(), fwd_.begin() + count * C_);
  e0_ += count;
}

void StreamingFiltfilt::finish() {
  const long held = n_ - e0_;
  if (held == 0) return;
  if (started_) {
    emitBlock(held, true);
    return;
  }
  // A short series: filtfiltButter2 itself on each channel.
  std::vector<double> out(static_cast<std::size_t>(held * C_)), x(static_cast<std::size_t>(held));
  for (int c = 0; c < C_; ++c) {
    for (long j = 0; j < held; ++j) x[std::size_t(j)] = raw_[std::size_t(j * C_ + c)];
    const auto y = sensors::filtfiltButter2(x, cutoff_hz_, rate_hz_);
    for (long j = 0; j < held; ++j) out[std::size_t(j * C_ + c)] = y[std::size_t(j)];
  }
  emitFrom(out, held);
}

}  // namespace wheelchair::signals

// ---------------------------------------------------------------------------------------
// IntervalConditioner

namespace wheelchair::signals {

namespace {

/// A sanitised stream (sanitize() of IntervalSignals.cpp as the samples come) with the running
/// integrals of its channels (intervalMeans' F), kept from the last sample the next query needs.
struct IntegralStream {
  struct Sample {
    double t;
    std::array<double, 4> x, F;
  };
  int channels = 0;
  std::deque<Sample> s;      ///< finalised samples (values and integrals known)
  std::deque<double> times;  ///< sanitised times, for the coverage test (grid)
  std::optional<Sample> front;
  bool ended = false;
  std::size_t count = 0;  ///< sanitised samples so far

  void finalise(double t, const std::array<double, 4>& x) {
    Sample n{t, x, {}};
    if (!front) {
      n.F.fill(0.0);
      front = n;
    } else {
      const Sample& p = s.back();
      for (int c = 0; c < channels; ++c) n.F[c] = p.F[c] + 0.5 * (x[c] + p.x[c]) * (t - p.t);
    }
    s.push_back(n);
  }
  /// The latest finalised time (-inf when none).
  double finalisedUntil() const { return s.empty() ? -INFINITY : s.back().t; }
  /// intervalMeans' integral from the first sample to t (ready(t) must hold).
  double integral(int c, double t) const {
    if (t <= front->t) return front->x[c] * (t - front->t);
    const Sample& b = s.back();
    if (t >= b.t) return b.F[c] + b.x[c] * (t - b.t);  // only when ended
    const auto it =
        std::upper_bound(s.begin(), s.end(), t, [](double v, const Sample& q) { return v < q.t; });
    const Sample &lo = *(it - 1), &hi = *it;
    const double h = t - lo.t, slope = (hi.x[c] - lo.x[c]) / (hi.t - lo.t);
    return lo.F[c] + lo.x[c] * h + 0.5 * slope * h * h;
  }
  bool ready(double t) const { return ended ? !s.empty() : finalisedUntil() > t; }
  /// Drops what queries from t on no longer need.
  void dropBefore(double t) {
    while (s.size() >= 2 && s[1].t <= t) s.pop_front();
  }
};

struct EncInterval {
  double t, t0, t1, u_r, u_l;
  std::array<double, 5> mean{};  ///< over [t0, t1]: i_r, i_l, U_r, U_l, gyro
};

double timeOf(double t) {
  return t;
}
double timeOf(const EncInterval& e) {
  return e.t;
}

// covered() of IntervalSignals.cpp on the part of a stream kept (its last time <= t onwards).
template <typename T>
bool coveredIn(const std::deque<T>& ts, double t, double max_gap) {
  auto it =
      std::upper_bound(ts.begin(), ts.end(), t, [](double v, const T& q) { return v < timeOf(q); });
  if (it == ts.begin()) return t == timeOf(ts.front());
  if (it == ts.end()) return t == timeOf(ts.back());
  return (timeOf(*it) - timeOf(*(it - 1))) <= max_gap;
}

}  // namespace

struct IntervalConditioner::Impl {
  const config::WheelchairConfig& cfg;
  IntervalSignalOptions o;
  RowSink sink;
  double dt, lw;
  long trim, min_len;
  // totals
  double ss_v = 0, ss_w = 0;
  std::size_t n_noise = 0;
  bool has_voltage = false;
  int n_segments = 0;

  // per recording
  int rec = 0;
  std::optional<sensors::WheelSpeedConverter> conv;
  std::deque<EncInterval> enc;
  std::size_t enc_done = 0;  ///< enc[0 .. enc_done) have their means
  std::size_t enc_count = 0;
  bool enc_ended = false;
  double enc_last_t1 = -INFINITY, enc_first_t = NAN;
  IntegralStream mot, imu;
  std::deque<io::MotorSample> mot_wait;     ///< sanitised, U not yet known (the next is needed)
  std::optional<io::MotorSample> mot_prev;  ///< the sample before mot_wait's first
  double mot_last_t = NAN, imu_last_t = NAN;
  bool any_voltage = false;
  // grid
  double t_lo = NAN;
  long kg = 0;
  // the current run of covered grid points
  std::unique_ptr<StreamingFiltfilt> run;
  long run_k0 = 0, run_len = 0;
  int run_segment = -1;
  // row making (the run's filtered samples, one behind for the central differences)
  struct Filtered {
    std::array<double, 7> raw, y;
  };
  Filtered p1{}, p2{};  ///< the last two filtered samples (row of p1 not yet made)
  bool have1 = false, have2 = false;
  long rows_made = 0;
  bool run_closing = false;

  Impl(const config::WheelchairConfig& c, const IntervalSignalOptions& opt, RowSink s)
      : cfg(c), o(opt), sink(std::move(s)) {
    dt = 1.0 / o.rate_hz;
    lw = cfg.vehicle.geom.track_width_m;
    trim = static_cast<long>(std::ceil(o.edge_trim_s / dt));
    min_len = static_cast<long>(std::ceil((2 * o.edge_trim_s + 1.0) / dt));
  }
  int channels() const { return o.gyro_omega ? 7 : 6; }

  void begin(int index) {
    rec = index;
    const auto& g = cfg.vehicle.geom;
    conv.emplace(cfg.encoders.params, g.wheel_radius_m, g.track_width_m);
    enc.clear();
    enc_done = enc_count = 0;
    enc_ended = false;
    enc_last_t1 = -INFINITY;
    enc_first_t = NAN;
    mot = IntegralStream{};
    mot.channels = 4;
    imu = IntegralStream{};
    imu.channels = 1;
    mot_wait.clear();
    mot_prev.reset();
    mot_last_t = imu_last_t = NAN;
    any_voltage = false;
    t_lo = NAN;
    kg = 0;
    run.reset();
    run_len = 0;
  }

  // --- streams ---------------------------------------------------------------------------
  void addEncoder(const io::EncoderSample& e) {
    const auto w = conv->add(e);
    if (!w) return;
    if (!(w->t1_s > w->t0_s) || !std::isfinite(w->u_right_m_s) || !std::isfinite(w->u_left_m_s))
      return;
    if (w->t0_s < enc_last_t1) return;
    enc.push_back({w->tMid(), w->t0_s, w->t1_s, w->u_right_m_s, w->u_left_m_s, {}});
    enc_last_t1 = w->t1_s;
    if (enc_count++ == 0) enc_first_t = w->tMid();
  }
  // sanitize(): non-finite time skipped, a time not after the last kept skipped, then
  // non-finite values skipped; the file order must be time order.
  template <typename F>
  bool keep(double t, double& last, F finite) {
    if (!std::isfinite(t)) return false;
    if (!std::isnan(last) && !(t > last)) {
      if (t < last)
        throw std::invalid_argument(
            "identify (streamed): a stream goes back in time; the file is not in time order");
      return false;
    }
    if (!finite()) return false;
    last = t;
    return true;
  }
  void addMotor(const io::MotorSample& m) {
    if (!keep(m.t_s, mot_last_t, [&] {
          return std::isfinite(m.current_right_A) && std::isfinite(m.current_left_A) &&
                 std::isfinite(m.vrc_right_V) && std::isfinite(m.vrc_left_V);
        }))
      return;
    ++mot.count;
    mot.times.push_back(m.t_s);
    mot_wait.push_back(m);
    if (mot_wait.size() == 2) finaliseMotor(false);
  }
  // The motor voltage U of mot_wait's first sample (its neighbours: mot_prev and the next).
  void finaliseMotor(bool last) {
    const io::MotorSample& k = mot_wait.front();
    const io::MotorSample& a = mot_prev ? *mot_prev : k;
    const io::MotorSample& b = last ? k : mot_wait[1];
    const double vrc[2] = {k.vrc_right_V, k.vrc_left_V};
    const double va[2] = {a.vrc_right_V, a.vrc_left_V}, vb[2] = {b.vrc_right_V, b.vrc_left_V};
    std::array<double, 4> x{k.current_right_A, k.current_left_A, 0, 0};
    for (int side = 0; side < 2; ++side) {
      const double rate = (vb[side] - va[side]) / (b.t_s - a.t_s);
      x[2 + side] = sensors::motorVoltageFromVrc(vrc[side], rate, cfg.motors.circuit);
      any_voltage = any_voltage || vrc[side] != 0.0;
    }
    mot.finalise(k.t_s, x);
    mot_prev = k;
    mot_wait.pop_front();
  }
  void addImu(const io::ImuSample& s) {
    if (!o.gyro_omega) return;
    if (!keep(s.t_s, imu_last_t, [&] { return std::isfinite(s.gyro_z_rad_s); })) return;
    ++imu.count;
    imu.times.push_back(s.t_s);
    imu.finalise(s.t_s, {s.gyro_z_rad_s, 0, 0, 0});
  }

  // --- interval means ----------------------------------------------------------------------
  void computeMeans() {
    while (enc_done < enc.size()) {
      EncInterval& e = enc[enc_done];
      if (!mot.ready(e.t1) || (o.gyro_omega && !imu.ready(e.t1))) return;
      for (int c = 0; c < 4; ++c)
        e.mean[c] = (mot.integral(c, e.t1) - mot.integral(c, e.t0)) / (e.t1 - e.t0);
      if (o.gyro_omega) e.mean[4] = (imu.integral(0, e.t1) - imu.integral(0, e.t0)) / (e.t1 - e.t0);
      mot.dropBefore(e.t1);
      imu.dropBefore(e.t1);
      ++enc_done;
    }
  }

  // --- grid --------------------------------------------------------------------------------
  // resampleLinear of the encoder midpoints' values at t (the bracket is held).
  double resampleEnc(double t, const std::function<double(const EncInterval&)>& val) const {
    if (t >= enc.back().t) return val(enc.back());
    const auto it = std::upper_bound(enc.begin(), enc.end(), t,
                                     [](double v, const EncInterval& q) { return v < q.t; });
    const EncInterval &lo = *(it - 1), &hi = *it;
    const double w = (t - lo.t) / (hi.t - lo.t);
    return val(lo) + w * (val(hi) - val(lo));
  }
  bool gridPointReady(double t) const {
    if (enc_ended && mot.ended && (!o.gyro_omega || imu.ended)) return true;
    const double t_next = t + dt;  // margin: the grid's end is decided at endRecording
    const bool enc_ok = enc_done > 0 && enc[enc_done - 1].t > t_next;
    const bool mot_ok = !mot.times.empty() && mot.times.back() > t_next;
    const bool imu_ok = !o.gyro_omega || (!imu.times.empty() && imu.times.back() > t_next);
    return enc_ok && mot_ok && imu_ok;
  }
  void advanceGrid(long n_grid) {
    if (std::isnan(t_lo)) {
      if (enc.empty() || !mot.front || (o.gyro_omega && !imu.front)) return;
      t_lo = std::max(enc_first_t, mot.times.front());
      if (o.gyro_omega) t_lo = std::max(t_lo, imu.times.front());
    }
    for (; kg < n_grid; ++kg) {
      const double t = t_lo + kg * dt;
      if (!gridPointReady(t)) return;
      const bool ok = coveredIn(enc, t, o.max_gap_s) && coveredIn(mot.times, t, o.max_gap_s) &&
                      (!o.gyro_omega || coveredIn(imu.times, t, o.max_gap_s));
      if (ok) {
        std::array<double, 7> x{};
        x[0] = resampleEnc(t, [](const EncInterval& e) { return e.u_r; });
        x[1] = resampleEnc(t, [](const EncInterval& e) { return e.u_l; });
        for (int c = 0; c < 4; ++c)
          x[2 + c] = resampleEnc(t, [c](const EncInterval& e) { return e.mean[c]; });
        if (o.gyro_omega) x[6] = resampleEnc(t, [](const EncInterval& e) { return e.mean[4]; });
        addToRun(x.data());
      } else {
        closeRun();
      }
      // what the next grid point no longer needs
      while (enc.size() >= 2 && enc[1].t <= t && enc_done >= 2) enc.pop_front(), --enc_done;
      while (mot.times.size() >= 2 && mot.times[1] <= t) mot.times.pop_front();
      while (imu.times.size() >= 2 && imu.times[1] <= t) imu.times.pop_front();
    }
  }

  // --- runs and rows -----------------------------------------------------------------------
  void addToRun(const double* x) {
    if (!run) {
      run_k0 = kg;
      run_len = 0;
      run_segment = -1;
      rows_made = 0;
      have1 = have2 = false;
      run = std::make_unique<StreamingFiltfilt>(
          channels(), o.cutoff_hz, o.rate_hz, std::max(trim + 2, min_len + 1),
          [this](long j, const double* raw, const double* y) { filtered(j, raw, y); });
    }
    ++run_len;
    run->push(x);
  }
  void closeRun() {
    if (!run) return;
    if (run_len >= min_len) {
      run_closing = true;
      run->finish();
      flushRows();
      run_closing = false;
    }
    run.reset();
  }
  // Sample j filtered: row j - 1 is made (its neighbours are known).
  void filtered(long, const double* raw, const double* y) {
    if (run_segment < 0) run_segment = n_segments++;
    Filtered f;
    std::copy(raw, raw + channels(), f.raw.begin());
    std::copy(y, y + channels(), f.y.begin());
    if (have1) makeRow(have2 ? p2 : p1, p1, f);
    p2 = p1;
    have2 = have1;
    p1 = f;
    have1 = true;
  }
  // The run's last row (one-sided difference).
  void flushRows() {
    if (have1) makeRow(have2 ? p2 : p1, p1, p1);
    have1 = have2 = false;
  }
  double vOf(const Filtered& f) const { return 0.5 * (f.y[0] + f.y[1]); }
  double wOf(const Filtered& f) const { return o.gyro_omega ? f.y[6] : (f.y[0] - f.y[1]) / lw; }
  // Row `rows_made` from its filtered sample `c` and neighbours `a` (before), `b` (after).
  void makeRow(const Filtered& a, const Filtered& c, const Filtered& b) {
    const long k = rows_made;
    const long n = run_len;
    IntervalRow r;
    r.recording = rec;
    r.segment = run_segment;
    r.k = k;
    r.t = t_lo + (run_k0 + k) * dt;
    r.u_r = c.y[0];
    r.u_l = c.y[1];
    r.i_r = c.y[2];
    r.i_l = c.y[3];
    r.U_r = c.y[4];
    r.U_l = c.y[5];
    r.v = vOf(c);
    r.omega = wOf(c);
    const bool first = k == 0, last = k == n - 1;
    if (first) {
      r.vdot = (vOf(b) - vOf(c)) / dt;
      r.omegadot = (wOf(b) - wOf(c)) / dt;
    } else if (last) {
      r.vdot = (vOf(c) - vOf(a)) / dt;
      r.omegadot = (wOf(c) - wOf(a)) / dt;
    } else {
      r.vdot = (vOf(b) - vOf(a)) / (2 * dt);
      r.omegadot = (wOf(b) - wOf(a)) / (2 * dt);
    }
    r.interior = k >= trim && (!run_closing || k < n - trim);
    r.moving = std::max(std::abs(r.u_r), std::abs(r.u_l)) >= o.standstill_speed_m_s;
    if (r.interior) {
      const double v_raw = 0.5 * (c.raw[0] + c.raw[1]);
      const double w_raw = o.gyro_omega ? c.raw[6] : (c.raw[0] - c.raw[1]) / lw;
      ss_v += std::pow(v_raw - r.v, 2);
      ss_w += std::pow(w_raw - r.omega, 2);
      ++n_noise;
    }
    ++rows_made;
    sink(r);
  }

  void end() {
    enc_ended = true;
    while (!mot_wait.empty()) finaliseMotor(mot_wait.size() == 1);
    mot.ended = imu.ended = true;
    const bool usable = enc_count >= 4 && mot.count >= 4 && (!o.gyro_omega || imu.count >= 4);
    if (!usable) {
      if (run) run.reset();
      return;
    }
    computeMeans();
    double t_hi = std::min(enc.back().t, mot.times.back());
    if (std::isnan(t_lo)) advanceGrid(0);
    if (o.gyro_omega) t_hi = std::min(t_hi, imu.times.back());
    if (!(t_hi > t_lo)) return;
    has_voltage = has_voltage || any_voltage;
    advanceGrid(static_cast<long>(std::floor((t_hi - t_lo) / dt)) + 1);
    closeRun();
  }
};

IntervalConditioner::IntervalConditioner(const config::WheelchairConfig& cfg,
                                         const IntervalSignalOptions& o, RowSink sink)
    : impl_(std::make_unique<Impl>(cfg, o, std::move(sink))) {}

IntervalConditioner::~IntervalConditioner() = default;

void IntervalConditioner::beginRecording(int index) {
  impl_->begin(index);
}

void IntervalConditioner::add(const io::AnySample& s) {
  auto& m = *impl_;
  if (const auto* e = std::get_if<io::EncoderSample>(&s))
    m.addEncoder(*e);
  else if (const auto* mo = std::get_if<io::MotorSample>(&s))
    m.addMotor(*mo);
  else if (const auto* i = std::get_if<io::ImuSample>(&s))
    m.addImu(*i);
  else
    return;
  m.computeMeans();
  m.advanceGrid(std::numeric_limits<long>::max());
}

void IntervalConditioner::endRecording() {
  impl_->end();
}

IntervalSignals IntervalConditioner::finish() {
  const auto& m = *impl_;
  IntervalSignals out;
  out.has_voltage = m.has_voltage;
  noiseFloors(m.ss_v, m.ss_w, m.n_noise, m.o, out);
  return out;
}

}  // namespace wheelchair::signals
