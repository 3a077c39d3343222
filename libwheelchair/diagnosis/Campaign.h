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
#include "libwheelchair/effects/Effect.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <functional>
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
  /// Truth engine of the simulated drives: "model" or "mujoco" (SimulationOptions::engine).
  std::string engine = "model";
  int triple_runs = 0;  ///< runs with three catalogue effects at once
  /// Drives with physics outside the catalogue: `unknown_runs` drives, each with the effects
  /// `unknown_effects` draws (the campaign program supplies them, e.g.
  /// simulation::randomUnknownEffect; the diagnosis does not know their names). Scored as
  /// flagged (a mismatch or any finding), located and described (unknownEffectScore), with
  /// the catalogue names the diagnosis used for them.
  int unknown_runs = 0;
  std::function<std::vector<effects::EffectSpec>(std::mt19937_64&)> unknown_effects;
  /// Run only the `unknown` drives: the catalogue and clean drives are drawn from the random
  /// stream as before (so the unknown drives are the same as in the full command) but not run.
  bool unknown_only = false;
};

/// A concealed effect with a random SMALL magnitude (docs/discovery.md lists the ranges).
effects::EffectSpec randomEffect(const std::string& id, std::mt19937_64& rng);

/// Relative error of the fitted parameter of a finding against the concealed effect, on the
/// deviation from nominal (e.g. (scale - 1)); NaN if not comparable.
double parameterError(const effects::EffectSpec& truth, const Finding& f,
                      const config::WheelchairConfig& cfg);

/// Whether a non-catalogue finding (`wheel_geometry`, `unmodeled`) on a MuJoCo drive is the
/// engine's own physics, measured independently (`truth`: simulation::measureMujocoTruth as
/// JSON: radius_rel / track_rel [min, max], which runCase widens to the geometry the
/// multibody realises in the drive itself, `geometry_in_drive` (simulation::realisedGeometry);
/// per right motor current v_omega_A, omega2_A,
/// omegadot_A and,
/// on a slope, slope_cos_A / slope_sin_A). wheel_geometry: every changed (non-zero) relative
/// radius / track within the measured range widened by 25 % of its largest magnitude (the
/// campaign's parameter tolerance). unmodeled on a motor current: only the centre-of-mass
/// terms v*omega (right +, left -), omega^2 and cos/sin(phi) (the slope's yaw moment on the
/// centre of mass) and the yaw-inertia term omegadot (right +, left -; omegadot_A), each
/// within 25 % of the engine's value. The acceleration terms vdot and omegadot are judged
/// against the values the multibody realises in the drive's own motion, per motor
/// (`vdot_in_drive_A`, `omegadot_in_drive_A` [right, left], measured by runCase against the
/// drive's model-engine twin when a finding has such a term; they depend on the motion's
/// spectrum: a step from rest gives vdot +0.005, a rolling start +0.13); without them a vdot
/// term is false and omegadot is judged against the step's omegadot_A. Anything else: false
/// (an extra).
bool engineTruthFinding(const Finding& f, const nlohmann::json& truth);

/// Score of an out-of-catalogue drive against the truth its generator states
/// (simulation::unknownEffectTruth of truth[0]): `located` when an `unmodeled` finding has a
/// physics component (UnmodeledPhysics.h) on the effect's channel, `described` when such a
/// component also has the effect's dependence class. Catalogue findings never count (naming
/// an unknown effect after the catalogue is a false finding); on MuJoCo the engine's own
/// centre-of-mass components (terms v*omega, omega^2) are set aside. `findings`: the
/// CaseResult's. A component's `ambiguous_with` readings (one collinear group,
/// UnmodeledPhysics.h) count too: then `described_in_group` says the effect's reading was one
/// of an ambiguous group's. JSON: {located, described, [described_in_group], truth {channel,
/// dependence, physics}, components, catalogue_names}.
nlohmann::json unknownEffectScore(const std::vector<effects::EffectSpec>& truth,
                                  const nlohmann::json& findings, const std::string& engine);

/// The TRACE of an out-of-catalogue effect (scoring honestly, issue 16 item 3): the drive
/// simulated twice with the same seed, with and without `effects` (every noise stream is its
/// own seeded stream, simulation/Random.h, so the two recordings differ by what the effect
/// does and nothing else), and per sensor stream the diagnosis sees the change d measured
/// against that stream's configured noise sigma (currents [motors] current_noise_A, gyro
/// [imu] gyro_noise_rad_s, encoder increments per sample: tick quantisation sqrt(1/6)
/// ticks): rms_ratio = rms(d) / sigma and lr = sum(d^2) / sigma^2 (the likelihood ratio of
/// the known change in white noise). `traced`: some stream's change is both significant
/// (lr >= chi2_1(1 - alpha)) and relevant (rms_ratio >= min_relevance: the floor any finding
/// must pass, DiagnosisOptions); an effect without a trace leaves nothing to find.
/// `realised`: the law the engine realised, measured on the noise-free true currents (half
/// sum: forward, half difference: yaw) regressed on each dependence class of the truth's v
/// or omega alone (sign_of_rate sgn(x), rate x, rate_squared x|x|, acceleration xdot,
/// constant 1; on yaw also castor_swivel, Stages.h castorSwivelMoment of the true motion with
/// dopt's castors): uncentred R^2 per class and the best one, on the channel that carries more
/// of the change (null when the true currents do not change: a sensor effect).
/// JSON: {traced, strongest, streams {name: {rms_ratio, lr}}, realised}.
nlohmann::json effectTrace(const config::WheelchairConfig& cfg, const std::string& scenario,
                           uint64_t seed, double duration_s,
                           const std::vector<effects::EffectSpec>& effects,
                           const DiagnosisOptions& dopt, const std::string& engine);

struct CaseResult {
  std::vector<effects::EffectSpec> truth;
  std::vector<std::string> reported;
  bool correct = false;
  std::vector<double> param_errors;              ///< per concealed effect
  double val_rms_before = 0, val_rms_after = 0;  ///< current channels (A) or gyro (rad)
  double runtime_s = 0;
  bool mismatch = false;  ///< the diagnosis found the model mismatched (with or without names)
  /// The catalogue names are right when the `unmodeled` findings (residual the catalogue does
  /// not explain) are set aside: correct naming plus a flag for the physics it cannot name.
  bool named_correct = false;
  /// Scored against what the truth engine IS (engine_truth): the catalogue names right and
  /// every other finding (`wheel_geometry`, `unmodeled`) the engine's own physics, measured
  /// on the multibody independently of the diagnosis (simulation/MujocoTruth.h; see
  /// engineTruthFinding). On the model engine the same as `correct`.
  bool engine_correct = false;
  /// A finding the engine does not realise: a catalogue name not concealed, or an `unmodeled`
  /// / `wheel_geometry` finding that is not the engine's own physics (engine_correct without
  /// the misses and the parameter errors).
  bool false_finding = false;
  /// Concealed effects not named that the report says it cannot tell from another reading
  /// (an info.cannot_tell note that starts with the effect's catalogue name and side, e.g.
  /// "motor_asymmetry/right or a load on both motors: ..."): not a correct naming, not a
  /// false finding (issue 16 item 5).
  std::vector<std::string> cannot_tell;
  nlohmann::json findings = nlohmann::json::array();  ///< per finding: effect, parameters
  nlohmann::json engine_truth;  ///< MuJoCo: the measured geometry and current terms
  nlohmann::json toJson() const;
};

CaseResult runCase(const config::WheelchairConfig& cfg, const std::string& scenario, uint64_t seed,
                   double duration_s, const std::vector<effects::EffectSpec>& effects,
                   const DiagnosisOptions& dopt, const std::string& engine = "model");

/// Runs everything; returns {"engine", "single": {effect: {runs, correct, rate,
/// median_param_error, cannot_tell, false_finding, ...}}, "pairs": {...}, "triples": {...}
/// (if triple_runs; cannot_tell / false_finding: drives with CaseResult::cannot_tell non-empty
/// / CaseResult::false_finding),
/// "clean": {runs, false_alarms, named_false_alarms, engine_false_alarms,
/// catalogue_false_alarms (drives with a catalogue name other than unmodeled /
/// wheel_geometry)}, "unknown": {runs, flagged, located, described, located_rate,
/// described_rate, by_effect {id: {runs, traced, located, described}}, named,
/// described_in_group, traced, located_traced, described_traced, described_traced_rate,
/// no_trace [effect (scenario)]} (if unknown_runs; each unknown case with its effectTrace),
/// "cases": [...]}.
nlohmann::json runCampaign(const config::WheelchairConfig& cfg, const CampaignOptions& opt,
                           const DiagnosisOptions& dopt);

}  // namespace wheelchair::diagnosis
