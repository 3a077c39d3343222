// Helpers of the diagnosis tests: a simulated drive with concealed effects, and diagnose() of
// one recording with the nominal vehicle and the default options.
#pragma once

#include "libwheelchair/diagnosis/Diagnosis.h"
#include "libwheelchair/simulation/Simulator.h"

#include <cstdint>
#include <string>
#include <vector>

namespace wheelchair::diagnosis::testutil {

/// `scenario` of `duration_s` (0: the scenario's own) driven by the nominal vehicle with
/// `effects` in the simulator's syntax ("encoder_scale:side=left,scale=0.95").
inline simulation::SimulationResult simulateWith(const std::string& scenario, uint64_t seed,
                                                 double duration_s,
                                                 const std::vector<std::string>& effects,
                                                 bool record_ground_truth = false) {
  config::WheelchairConfig cfg;
  simulation::SimulationOptions so;
  so.loadFromConfig(cfg.ini());
  if (record_ground_truth) so.record_ground_truth = true;  // else as the configuration says
  std::vector<effects::EffectSpec> e;
  for (auto& s : effects) e.push_back(effects::parseValidEffect(s));
  return simulation::simulate(cfg, scenario, seed, duration_s, e, so);
}

/// diagnose() of one recording (no validation recordings): nominal vehicle, default options.
inline DiagnosisReport diagnoseOne(const io::Recording& rec) {
  config::WheelchairConfig cfg;
  DiagnosisOptions opt;
  return diagnose({rec}, {}, cfg, opt);
}

}  // namespace wheelchair::diagnosis::testutil
