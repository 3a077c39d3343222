// The identification's flavour of the drive-signal conditioning (issue 14: it lived as
// identification::prepareSignals): recordings -> segments on a common grid, every signal
// through the same box filter as the encoder speeds.
//
// Why a flavour of its own beside prepare() (DriveSignals.h): the least squares of the
// identification regress the currents on the accelerations, so both sides of (2) must see the
// same filter (docs/identification.md, section 2). An encoder speed is the mean over its tick
// interval [t0, t1]; here the currents, the motor voltages and the gyro are averaged over the
// same intervals before anything else. prepare() differentiates the rim distances instead and
// filters the currents on their own time base, which is right for the diagnosis' residuals but
// would bias the identification's estimates by the box filter's phase.
//
//   1. streams: encoder interval speeds u_R, u_L at the interval midpoints (time-ordered,
//      non-overlapping, finite); motor currents and V_RC voltages, the motor voltage U per side
//      from the V_RC inverse (sensors::motorVoltageFromVrc); gyro; all sorted, repeated stamps
//      and non-finite samples dropped
//   2. a grid at rate_hz from the latest stream start; a grid point is usable when every stream
//      covers it without a gap over max_gap_s; runs of usable points at least
//      2 edge_trim_s + 1 s long are the segments
//   3. per segment: speeds resampled linearly onto the grid; currents, voltages (and the gyro)
//      as interval means over the encoder intervals, resampled; all zero-phase 2nd-order
//      Butterworth at cutoff_hz; v = (u_R + u_L)/2, omega = (u_R - u_L)/l_w (or the gyro);
//      vdot, omegadot by central differences of the filtered signals
//   4. rows flagged interior (not within edge_trim_s of the ends) and moving (max |u_i| at
//      least standstill_speed_m_s); noise floors = raw-minus-filtered rms of v and omega over
//      the interior rows, scaled by the filter's (and filter + difference's) white-noise gain
//
// Frames and units: index R = right, L = left; u > 0 forward, omega > 0 turns left; s, m/s,
// rad/s, m/s^2, rad/s^2, A, V.
//
// Example:
//   IntervalSignalOptions o;  o.rate_hz = 100;  o.cutoff_hz = 2;
//   const IntervalSignals d = prepareIntervalMeans({rec}, cfg, o);
//   for (const IntervalSegment& s : d.segments) use(s.t, s.vdot, s.i_r);
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/io/Recording.h"

#include <vector>

namespace wheelchair::signals {

struct IntervalSignalOptions {
  double rate_hz = 100.0;              ///< grid (Hz)
  double cutoff_hz = 2.0;              ///< zero-phase low-pass (Hz), every signal
  bool gyro_omega = false;             ///< omega from the gyro instead of the encoders
  double standstill_speed_m_s = 0.03;  ///< a row is standstill when both |u_i| are below (m/s)
  double edge_trim_s = 1.0;            ///< rows this close to a segment end are not interior (s)
  double max_gap_s = 0.25;             ///< a stream gap longer than this splits a segment (s)
};

/// One continuous stretch of a recording on the common grid, all signals filtered.
struct IntervalSegment {
  int recording = 0;                                       ///< index into the recordings
  std::vector<double> t;                                   ///< grid (s)
  std::vector<double> u_r, u_l, v, omega, vdot, omegadot;  ///< filtered (m/s, rad/s, /s)
  std::vector<double> i_r, i_l;                            ///< filtered currents (A)
  std::vector<double> U_r, U_l;                            ///< motor voltage (V_RC inverse) (V)
  std::vector<char> interior;  ///< not within edge_trim_s of the segment ends
  std::vector<char> moving;    ///< not standstill
};

struct IntervalSignals {
  std::vector<IntervalSegment> segments;
  double noise_v = 0, noise_omega = 0;        ///< filtered-signal noise rms (m/s, rad/s)
  double noise_vdot = 0, noise_omegadot = 0;  ///< filtered-derivative noise rms
  bool has_voltage = false;                   ///< some V_RC sample is not zero
};

/// One grid sample of a segment: what an IntervalSegment holds at index k (the streaming
/// conditioning, IntervalStream.h, produces these instead of whole segments).
struct IntervalRow {
  int recording = 0;
  int segment = 0;  ///< index of the segment over all recordings, in order
  long k = 0;       ///< index within the segment
  double t = 0;     ///< (s)
  double u_r = 0, u_l = 0, v = 0, omega = 0, vdot = 0, omegadot = 0;  ///< filtered
  double i_r = 0, i_l = 0, U_r = 0, U_l = 0;                          ///< filtered (A, V)
  bool interior = false, moving = false;
};

/// Row k of segment s (its index `segment` over all recordings).
IntervalRow intervalRow(const IntervalSegment& s, int segment, std::size_t k);

/// Step 4's noise floors into `out` from the raw-minus-filtered sums of squares of v and omega
/// over the n interior rows (nothing when n = 0).
void noiseFloors(double ss_v, double ss_w, std::size_t n, const IntervalSignalOptions& o,
                 IntervalSignals& out);

/// Steps 1-4 over the recordings (segments of all of them, in order).
IntervalSignals prepareIntervalMeans(const std::vector<io::Recording>& recordings,
                                     const config::WheelchairConfig& cfg,
                                     const IntervalSignalOptions& o);

}  // namespace wheelchair::signals
