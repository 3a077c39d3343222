// Sensor-fault detectors of `wheelchair diagnose` (issue 7: `sonar_dropout` and
// `pozyx_outliers` are reported as faults of a sensor, Finding::is_fault, never as physics;
// docs/discovery.md "Sensor faults").
//
//   sonar_dropout   A sonar reads 0 when there is no echo. On a healthy sensor that happens
//                   only while no target is in the cone, i.e. as a function of the pose, which
//                   changes smoothly. A DROPOUT is a run of zero readings that interrupts a
//                   target track: bracketed by valid readings inside the range band, and the
//                   readings of the target on both sides (up to `sonar_track_readings` each,
//                   no jump larger than noise + `sonar_max_range_rate_m_s` dt) lie on ONE line
//                   in time (weighted least squares, variance = noise + random range
//                   acceleration over the distance from the run; chi-square with n - 2 dof
//                   inside its 1 - alpha band), and no longer than `sonar_max_run_s`. Readings
//                   outside [min_range - 5 sigma, max_range + 5 sigma] that are not 0 (or not
//                   finite) count as out-of-range. Parameters as the simulator's effect:
//                   `probability` (failed / expected echoes, where an echo was expected),
//                   `burst_length` (mean readings per run). Fires when at least one run passes
//                   (family-wise level alpha).
//   pozyx_outliers  Each Pozyx fix is compared with the odometric track (encoders, heading from
//                   the gyro when present, stage-1 corrections applied, tag lever arm from the
//                   configuration) mapped into the anchor frame by a robust (Tukey IRLS) local
//                   SE(2) fit over +-`pozyx_window_s`, leaving the fix itself out; the noise
//                   scale is max(configured noise, 1.4826 MAD of the innovations); the
//                   variance adds the left-out fix's prediction variance (translation and
//                   rotation of the local fit). A fix is an outlier when |e|^2 / s^2 exceeds
//                   the chi-square(2) quantile at p0 = 1/n (one such fix expected when clean);
//                   the FAULT is declared when the count k of outliers is significant against
//                   Binomial(n, p0) at level alpha (an outlier process, not one rare Gaussian
//                   fix: 1 fix never fires) AND the largest is beyond the Bonferroni level
//                   alpha / n (a cluster of moderate exceedances from a local track error is
//                   not a UWB fault). Parameters: `rate` (k / fixes),
//                   `magnitude_m` (median displacement of the outliers).
//
// Example:
//   SensorFaultReport sf = detectSensorFaults(recordings, cfg, corrections, {});
//   for (auto& f : sf.findings) rep.addFinding(f);
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/diagnosis/Finding.h"
#include "libwheelchair/diagnosis/Stages.h"
#include "libwheelchair/io/Recording.h"

#include <nlohmann/json.hpp>

#include <vector>

namespace wheelchair::diagnosis {

struct SensorFaultOptions {
  double alpha = 0.01;                 ///< family-wise false-alarm level per detector
  double sonar_max_run_s = 2.0;        ///< longest zero run that can be a dropout
  int sonar_track_readings = 3;        ///< valid readings per side for the range tracks
  double sonar_max_track_gap_s = 1.0;  ///< readings of a track are no further apart than this
  /// Range acceleration of a tracked target (m/s^2, ~ v^2 / d of a post passed at 1 m/s, 1 m)
  /// allowed when the tracks on both sides of a zero run are extrapolated to its midpoint.
  double sonar_range_accel_m_s2 = 1.0;
  /// Largest range rate of one target (m/s); a larger step between readings = another target.
  double sonar_max_range_rate_m_s = 2.0;
  double pozyx_window_s = 3.0;     ///< half-width of the local alignment window
  int pozyx_min_window_fixes = 8;  ///< fewer fixes in the window: not tested
};

struct SensorFaultReport {
  std::vector<Finding> findings;                   ///< is_fault = true
  nlohmann::json info = nlohmann::json::object();  ///< per-detector statistics (also when quiet)
};

/// Runs both detectors on the recordings (times are each recording's own clock; segments
/// of several recordings are listed together). `corr` = the stage-1 sensor corrections for
/// the odometric track (identity if unknown).
SensorFaultReport detectSensorFaults(const std::vector<io::Recording>& recs,
                                     const config::WheelchairConfig& cfg, const Corrections& corr,
                                     const SensorFaultOptions& opt);
/// The same with each recording's streams already made (`streams[i]` = makeStreams(recs[i]);
/// only the encoder, gyro and Pozyx streams are read): the Pozyx check then reads them instead
/// of the recordings' encoder / IMU samples, which may have been released (diagnose on a long
/// drive; memory, docs/benchmarks.md). The sonar check reads recs[i].sonar.
SensorFaultReport detectSensorFaults(const std::vector<io::Recording>& recs,
                                     const config::WheelchairConfig& cfg, const Corrections& corr,
                                     const SensorFaultOptions& opt,
                                     const std::vector<Streams>* streams);

}  // namespace wheelchair::diagnosis
