#include "libwheelchair/signals/IntervalSignals.h"

#include "libwheelchair/sensors/Encoders.h"
#include "libwheelchair/sensors/Filtering.h"
#include "libwheelchair/sensors/VoltageCircuit.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>

namespace wheelchair::signals {

namespace {
struct Stream {
  std::vector<double> t;
  std::vector<std::vector<double>> x;
};

struct EncoderStream {
  std::vector<double> t, t0, t1;  // midpoints and interval bounds
  std::vector<double> u_r, u_l;
};

std::vector<double> filt(const std::vector<double>& x, const IntervalSignalOptions& o) {
  return sensors::filtfiltButter2(x, o.cutoff_hz, o.rate_hz);
}

std::vector<double> resample(const std::vector<double>& ts, const std::vector<double>& xs,
                             const std::vector<double>& tg) {
  return sensors::resampleLinear(ts, xs, tg);
}

// Encoder intervals -> mean rim speeds at the interval midpoints (time-ordered, positive
// and non-overlapping intervals only).
EncoderStream encoderStream(const io::Recording& rec, const config::WheelchairConfig& cfg) {
  const auto& g = cfg.vehicle.geom;
  auto iv = sensors::wheelSpeedsFromTicks(rec.encoders, cfg.encoders.params, g.wheel_radius_m,
                                          g.track_width_m);
  std::stable_sort(iv.begin(), iv.end(),
                   [](const auto& a, const auto& b) { return a.t0_s < b.t0_s; });
  EncoderStream s;
  for (const auto& w : iv) {
    if (!(w.t1_s > w.t0_s) || !std::isfinite(w.u_right_m_s) || !std::isfinite(w.u_left_m_s))
      continue;
    if (!s.t1.empty() && w.t0_s < s.t1.back()) continue;
    s.t.push_back(w.tMid());
    s.t0.push_back(w.t0_s);
    s.t1.push_back(w.t1_s);
    s.u_r.push_back(w.u_right_m_s);
    s.u_l.push_back(w.u_left_m_s);
  }
  return s;
}

// Means of a sampled signal (piecewise linear between its samples, held constant outside)
// over the encoder intervals [t0, t1], placed at the interval midpoints: the speeds are
// interval means, so the other signals go through the same box filter (section 2 of
// docs/identification.md: both sides of (2) must see the same filter).
std::vector<double> intervalMeans(const std::vector<double>& ts, const std::vector<double>& xs,
                                  const std::vector<double>& t0, const std::vector<double>& t1) {
  const std::size_t n = ts.size();
  std::vector<double> F(n, 0.0);  // integral from ts[0]
  for (std::size_t j = 1; j < n; ++j)
    F[j] = F[j - 1] + 0.5 * (xs[j] + xs[j - 1]) * (ts[j] - ts[j - 1]);
  auto integral = [&](double t) {
    if (t <= ts.front()) return xs.front() * (t - ts.front());
    if (t >= ts.back()) return F[n - 1] + xs.back() * (t - ts.back());
    const std::size_t j = std::upper_bound(ts.begin(), ts.end(), t) - ts.begin() - 1;
    const double h = t - ts[j], slope = (xs[j + 1] - xs[j]) / (ts[j + 1] - ts[j]);
    return F[j] + xs[j] * h + 0.5 * slope * h * h;
  };
  std::vector<double> m(t0.size());
  for (std::size_t k = 0; k < t0.size(); ++k)
    m[k] = (integral(t1[k]) - integral(t0[k])) / (t1[k] - t0[k]);
  return m;
}

// Time-sorts a stream and drops duplicated/non-increasing timestamps (raw logs may hold them).
void sanitize(Stream& s) {
  std::vector<std::size_t> idx(s.t.size());
  std::iota(idx.begin(), idx.end(), 0);
  std::stable_sort(idx.begin(), idx.end(), [&](auto a, auto b) { return s.t[a] < s.t[b]; });
  Stream o;
  o.x.resize(s.x.size());
  for (auto k : idx) {
    if (!std::isfinite(s.t[k])) continue;
    if (!o.t.empty() && !(s.t[k] > o.t.back())) continue;
    bool finite = true;
    for (auto& c : s.x) finite = finite && std::isfinite(c[k]);
    if (!finite) continue;
    o.t.push_back(s.t[k]);
    for (std::size_t c = 0; c < s.x.size(); ++c) o.x[c].push_back(s.x[c][k]);
  }
  s = std::move(o);
}

// True when grid time t lies inside the stream's coverage and not inside a gap.
bool covered(const std::vector<double>& ts, double t, double max_gap) {
  auto it = std::upper_bound(ts.begin(), ts.end(), t);
  if (it == ts.begin()) return t == ts.front();
  if (it == ts.end()) return t == ts.back();
  return (*it - *(it - 1)) <= max_gap;
}

std::vector<double> centralDiff(const std::vector<double>& x, double dt) {
  const std::size_t n = x.size();
  std::vector<double> d(n, 0.0);
  if (n < 2) return d;
  for (std::size_t k = 1; k + 1 < n; ++k) d[k] = (x[k + 1] - x[k - 1]) / (2 * dt);
  d[0] = (x[1] - x[0]) / dt;
  d[n - 1] = (x[n - 1] - x[n - 2]) / dt;
  return d;
}

/// One recording's streams for the identification: encoder interval speeds, motor currents
/// and V_RC voltages (with the motor voltage U per side from the V_RC inverse), gyro.
struct RecordingStreams {
  EncoderStream enc;
  Stream mot, imu;
  std::array<std::vector<double>, 2> U;  ///< motor voltage at the motor samples (V)
  bool any_voltage = false;
};

RecordingStreams recordingStreams(const io::Recording& rec, const config::WheelchairConfig& cfg) {
  RecordingStreams r;
  r.enc = encoderStream(rec, cfg);
  Stream& mot = r.mot;
  mot.x.resize(4);
  for (const auto& m : rec.motors) {
    mot.t.push_back(m.t_s);
    mot.x[0].push_back(m.current_right_A);
    mot.x[1].push_back(m.current_left_A);
    mot.x[2].push_back(m.vrc_right_V);
    mot.x[3].push_back(m.vrc_left_V);
  }
  sanitize(mot);
  r.imu.x.resize(1);
  for (const auto& s : rec.imu) {
    r.imu.t.push_back(s.t_s);
    r.imu.x[0].push_back(s.gyro_z_rad_s);
  }
  sanitize(r.imu);
  // Motor voltage U per side from the V_RC inverse, at the motor samples.
  for (int side = 0; side < 2 && mot.t.size() >= 4; ++side) {
    const auto& vrc = mot.x[2 + side];
    r.U[side].resize(vrc.size());
    for (std::size_t k = 0; k < vrc.size(); ++k) {
      const std::size_t a = k == 0 ? 0 : k - 1, b = std::min(k + 1, vrc.size() - 1);
      const double rate = (vrc[b] - vrc[a]) / (mot.t[b] - mot.t[a]);
      // Differential V_RC of one motor -> U = V_w1 - V_w2 (inverse of (11) with the knee).
      r.U[side][k] = sensors::motorVoltageFromVrc(vrc[k], rate, cfg.motors.circuit);
      r.any_voltage = r.any_voltage || vrc[k] != 0.0;
    }
  }
  return r;
}

/// Raw-minus-filtered sums of squares of v and omega (the noise floor estimate).
struct NoiseSums {
  double ss_v = 0, ss_w = 0;
  std::size_t n = 0;
};

/// The grid samples [k0, k1) of one recording as a filtered segment.
IntervalSegment conditionSegment(const RecordingStreams& r, int recording, double t_lo, long k0,
                                 long k1, double lw, const IntervalSignalOptions& o,
                                 NoiseSums& noise) {
  const double dt = 1.0 / o.rate_hz;
  const bool gyro = o.gyro_omega;
  const EncoderStream& enc = r.enc;
  IntervalSegment s;
  s.recording = recording;
  for (long k = k0; k < k1; ++k) s.t.push_back(t_lo + k * dt);
  const auto ur_raw = resample(enc.t, enc.u_r, s.t);
  const auto ul_raw = resample(enc.t, enc.u_l, s.t);
  // Currents, voltages, gyro: interval means over the encoder intervals first.
  auto viaEnc = [&](const Stream& st, const std::vector<double>& x) {
    return resample(enc.t, intervalMeans(st.t, x, enc.t0, enc.t1), s.t);
  };
  s.u_r = filt(ur_raw, o);
  s.u_l = filt(ul_raw, o);
  s.i_r = filt(viaEnc(r.mot, r.mot.x[0]), o);
  s.i_l = filt(viaEnc(r.mot, r.mot.x[1]), o);
  s.U_r = filt(viaEnc(r.mot, r.U[0]), o);
  s.U_l = filt(viaEnc(r.mot, r.U[1]), o);
  const std::size_t n = s.t.size();
  std::vector<double> v_raw(n), w_raw(n);
  s.v.resize(n);
  s.omega.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    v_raw[k] = 0.5 * (ur_raw[k] + ul_raw[k]);
    w_raw[k] = (ur_raw[k] - ul_raw[k]) / lw;
    s.v[k] = 0.5 * (s.u_r[k] + s.u_l[k]);
    s.omega[k] = (s.u_r[k] - s.u_l[k]) / lw;
  }
  if (gyro) {
    w_raw = viaEnc(r.imu, r.imu.x[0]);
    s.omega = filt(w_raw, o);
  }
  s.vdot = centralDiff(s.v, dt);
  s.omegadot = centralDiff(s.omega, dt);
  s.interior.assign(n, 0);
  s.moving.assign(n, 0);
  const long trim = static_cast<long>(std::ceil(o.edge_trim_s / dt));
  for (std::size_t k = 0; k < n; ++k) {
    s.interior[k] = long(k) >= trim && long(k) < long(n) - trim;
    s.moving[k] = std::max(std::abs(s.u_r[k]), std::abs(s.u_l[k])) >= o.standstill_speed_m_s;
    if (s.interior[k]) {
      noise.ss_v += std::pow(v_raw[k] - s.v[k], 2);
      noise.ss_w += std::pow(w_raw[k] - s.omega[k], 2);
      ++noise.n;
    }
  }
  return s;
}

}  // namespace

void noiseFloors(double ss_v, double ss_w, std::size_t n_noise, const IntervalSignalOptions& o,
                 IntervalSignals& out) {
  const double dt = 1.0 / o.rate_hz;
  // Noise floors: raw-minus-filtered rms (the noise above the cut-off) times the noise gain
  // of the filter (and of filter + central difference) for white noise.
  if (n_noise > 0) {
    const long half = static_cast<long>(std::ceil(20 * o.rate_hz / o.cutoff_hz));
    std::vector<double> imp(2 * half + 1, 0.0);
    imp[half] = 1.0;
    const auto h = filt(imp, o);
    const auto hd = centralDiff(h, dt);
    double g0 = 0, gd = 0;
    for (std::size_t k = 0; k < h.size(); ++k) g0 += h[k] * h[k], gd += hd[k] * hd[k];
    g0 = std::sqrt(g0), gd = std::sqrt(gd);
    // raw - filtered keeps the fraction (1 - g0^2) of white noise variance (approximately).
    const double keep = std::max(1e-3, 1.0 - 2 * h[half] + g0 * g0);
    const double sv = std::sqrt(ss_v / n_noise / keep), sw = std::sqrt(ss_w / n_noise / keep);
    out.noise_v = sv * g0;
    out.noise_omega = sw * g0;
    out.noise_vdot = sv * gd;
    out.noise_omegadot = sw * gd;
  }
}

IntervalRow intervalRow(const IntervalSegment& s, int segment, std::size_t k) {
  IntervalRow r;
  r.recording = s.recording;
  r.segment = segment;
  r.k = static_cast<long>(k);
  r.t = s.t[k];
  r.u_r = s.u_r[k];
  r.u_l = s.u_l[k];
  r.v = s.v[k];
  r.omega = s.omega[k];
  r.vdot = s.vdot[k];
  r.omegadot = s.omegadot[k];
  r.i_r = s.i_r[k];
  r.i_l = s.i_l[k];
  r.U_r = s.U_r[k];
  r.U_l = s.U_l[k];
  r.interior = s.interior[k] != 0;
  r.moving = s.moving[k] != 0;
  return r;
}

IntervalSignals prepareIntervalMeans(const std::vector<io::Recording>& recs,
                                     const config::WheelchairConfig& cfg,
                                     const IntervalSignalOptions& o) {
  const double dt = 1.0 / o.rate_hz, lw = cfg.vehicle.geom.track_width_m;
  const bool gyro = o.gyro_omega;
  IntervalSignals out;
  NoiseSums noise;
  for (std::size_t ri = 0; ri < recs.size(); ++ri) {
    const RecordingStreams r = recordingStreams(recs[ri], cfg);
    const EncoderStream& enc = r.enc;
    const Stream &mot = r.mot, &imu = r.imu;
    if (enc.t.size() < 4 || mot.t.size() < 4 || (gyro && imu.t.size() < 4)) continue;
    out.has_voltage = out.has_voltage || r.any_voltage;
    double t_lo = std::max(enc.t.front(), mot.t.front());
    double t_hi = std::min(enc.t.back(), mot.t.back());
    if (gyro) t_lo = std::max(t_lo, imu.t.front()), t_hi = std::min(t_hi, imu.t.back());
    if (!(t_hi > t_lo)) continue;
    const long n_grid = static_cast<long>(std::floor((t_hi - t_lo) / dt)) + 1;
    std::vector<char> ok(n_grid);
    for (long k = 0; k < n_grid; ++k) {
      const double t = t_lo + k * dt;
      ok[k] = covered(enc.t, t, o.max_gap_s) && covered(mot.t, t, o.max_gap_s) &&
              (!gyro || covered(imu.t, t, o.max_gap_s));
    }
    const long min_len = static_cast<long>(std::ceil((2 * o.edge_trim_s + 1.0) / dt));
    for (long k0 = 0; k0 < n_grid;) {
      if (!ok[k0]) {
        ++k0;
        continue;
      }
      long k1 = k0;
      while (k1 < n_grid && ok[k1]) ++k1;
      if (k1 - k0 >= min_len)
        out.segments.push_back(
            conditionSegment(r, static_cast<int>(ri), t_lo, k0, k1, lw, o, noise));
      k0 = k1;
    }
  }
  noiseFloors(noise.ss_v, noise.ss_w, noise.n, o, out);
  return out;
}

}  // namespace wheelchair::signals
