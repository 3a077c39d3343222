// Small signal-processing utilities shared by several modules (docs/sensors.md, "Filtering"):
// a zero-phase 2nd-order Butterworth low-pass (forward-backward, like scipy.signal.filtfilt),
// linear resampling and a central-difference derivative on uneven time bases.
//
// Cut-off convention: `cutoff_hz` is the -3 dB frequency of ONE pass of the 2nd-order
// Butterworth (bilinear transform with frequency pre-warping, so it is exact in the digital
// domain). Forward-backward filtering squares the magnitude response: the zero-phase result is
// -6 dB (gain 0.5) at cutoff_hz and rolls off at -80 dB/decade, with exactly zero phase. This
// is the same convention as scipy.signal.butter(2, fc, fs=fs) + filtfilt. To get a combined
// -3 dB point at f3, pass cutoff_hz = f3 / 0.802 (since |H|^4 = 1/2 <=> (f/fc)^4 = sqrt2 - 1).
//
// Example:
//   auto xs = filtfiltButter2(x, 5.0, 100.0);           // 5 Hz on a 100 Hz uniform series
//   auto y  = resampleLinear(t_imu, gyro, t_enc);        // gyro on the encoder time base
//   auto xd = centralDerivative(t, xs);                  // d x / d t
#pragma once

#include <cstddef>
#include <vector>

namespace wheelchair::sensors {

/// Coefficients of one biquad y = (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2) x.
struct Biquad {
  double b0 = 1, b1 = 0, b2 = 0, a1 = 0, a2 = 0;
  /// Gain at DC, (b0 + b1 + b2) / (1 + a1 + a2).
  double dcGain() const;
};

/// 2nd-order Butterworth low-pass (bilinear, pre-warped): -3 dB at cutoff_hz, unit DC gain.
/// Throws std::invalid_argument unless 0 < cutoff_hz < sample_rate_hz / 2.
Biquad butter2Lowpass(double cutoff_hz, double sample_rate_hz);

/// One causal pass (direct form II transposed). With `steady_start`, the state starts at the
/// steady state for a constant input equal to x[0] (scipy's lfilter_zi * x[0]); otherwise 0.
std::vector<double> biquadFilter(const Biquad& f, const std::vector<double>& x,
                                 bool steady_start = true);

/// Zero-phase 2nd-order Butterworth low-pass: the filter applied forward then backward on the
/// series extended at both ends by odd reflection (2 x[0] - x[k], 2 x[n-1] - x[n-1-k]) over
/// filtfiltPadLength samples, each pass started at its steady state for its first input
/// (scipy's lfilter_zi). Odd reflection continues the value and slope across the ends, so
/// constants and ramps come out unchanged up to the ends. Assumes uniform sampling at
/// sample_rate_hz. Series shorter than 2 samples are returned unchanged. Throws
/// std::invalid_argument unless 0 < cutoff_hz < sample_rate_hz / 2.
std::vector<double> filtfiltButter2(const std::vector<double>& x, double cutoff_hz,
                                    double sample_rate_hz);

/// Padding used by filtfiltButter2: min(n - 1, max(9, ceil(3 fs / fc))), i.e. three periods
/// of the cut-off (about 13 decay time constants of the filter, so the start-up transient is
/// ~1e-6 of the edge slope by the time it reaches the data). scipy's default is 9 samples
/// (3 * max(len(a), len(b))), too short when fc << fs.
std::size_t filtfiltPadLength(std::size_t n, double cutoff_hz, double sample_rate_hz);

/// filtfiltButter2 for a series on an uneven (strictly increasing) time base: resampled
/// linearly onto a uniform grid with the median sample spacing, filtered, and interpolated back
/// to t_s. If cutoff_hz is at or above the grid's Nyquist frequency the series is returned
/// unchanged (there is nothing to remove).
std::vector<double> filtfiltButter2(const std::vector<double>& t_s, const std::vector<double>& x,
                                    double cutoff_hz);

/// Linear interpolation of (t_src, x_src) at t_dst. t_src must be non-decreasing (equal times
/// are allowed: the later sample wins); t_dst may be in any order. Outside [t_src.front(),
/// t_src.back()] the end values are held (no extrapolation). An empty source throws
/// std::invalid_argument; a single-sample source gives a constant.
std::vector<double> resampleLinear(const std::vector<double>& t_src,
                                   const std::vector<double>& x_src,
                                   const std::vector<double>& t_dst);

/// dx/dt on an uneven, strictly increasing time base: the second-order three-point formula
/// (exact for quadratics) at interior samples,
///   x'_i = [h-^2 x_{i+1} - h+^2 x_{i-1} + (h+^2 - h-^2) x_i] / (h- h+ (h- + h+)),
/// h- = t_i - t_{i-1}, h+ = t_{i+1} - t_i, and the second-order one-sided three-point formula
/// at both ends (a plain difference when n = 2; zeros when n < 2). Throws
/// std::invalid_argument if the sizes differ or the time base is not strictly increasing.
std::vector<double> centralDerivative(const std::vector<double>& t_s, const std::vector<double>& x);

/// Median of the positive sample spacings of t_s (0 if there are none).
double medianSpacing(const std::vector<double>& t_s);

}  // namespace wheelchair::sensors
