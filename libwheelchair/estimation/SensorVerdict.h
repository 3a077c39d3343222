// One line per sensor, in words, from the filter's consistency statistics (SensorStats).
//
// A consistent filter sees, for a sensor with d-dimensional measurements,
//   * NIS values ~ chi2(d): their mean over n accepted updates lies, with 95 % probability, in
//     SensorStats::meanNisBand95() = chi2MeanBand(0.95, d, n) (stats/Distributions.h);
//   * gate rejections ~ Binomial(N, q), q = 1 - gate_probability, N = used + rejected,
//     approximated by Poisson(lambda = N q). The chance of k or more rejections is
//     P(X >= k) = chi2Cdf(2 lambda, 2 k) (the Poisson-chi2 identity); below 5 % the rejections
//     are too many for chance (the same 95 % level as the band).
// The verdict is, in this order: not used (no attempt), "inconsistent" (too many rejections or
// a mean NIS above the band: larger errors than the model allows — a fault or a wrong model),
// "noise overestimated" (mean NIS below the band: the filter trusts the sensor less than it
// could), else "consistent". Dropouts (invalid readings) are reported as a share.
//
// Example (three_task_faulty, left encoder 5 % short):
//   sensorVerdict(Sensor::Encoders, res.stats(Sensor::Encoders), 0.999)
//   -> "encoders: 52 % of updates rejected (1107 of 2149; 0.1 % expected at the gate):
//       inconsistent with the other sensors - a fault or a wrong model (see `wheelchair
//       diagnose`)"
//   sensorVerdict(Sensor::Gyro, ...) -> "gyro: consistent (NIS mean 1.03, expected 0.96..1.04;
//                                       0 % rejected)"
#pragma once

#include "libwheelchair/estimation/EstimationTypes.h"

#include <string>
#include <vector>

namespace wheelchair::estimation {

enum class SensorConsistency { NotUsed, Consistent, NoiseOverestimated, Inconsistent };

/// Classifies `st` as described above. gate_probability <= 0 or >= 1: no gate (rejections
/// then are not judged).
SensorConsistency sensorConsistency(const SensorStats& st, double gate_probability);

/// P(at least st.rejected rejections | consistent filter, gate at gate_probability); 1 when
/// nothing was rejected or there is no gate.
double rejectionPValue(const SensorStats& st, double gate_probability);

/// The one-line verdict for sensor `s` (no trailing newline).
std::string sensorVerdict(Sensor s, const SensorStats& st, double gate_probability);

/// One verdict per sensor of `res` that saw any measurement (attempted, dropped or skipped).
std::vector<std::string> sensorVerdicts(const EstimationResult& res, double gate_probability);

}  // namespace wheelchair::estimation
