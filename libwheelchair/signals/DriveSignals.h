// One conditioning pipeline for the drive signals (issue 14): recording -> segmented signals on
// a common time grid, used by the diagnosis (stage 2 rows), its figures and the identification's
// currents check.
//
//   1. ticks -> cumulative rim distances s_R, s_L (m; odometry radii, unwrapped counters),
//      motor currents i_R, i_L (A); both streams sorted, repeated stamps dropped
//   2. each stream split where consecutive samples are more than max_gap_s apart; a segment is
//      an overlap of both streams' pieces, edge_trim_s shorter at both ends, at least
//      min_segment_s long
//   3. a grid at grid_rate_hz over the segment plus a margin of min(edge_trim_s, 1 s) each side
//      (the filter's run-in, dropped afterwards: rows [i0, i1))
//   4. distances resampled linearly onto the grid, rim speeds u = central differences
//   5. zero-phase 2nd-order Butterworth at cutoff_hz on the speeds; accelerations = central
//      differences of the filtered speeds
//   6. currents filtered on their own time base (same filter), then resampled onto the grid
//
// Frames and units: index 0 = right, 1 = left; u > 0 forward; s, m, m/s, m/s^2, A.
//
// Example:
//   DriveSignalOptions o;  o.grid_rate_hz = 50;  o.cutoff_hz = 2;
//   for (const DriveSegment& s : prepare(driveStreams(rec, cfg), o))
//     for (int i = s.i0; i < s.i1; ++i) use(s.t[i], s.u_f[0][i], s.i_f[0][i]);
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/io/Recording.h"

#include <array>
#include <vector>

namespace wheelchair::signals {

/// Encoder rim distances and motor currents, sorted by time without repeated stamps.
struct DriveStreams {
  std::vector<double> te;                ///< encoder stamps (s)
  std::array<std::vector<double>, 2> s;  ///< cumulative rim distance from the first sample (m)
  std::vector<double> tm;                ///< motor stamps (s)
  std::array<std::vector<double>, 2> i;  ///< motor currents (A), finite
};

/// Step 1 from a recording: counters unwrapped, distances with the odometry radius of each
/// wheel (model::Geometry::odometryRadius) and [encoders]' ticks per revolution.
DriveStreams driveStreams(const io::Recording& rec, const config::WheelchairConfig& cfg);

/// Step 1's encoder part: `out.te`, `out.s` from the encoder samples (as driveStreams).
void encoderDistances(const std::vector<io::EncoderSample>& enc,
                      const config::WheelchairConfig& cfg, DriveStreams& out);

/// Step 1's rule for samples held as columns in stored order (time `t_s` and `values`, e.g. the
/// motor currents read from a rawlog as a stream): stable time order, the first sample of
/// each repeated stamp, a sample with a non-finite value dropped -- the samples driveStreams
/// keeps of the motor currents. In place (no copy) when the stamps never decrease.
/// E.g. t = {0, 1, 1, 2}, i = {5, 6, 7, NaN} -> t = {0, 1}, i = {5, 6}.
void sortUniqueFinite(std::vector<double>& t_s, const std::vector<std::vector<double>*>& values);

struct DriveSignalOptions {
  double grid_rate_hz = 50.0;  ///< grid (Hz)
  double cutoff_hz = 2.0;      ///< zero-phase low-pass (Hz)
  double max_gap_s = 0.25;     ///< a longer stream gap splits a segment (s)
  double edge_trim_s = 1.0;    ///< dropped at both ends of every segment (s)
  double min_segment_s = 3.0;  ///< shorter segments are not used (s)
};

/// One continuous stretch on the grid (margin included: use rows [i0, i1)).
struct DriveSegment {
  double lo = 0, hi = 0;                   ///< the segment (s), without the margin
  int i0 = 0, i1 = 0;                      ///< rows inside the segment
  std::vector<double> t;                   ///< grid (s)
  std::array<std::vector<double>, 2> p;    ///< rim distance on the grid (m)
  std::array<std::vector<double>, 2> u;    ///< rim speed, unfiltered central difference (m/s)
  std::array<std::vector<double>, 2> u_f;  ///< rim speed, filtered (m/s)
  std::array<std::vector<double>, 2> a_f;  ///< d/dt of the filtered rim speed (m/s^2)
  std::array<std::vector<double>, 2> i_f;  ///< current, filtered, resampled (A)
};

/// Steps 2-6.
std::vector<DriveSegment> prepare(const DriveStreams& s, const DriveSignalOptions& o);

/// Steps 1-6 of a recording.
inline std::vector<DriveSegment> prepare(const io::Recording& rec,
                                         const config::WheelchairConfig& cfg,
                                         const DriveSignalOptions& o) {
  return prepare(driveStreams(rec, cfg), o);
}

/// [t_begin, t_end] pieces of sorted stamps split where the step exceeds max_gap_s.
std::vector<std::pair<double, double>> splitAtGaps(const std::vector<double>& t, double max_gap_s);

}  // namespace wheelchair::signals
