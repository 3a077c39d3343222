// Shared helpers of the simulation tests.
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/simulation/Simulator.h"

#include <cmath>
#include <string>
#include <vector>

namespace wheelchair::simulation::test {

inline SimulationResult run(const std::string& scenario, uint64_t seed,
                            const std::vector<std::string>& effects = {}, double duration_s = 0,
                            SimulationOptions opt = SimulationOptions{}) {
  static const config::WheelchairConfig cfg;
  std::vector<effects::EffectSpec> e;
  for (const auto& t : effects) e.push_back(effects::parseValidEffect(t));
  return simulate(cfg, scenario, seed, duration_s, e, opt);
}

inline double rms(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x * x;
  return v.empty() ? 0 : std::sqrt(s / v.size());
}

}  // namespace wheelchair::simulation::test
