#include "libwheelchair/sensors/Filtering.h"

#include "libwheelchair/stats/Descriptive.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace wheelchair::sensors {

namespace {
constexpr double kPi = 3.141592653589793238462643383279;
}  // namespace

double Biquad::dcGain() const {
  return (b0 + b1 + b2) / (1.0 + a1 + a2);
}

Biquad butter2Lowpass(double cutoff_hz, double sample_rate_hz) {
  if (!(sample_rate_hz > 0) || !(cutoff_hz > 0) || !(cutoff_hz < 0.5 * sample_rate_hz))
    throw std::invalid_argument("butter2Lowpass: need 0 < cutoff < sample_rate / 2");
  const double k = std::tan(kPi * cutoff_hz / sample_rate_hz);  // pre-warped analog cut-off
  const double k2 = k * k;
  const double s2 = std::sqrt(2.0);
  const double norm = 1.0 / (1.0 + s2 * k + k2);
  Biquad f;
  f.b0 = k2 * norm;
  f.b1 = 2.0 * f.b0;
  f.b2 = f.b0;
  f.a1 = 2.0 * (k2 - 1.0) * norm;
  f.a2 = (1.0 - s2 * k + k2) * norm;
  return f;
}

namespace {

/// biquadFilter from x into y (y may be x: sample i is read before it is written).
void biquadInto(const Biquad& f, const std::vector<double>& x, bool steady_start,
                std::vector<double>& y) {
  if (x.empty()) return;
  double z1 = 0, z2 = 0;
  if (steady_start) {
    // Steady state for constant input x0 (output g x0): z2 = (b2 - a2 g) x0, z1 = (g - b0) x0.
    const double g = f.dcGain();
    z1 = (g - f.b0) * x[0];
    z2 = (f.b2 - f.a2 * g) * x[0];
  }
  for (std::size_t i = 0; i < x.size(); ++i) {
    const double xi = x[i];
    const double yi = f.b0 * xi + z1;
    z1 = f.b1 * xi - f.a1 * yi + z2;
    z2 = f.b2 * xi - f.a2 * yi;
    y[i] = yi;
  }
}

/// biquadFilter(f, x, true) written over x.
void biquadFilterInPlace(const Biquad& f, std::vector<double>& x) {
  biquadInto(f, x, true, x);
}

}  // namespace

std::vector<double> biquadFilter(const Biquad& f, const std::vector<double>& x, bool steady_start) {
  std::vector<double> y(x.size());
  biquadInto(f, x, steady_start, y);
  return y;
}

std::size_t filtfiltPadLength(std::size_t n, double cutoff_hz, double sample_rate_hz) {
  if (n < 2) return 0;
  const double periods = std::ceil(3.0 * sample_rate_hz / cutoff_hz);
  const std::size_t want = std::max<std::size_t>(9, static_cast<std::size_t>(periods));
  return std::min(want, n - 1);
}

std::vector<double> filtfiltButter2(const std::vector<double>& x, double cutoff_hz,
                                    double sample_rate_hz) {
  const Biquad f = butter2Lowpass(cutoff_hz, sample_rate_hz);  // validates the arguments
  const std::size_t n = x.size();
  if (n < 2) return x;
  const std::size_t pad = filtfiltPadLength(n, cutoff_hz, sample_rate_hz);
  std::vector<double> ext;
  ext.reserve(n + 2 * pad);
  for (std::size_t k = pad; k >= 1; --k) ext.push_back(2.0 * x[0] - x[k]);
  ext.insert(ext.end(), x.begin(), x.end());
  for (std::size_t k = 1; k <= pad; ++k) ext.push_back(2.0 * x[n - 1] - x[n - 1 - k]);

  // Both passes in place in the one buffer, the result its middle (memory: one series and its
  // padding, not three; the same operations as biquadFilter's).
  biquadFilterInPlace(f, ext);
  std::reverse(ext.begin(), ext.end());
  biquadFilterInPlace(f, ext);
  std::reverse(ext.begin(), ext.end());
  ext.erase(ext.begin(), ext.begin() + static_cast<std::ptrdiff_t>(pad));
  ext.resize(n);
  return ext;
}

double medianSpacing(const std::vector<double>& t_s) {
  std::vector<double> d;
  d.reserve(t_s.size());
  for (std::size_t i = 1; i < t_s.size(); ++i)
    if (t_s[i] - t_s[i - 1] > 0) d.push_back(t_s[i] - t_s[i - 1]);
  return d.empty() ? 0.0 : stats::median(std::move(d));
}

std::vector<double> filtfiltButter2(const std::vector<double>& t_s, const std::vector<double>& x,
                                    double cutoff_hz) {
  if (t_s.size() != x.size()) throw std::invalid_argument("filtfiltButter2: size mismatch");
  if (x.size() < 2) return x;
  for (std::size_t i = 1; i < t_s.size(); ++i)
    if (!(t_s[i] > t_s[i - 1]))
      throw std::invalid_argument("filtfiltButter2: time base not strictly increasing");
  if (!(cutoff_hz > 0)) throw std::invalid_argument("filtfiltButter2: cutoff <= 0");
  const double dt = medianSpacing(t_s);
  const double fs = 1.0 / dt;
  if (cutoff_hz >= 0.5 * fs) return x;
  const double span = t_s.back() - t_s.front();
  const std::size_t m = static_cast<std::size_t>(std::floor(span / dt + 1e-9)) + 1;
  std::vector<double> grid(m);
  for (std::size_t k = 0; k < m; ++k) grid[k] = t_s.front() + double(k) * dt;
  const std::vector<double> xg = filtfiltButter2(resampleLinear(t_s, x, grid), cutoff_hz, fs);
  // The grid may stop just short of t_s.back(): extend it by the last filtered value's time.
  if (grid.back() < t_s.back()) {
    grid.push_back(t_s.back());
    std::vector<double> xg2 = xg;
    xg2.push_back(xg.back());
    return resampleLinear(grid, xg2, t_s);
  }
  return resampleLinear(grid, xg, t_s);
}

std::vector<double> resampleLinear(const std::vector<double>& t_src,
                                   const std::vector<double>& x_src,
                                   const std::vector<double>& t_dst) {
  if (t_src.size() != x_src.size()) throw std::invalid_argument("resampleLinear: size mismatch");
  if (t_src.empty()) throw std::invalid_argument("resampleLinear: empty source");
  std::vector<double> out(t_dst.size());
  const std::size_t n = t_src.size();
  for (std::size_t j = 0; j < t_dst.size(); ++j) {
    const double t = t_dst[j];
    if (!(t >= t_src.front())) {  // before the start (or NaN): hold the first value
      out[j] = x_src[0];
      continue;
    }
    if (t >= t_src.back()) {
      out[j] = x_src[n - 1];
      continue;
    }
    // First index with t_src[hi] > t; then t_src[hi - 1] <= t < t_src[hi].
    const std::size_t hi = std::upper_bound(t_src.begin(), t_src.end(), t) - t_src.begin();
    const std::size_t lo = hi - 1;
    const double h = t_src[hi] - t_src[lo];
    const double w = (t - t_src[lo]) / h;  // h > 0 by construction of upper_bound
    out[j] = x_src[lo] + w * (x_src[hi] - x_src[lo]);
  }
  return out;
}

std::vector<double> centralDerivative(const std::vector<double>& t_s,
                                      const std::vector<double>& x) {
  if (t_s.size() != x.size()) throw std::invalid_argument("centralDerivative: size mismatch");
  const std::size_t n = x.size();
  for (std::size_t i = 1; i < n; ++i)
    if (!(t_s[i] > t_s[i - 1]))
      throw std::invalid_argument("centralDerivative: time base not strictly increasing");
  std::vector<double> d(n, 0.0);
  if (n < 2) return d;
  if (n == 2) {
    d[0] = d[1] = (x[1] - x[0]) / (t_s[1] - t_s[0]);
    return d;
  }
  for (std::size_t i = 1; i + 1 < n; ++i) {
    const double hm = t_s[i] - t_s[i - 1], hp = t_s[i + 1] - t_s[i];
    d[i] = (hm * hm * x[i + 1] - hp * hp * x[i - 1] + (hp * hp - hm * hm) * x[i]) /
           (hm * hp * (hm + hp));
  }
  // One-sided three-point formulas (exact for quadratics), from the Lagrange polynomial
  // through (t0, t1, t2) differentiated at t0, and through (t_{n-3}, t_{n-2}, t_{n-1}) at t_{n-1}.
  {
    const double h1 = t_s[1] - t_s[0], h2 = t_s[2] - t_s[1];
    d[0] = -(2 * h1 + h2) / (h1 * (h1 + h2)) * x[0] + (h1 + h2) / (h1 * h2) * x[1] -
           h1 / (h2 * (h1 + h2)) * x[2];
  }
  {
    const double h1 = t_s[n - 2] - t_s[n - 3], h2 = t_s[n - 1] - t_s[n - 2];
    d[n - 1] = h2 / (h1 * (h1 + h2)) * x[n - 3] - (h1 + h2) / (h1 * h2) * x[n - 2] +
               (h1 + 2 * h2) / (h2 * (h1 + h2)) * x[n - 1];
  }
  return d;
}

}  // namespace wheelchair::sensors
