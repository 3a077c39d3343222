// Filtering utilities: zero-phase Butterworth, linear resampling, uneven derivative.
#include "libwheelchair/sensors/Filtering.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstring>
#include <stdexcept>
#include <vector>

using namespace wheelchair::sensors;

namespace {
constexpr double kPi = 3.141592653589793238462643383279;

double magnitude(const Biquad& f, double freq_hz, double fs) {
  const std::complex<double> z1 = std::polar(1.0, -2 * kPi * freq_hz / fs);  // z^-1
  const std::complex<double> h =
      (f.b0 + f.b1 * z1 + f.b2 * z1 * z1) / (1.0 + f.a1 * z1 + f.a2 * z1 * z1);
  return std::abs(h);
}

// Least-squares amplitude and phase of a sinusoid at freq over samples [k0, k1).
void fitSine(const std::vector<double>& t, const std::vector<double>& y, double freq,
             std::size_t k0, std::size_t k1, double* amp, double* phase) {
  double ss = 0, sc = 0, cc = 0, ys = 0, yc = 0;
  for (std::size_t k = k0; k < k1; ++k) {
    const double s = std::sin(2 * kPi * freq * t[k]), c = std::cos(2 * kPi * freq * t[k]);
    ss += s * s, sc += s * c, cc += c * c, ys += y[k] * s, yc += y[k] * c;
  }
  const double det = ss * cc - sc * sc;
  const double a = (ys * cc - yc * sc) / det, b = (yc * ss - ys * sc) / det;  // a sin + b cos
  *amp = std::hypot(a, b);
  *phase = std::atan2(b, a);
}

std::vector<double> sineSeries(double freq, double fs, int n, std::vector<double>* t) {
  std::vector<double> x(n);
  t->resize(n);
  for (int k = 0; k < n; ++k) {
    (*t)[k] = k / fs;
    x[k] = std::sin(2 * kPi * freq * (*t)[k]);
  }
  return x;
}
}  // namespace

TEST(Filtering, Butter2DesignCutoffConvention) {
  const double fs = 100.0;
  for (double fc : {1.0, 5.0, 20.0, 45.0}) {
    const Biquad f = butter2Lowpass(fc, fs);
    EXPECT_NEAR(f.dcGain(), 1.0, 1e-12);
    EXPECT_NEAR(magnitude(f, fc, fs), 1.0 / std::sqrt(2.0), 1e-9) << fc;  // -3 dB per pass
    EXPECT_LT(magnitude(f, 0.999 * fs / 2, fs), 1e-3);                    // zero at Nyquist
  }
  // scipy.signal.butter(2, 10, fs=100): b = [0.06745527, 0.13491055, 0.06745527],
  // a = [1, -1.1429805, 0.4128016].
  const Biquad f = butter2Lowpass(10.0, 100.0);
  EXPECT_NEAR(f.b0, 0.06745527, 1e-8);
  EXPECT_NEAR(f.b1, 0.13491055, 1e-8);
  EXPECT_NEAR(f.a1, -1.1429805, 1e-7);
  EXPECT_NEAR(f.a2, 0.4128016, 1e-7);
  EXPECT_THROW(butter2Lowpass(0.0, 100.0), std::invalid_argument);
  EXPECT_THROW(butter2Lowpass(50.0, 100.0), std::invalid_argument);
  EXPECT_THROW(filtfiltButter2(std::vector<double>(10, 1.0), 60.0, 100.0), std::invalid_argument);
}

TEST(Filtering, FiltfiltZeroPhaseBelowCutoff) {
  const double fs = 100.0, fc = 10.0, f0 = 2.0;
  std::vector<double> t;
  const std::vector<double> x = sineSeries(f0, fs, 500, &t);
  const std::vector<double> y = filtfiltButter2(x, fc, fs);
  ASSERT_EQ(y.size(), x.size());
  double amp = 0, ph = 0;
  fitSine(t, y, f0, 50, 450, &amp, &ph);
  const double expected = std::pow(magnitude(butter2Lowpass(fc, fs), f0, fs), 2);
  EXPECT_NEAR(amp, expected, 1e-4);
  EXPECT_NEAR(ph, 0.0, 1e-4);  // zero phase
  // Peaks stay where they were: x peaks at t = 0.125 + k * 0.5 s (sample 12.5 + 50 k).
  for (int k = 2; k < 8; ++k) {
    const std::size_t i0 = std::size_t(50 * k + 12);  // samples 12 and 13 straddle the peak
    EXPECT_NEAR(y[i0], y[i0 + 1], 1e-4) << k;         // symmetric about the true peak
    EXPECT_GT(y[i0], y[i0 - 1]);
    EXPECT_GT(y[i0 + 1], y[i0 + 2]);
  }
  // The one-pass causal filter, by contrast, lags.
  const std::vector<double> yc = biquadFilter(butter2Lowpass(fc, fs), x);
  double amp_c = 0, ph_c = 0;
  fitSine(t, yc, f0, 50, 450, &amp_c, &ph_c);
  EXPECT_LT(ph_c, -0.2);
  // Edges: no start-up transient to speak of on a smooth signal.
  for (std::size_t k = 0; k < x.size(); ++k) EXPECT_NEAR(y[k], expected * x[k], 0.03) << k;
}

TEST(Filtering, FiltfiltAttenuatesAboveCutoff) {
  const double fs = 100.0, fc = 5.0;
  std::vector<double> t;
  const std::vector<double> hi = sineSeries(30.0, fs, 600, &t);
  const std::vector<double> lo = sineSeries(1.0, fs, 600, &t);
  std::vector<double> x(hi.size());
  for (std::size_t k = 0; k < x.size(); ++k) x[k] = lo[k] + hi[k];
  const std::vector<double> y = filtfiltButter2(x, fc, fs);
  double amp_hi = 0, ph = 0, amp_lo = 0;
  fitSine(t, y, 30.0, 50, 550, &amp_hi, &ph);
  fitSine(t, y, 1.0, 50, 550, &amp_lo, &ph);
  const double g30 = std::pow(magnitude(butter2Lowpass(fc, fs), 30.0, fs), 2);
  EXPECT_LT(g30, 5e-3);
  EXPECT_NEAR(amp_hi, g30, 1e-3);
  EXPECT_LT(amp_hi, 0.01);
  EXPECT_NEAR(amp_lo, 1.0, 2e-3);
  // At the cut-off the zero-phase result has gain 1/2 (-6 dB).
  const std::vector<double> xc = sineSeries(fc, fs, 600, &t);
  double amp_c = 0;
  fitSine(t, filtfiltButter2(xc, fc, fs), fc, 50, 550, &amp_c, &ph);
  EXPECT_NEAR(amp_c, 0.5, 2e-3);
}

TEST(Filtering, FiltfiltEdgesAndShortInputs) {
  const std::vector<double> c(50, 3.7);
  for (double v : filtfiltButter2(c, 5.0, 100.0)) EXPECT_NEAR(v, 3.7, 1e-12);
  // A ramp is preserved by the zero-phase filter, up to the ends thanks to the odd reflection
  // and the long padding.
  std::vector<double> ramp(200);
  for (std::size_t k = 0; k < ramp.size(); ++k) ramp[k] = 0.5 * k - 7.0;
  const std::vector<double> yr = filtfiltButter2(ramp, 5.0, 100.0);
  for (std::size_t k = 0; k < ramp.size(); ++k) {
    EXPECT_NEAR(yr[k], ramp[k], (k < 40 || k > 160) ? 1e-4 : 1e-6) << k;
  }
  // With scipy's 9-sample padding the ends would be off by ~0.2 samples of slope.
  EXPECT_EQ(filtfiltPadLength(200, 5.0, 100.0), 60u);
  EXPECT_EQ(filtfiltPadLength(200, 40.0, 100.0), 9u);
  EXPECT_EQ(filtfiltPadLength(5, 5.0, 100.0), 4u);
  EXPECT_TRUE(filtfiltButter2(std::vector<double>{}, 5.0, 100.0).empty());
  EXPECT_EQ(filtfiltButter2(std::vector<double>{2.0}, 5.0, 100.0), std::vector<double>{2.0});
  const std::vector<double> y3 = filtfiltButter2(std::vector<double>{1.0, 1.0, 1.0}, 5.0, 100.0);
  ASSERT_EQ(y3.size(), 3u);
  for (double v : y3) EXPECT_NEAR(v, 1.0, 1e-12);
}

TEST(Filtering, FiltfiltUnevenTimeBase) {
  const double f0 = 1.5, fc = 8.0;
  std::vector<double> t, x;
  double tk = 0;
  for (int k = 0; k < 600; ++k) {
    t.push_back(tk);
    x.push_back(std::sin(2 * kPi * f0 * tk) + 0.3 * std::sin(2 * kPi * 35.0 * tk));
    tk += 0.01 * (1.0 + 0.3 * std::sin(1.3 * k));  // 100 Hz +- 30 % jitter
  }
  const std::vector<double> y = filtfiltButter2(t, x, fc);
  ASSERT_EQ(y.size(), x.size());
  double amp = 0, ph = 0;
  fitSine(t, y, f0, 60, 540, &amp, &ph);
  EXPECT_NEAR(amp, 1.0, 0.02);
  EXPECT_NEAR(ph, 0.0, 0.01);
  for (std::size_t k = 60; k < 540; ++k) EXPECT_NEAR(y[k], std::sin(2 * kPi * f0 * t[k]), 0.06);
  // Cut-off above the grid's Nyquist: unchanged.
  EXPECT_EQ(filtfiltButter2(t, x, 80.0), x);
  EXPECT_THROW(filtfiltButter2(std::vector<double>{0, 1, 1}, x, 1.0), std::invalid_argument);
}

TEST(Filtering, ResampleLinear) {
  const std::vector<double> ts = {0.0, 0.1, 0.25, 0.25, 0.7};
  const std::vector<double> xs = {1.0, 2.0, 3.5, 10.0, 14.5};
  const std::vector<double> y = resampleLinear(ts, xs, {-1.0, 0.0, 0.05, 0.2, 0.25, 0.4, 0.7, 2.0});
  ASSERT_EQ(y.size(), 8u);
  EXPECT_DOUBLE_EQ(y[0], 1.0);  // held before the start
  EXPECT_DOUBLE_EQ(y[1], 1.0);
  EXPECT_NEAR(y[2], 1.5, 1e-12);
  EXPECT_NEAR(y[3], 3.0, 1e-12);
  EXPECT_DOUBLE_EQ(y[4], 10.0);  // duplicate time: the later sample wins
  EXPECT_NEAR(y[5], 10.0 + 4.5 * (0.15 / 0.45), 1e-12);
  EXPECT_DOUBLE_EQ(y[6], 14.5);
  EXPECT_DOUBLE_EQ(y[7], 14.5);  // held after the end
  EXPECT_EQ(resampleLinear({1.0}, {4.0}, {0.0, 5.0}), (std::vector<double>{4.0, 4.0}));
  EXPECT_THROW(resampleLinear({}, {}, {1.0}), std::invalid_argument);
  EXPECT_THROW(resampleLinear({0.0, 1.0}, {1.0}, {1.0}), std::invalid_argument);
}

TEST(Filtering, CentralDerivativeUneven) {
  std::vector<double> t, x;
  double tk = 0.3;
  for (int k = 0; k < 30; ++k) {
    t.push_back(tk);
    x.push_back(2.0 - 1.5 * tk + 0.8 * tk * tk);  // quadratic: exact everywhere
    tk += 0.01 + 0.02 * std::abs(std::sin(2.1 * k));
  }
  const std::vector<double> d = centralDerivative(t, x);
  for (std::size_t k = 0; k < t.size(); ++k) EXPECT_NEAR(d[k], -1.5 + 1.6 * t[k], 1e-9) << k;
  // A cubic is not exact but second-order accurate.
  std::vector<double> tc, xc;
  for (int k = 0; k < 200; ++k) {
    tc.push_back(k * 0.01 + 0.003 * std::sin(k));
    xc.push_back(std::sin(tc.back()));
  }
  const std::vector<double> dc = centralDerivative(tc, xc);
  for (std::size_t k = 0; k < tc.size(); ++k) EXPECT_NEAR(dc[k], std::cos(tc[k]), 1e-4) << k;
  EXPECT_EQ(centralDerivative({0.0, 0.5}, {1.0, 2.0}), (std::vector<double>{2.0, 2.0}));
  EXPECT_EQ(centralDerivative({1.0}, {1.0}), std::vector<double>{0.0});
  EXPECT_THROW(centralDerivative({0.0, 0.0, 1.0}, {1.0, 2.0, 3.0}), std::invalid_argument);
  EXPECT_THROW(centralDerivative({0.0, 1.0}, {1.0}), std::invalid_argument);
  EXPECT_NEAR(medianSpacing({0.0, 0.1, 0.3, 0.4}), 0.1, 1e-12);
  EXPECT_NEAR(medianSpacing({0.0, 0.1, 0.3, 0.4, 0.8}), 0.15, 1e-12);
}

// filtfiltButter2 filters in one buffer (memory, docs/benchmarks.md "Tenth round"): bit for
// bit the padded series run through biquadFilter forwards and backwards (as it was computed
// with a new vector per pass), on a noisy current-like series.
TEST(Filtering, FiltfiltInOneBufferEqualsTwoBiquadPasses) {
  const double fs = 50.0, fc = 2.5;
  std::vector<double> x(20000);
  unsigned state = 12345u;
  for (std::size_t i = 0; i < x.size(); ++i) {
    state = state * 1103515245u + 12345u;
    const double noise = (double((state >> 8) & 0xffff) / 65535.0 - 0.5) * 0.2;
    x[i] = 2.0 * std::sin(0.01 * double(i)) + (i % 700 < 350 ? 0.8 : -0.3) + noise;
  }
  const std::size_t n = x.size(), pad = filtfiltPadLength(n, fc, fs);
  std::vector<double> ext;
  for (std::size_t k = pad; k >= 1; --k) ext.push_back(2.0 * x[0] - x[k]);
  ext.insert(ext.end(), x.begin(), x.end());
  for (std::size_t k = 1; k <= pad; ++k) ext.push_back(2.0 * x[n - 1] - x[n - 1 - k]);
  const Biquad f = butter2Lowpass(fc, fs);
  std::vector<double> y = biquadFilter(f, ext, true);
  std::reverse(y.begin(), y.end());
  y = biquadFilter(f, y, true);
  std::reverse(y.begin(), y.end());
  const std::vector<double> want(y.begin() + pad, y.begin() + pad + n);
  const std::vector<double> got = filtfiltButter2(x, fc, fs);
  ASSERT_EQ(got.size(), n);
  EXPECT_EQ(std::memcmp(got.data(), want.data(), n * sizeof(double)), 0);
}
