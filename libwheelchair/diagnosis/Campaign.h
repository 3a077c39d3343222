// The discovery campaign (issue 7 "Proof"): simulated drives with catalogue effects concealed
// at small random magnitudes, diagnosed, and scored: correct naming (the reported set of
// effect ids equals the concealed set, nothing extra), parameter error, false alarms on clean
// drives, and validation improvement. bench/discovery_campaign.cpp runs it from the command
// line; tests/diagnosis runs a small seeded version.
//
// Example:
//   CampaignOptions o;  o.runs_per_effect = 5;  o.seed = 1;
//   nlohmann::json summary = runCampaign(cfg, o);
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/diagnosis/Diagnosis.h"
#include "libwheelchair/simulation/Effects.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <random>
#include <string>
#include <vector>

namespace wheelchair::diagnosis {

struct CampaignOptions {
  int runs_per_effect = 10;  ///< single-effect runs per catalogue effect
  int clean_runs = 20;       ///< runs without any effect (false alarms)
  int pair_runs = 20;        ///< runs with two effects at once
  uint64_t seed = 1;
  std::vector<std::string> scenarios = {"excite", "square"};
  double duration_s = 90;  ///< excite duration (waypoint scenarios use their default)
  std::vector<std::string> effects = {"gyro_bias",    "gyro_scale",      "encoder_scale",
                                      "sensor_delay", "motor_asymmetry", "coulomb_friction",
                                      "ground_slope", "payload_mass"};
  bool verbose = false;
};

/// A concealed effect with a random SMALL magnitude (docs/discovery.md lists the ranges).
simulation::EffectSpec randomEffect(const std::string& id, std::mt19937_64& rng);

/// Relative error of the fitted parameter of a finding against the concealed effect, on the
/// deviation from nominal (e.g. (scale - 1)); NaN if not comparable.
double parameterError(const simulation::EffectSpec& truth, const Finding& f,
                      const config::WheelchairConfig& cfg);

struct CaseResult {
  std::vector<simulation::EffectSpec> truth;
  std::vector<std::string> reported;
  bool correct = false;
  std::vector<double> param_errors;              ///< per concealed effect
  double val_rms_before = 0, val_rms_after = 0;  ///< current channels (A) or gyro (rad)
  double runtime_s = 0;
  nlohmann::json toJson() const;
};

CaseResult runCase(const config::WheelchairConfig& cfg, const std::string& scenario, uint64_t seed,
                   double duration_s, const std::vector<simulation::EffectSpec>& effects,
                   const DiagnosisOptions& dopt);

/// Runs everything; returns {"single": {effect: {runs, correct, rate, median_param_error, ...}},
/// "pairs": {...}, "clean": {...}, "cases": [...]}.
nlohmann::json runCampaign(const config::WheelchairConfig& cfg, const CampaignOptions& opt,
                           const DiagnosisOptions& dopt);

}  // namespace wheelchair::diagnosis
