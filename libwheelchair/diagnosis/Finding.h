// The result of `wheelchair diagnose` and its JSON contract (docs/discovery.md).
//
// A Finding is one named effect of the catalogue (docs/effects.md: the ids and parameter
// names are shared with the simulator's EffectSpec), a sensor fault, or an `unmodeled` term.
// Other analysers (e.g. the command-driven CommandResponse for actuator_lag) produce Findings
// too and add them with DiagnosisReport::addFinding; the JSON writer is shared.
//
// Example:
//   DiagnosisReport rep = diagnose(fit_recordings, cfg, opt);
//   rep.addFinding(commandResponseFinding);        // from another analyser
//   writeJsonFile(rep.toJson(), "out.json");
#pragma once

#include <nlohmann/json.hpp>

#include <map>
#include <string>
#include <utility>
#include <vector>

namespace wheelchair::diagnosis {

struct Finding {
  std::string effect;       ///< catalogue id (motor_asymmetry, encoder_scale, ..., unmodeled)
  std::string description;  ///< plain words with numbers
  std::vector<std::string> channels;                      ///< where it shows (gyro, encoders, ...)
  std::vector<std::pair<double, double>> segments;        ///< [t0, t1] where it acts most (s)
  nlohmann::json parameters = nlohmann::json::object();   ///< name -> value (number or text)
  nlohmann::json uncertainty = nlohmann::json::object();  ///< name -> 1-sigma
  nlohmann::json evidence = nlohmann::json::object();     ///< lr, p_value, delta_bic, n_eff, ...
  nlohmann::json fit_before = nlohmann::json::object();   ///< validation metrics without it
  nlohmann::json fit_after = nlohmann::json::object();    ///< ... and with it
  /// `unmodeled` findings: what the terms are physically (UnmodeledPhysics.h): per component
  /// channel, dependence class, term, coefficient +- sd, physical reading, held-out gain.
  nlohmann::json physics = nlohmann::json::array();
  bool is_fault = false;  ///< sensor fault (sonar_dropout, pozyx_outliers), not physics
  /// Found by the command-driven analyser (CommandResponse.h): its corrected parameters go to
  /// [mrclam_response], not to [model_extensions] (JSON: "analyser": "command_response").
  bool command_response = false;

  /// The simulator's effect text of this finding (`id:key=value,...`), empty for
  /// findings that are not catalogue effects (unmodeled).
  std::string effectText() const;
  nlohmann::json toJson() const;
};

struct DiagnosisReport {
  bool mismatch = false;
  std::vector<Finding> findings;
  std::string config_written;
  /// Per-channel compare/locate results (residual statistics per regime, NIS, whiteness)
  /// before and after, on the validation data; and run information.
  nlohmann::json channels = nlohmann::json::object();
  nlohmann::json validation = nlohmann::json::object();
  nlohmann::json info = nlohmann::json::object();
  /// Command-driven recordings: open-loop drift on the validation recordings of the nominal
  /// model and of the corrected one (drift_10s_m, drift_60s_m, heading_drift_10s_deg,
  /// heading_drift_60s_deg); written to the JSON only when set.
  nlohmann::json fit_before = nlohmann::json::object();
  nlohmann::json fit_after = nlohmann::json::object();
  /// Extra INI keys of the corrected configuration (section -> key -> value), e.g. the
  /// command-driven model's [mrclam_response]; correctedConfig() writes them.
  std::map<std::string, std::map<std::string, std::string>> config_updates;

  /// Adds a finding of another analyser (sets mismatch).
  void addFinding(Finding f);
  const Finding* find(const std::string& effect) const;
  nlohmann::json toJson() const;
};

}  // namespace wheelchair::diagnosis
