#include "libwheelchair/estimation/SensorVerdict.h"

#include "libwheelchair/stats/Distributions.h"

#include <fmt/core.h>

#include <cmath>

namespace wheelchair::estimation {

namespace {
constexpr double kLevel = 0.95;  // the level of SensorStats::meanNisBand95()

bool hasGate(double p) {
  return p > 0 && p < 1;
}

double percent(long part, long whole) {
  return whole > 0 ? 100.0 * double(part) / double(whole) : 0.0;
}
}  // namespace

double rejectionPValue(const SensorStats& st, double gate_probability) {
  if (st.rejected <= 0 || !hasGate(gate_probability)) return 1.0;
  const double lambda = double(st.used + st.rejected) * (1 - gate_probability);
  return stats::chi2Cdf(2 * lambda, 2.0 * double(st.rejected));
}

SensorConsistency sensorConsistency(const SensorStats& st, double gate_probability) {
  if (st.used + st.rejected <= 0) return SensorConsistency::NotUsed;
  if (rejectionPValue(st, gate_probability) < 1 - kLevel) return SensorConsistency::Inconsistent;
  if (st.nis_count <= 0 || st.dof <= 0) return SensorConsistency::Consistent;
  const auto band = st.meanNisBand95();
  if (st.meanNis() > band.second) return SensorConsistency::Inconsistent;
  if (st.meanNis() < band.first) return SensorConsistency::NoiseOverestimated;
  return SensorConsistency::Consistent;
}

std::string sensorVerdict(Sensor s, const SensorStats& st, double gate_probability) {
  const std::string name = sensorName(s);
  const long attempts = st.used + st.rejected;
  std::string dropped;
  if (st.dropouts > 0)
    dropped = fmt::format("; {:.0f} % of readings without a valid value (dropouts: {} of {})",
                          percent(st.dropouts, attempts + st.dropouts), st.dropouts,
                          attempts + st.dropouts);
  const auto band = st.meanNisBand95();
  const std::string nis = st.nis_count > 0 ? fmt::format("NIS mean {:.2f}, expected {:.2f}..{:.2f}",
                                                         st.meanNis(), band.first, band.second)
                                           : std::string("no NIS");
  const double expected_pct = hasGate(gate_probability) ? 100 * (1 - gate_probability) : 0.0;
  switch (sensorConsistency(st, gate_probability)) {
    case SensorConsistency::NotUsed:
      if (st.skipped > 0 && st.dropouts == 0)
        return fmt::format("{}: not used ({} readings skipped: sensor disabled)", name, st.skipped);
      return fmt::format("{}: not used (no valid reading{})", name, dropped);
    case SensorConsistency::Inconsistent:
      if (rejectionPValue(st, gate_probability) < 1 - kLevel)
        return fmt::format(
            "{}: {:.0f} % of updates rejected ({} of {}; {:.1f} % expected at the gate; {}): "
            "inconsistent with the other sensors - a fault or a wrong model (see `wheelchair "
            "diagnose`){}",
            name, percent(st.rejected, attempts), st.rejected, attempts, expected_pct, nis,
            dropped);
      return fmt::format(
          "{}: errors larger than the model allows ({}; {:.0f} % rejected): inconsistent - a "
          "fault, a wrong model or too small a noise setting (see `wheelchair diagnose`){}",
          name, nis, percent(st.rejected, attempts), dropped);
    case SensorConsistency::NoiseOverestimated:
      return fmt::format(
          "{}: usable, errors smaller than the model assumes ({}; {:.0f} % rejected): its noise "
          "setting is conservative{}",
          name, nis, percent(st.rejected, attempts), dropped);
    case SensorConsistency::Consistent:
      break;
  }
  return fmt::format("{}: consistent ({}; {:.0f} % rejected){}", name, nis,
                     percent(st.rejected, attempts), dropped);
}

std::vector<std::string> sensorVerdicts(const EstimationResult& res, double gate_probability) {
  std::vector<std::string> out;
  for (int s = 0; s < kNumSensors; ++s) {
    const auto& st = res.sensors[s];
    if (!st.used && !st.rejected && !st.dropouts && !st.skipped) continue;
    out.push_back(sensorVerdict(static_cast<Sensor>(s), st, gate_probability));
  }
  return out;
}

}  // namespace wheelchair::estimation
