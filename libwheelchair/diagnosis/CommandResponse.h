// Discovery of how a drive responds to its velocity COMMANDS, from recordings with a command
// stream (JOYSTICK: demanded v, omega) and motion-capture ground truth (GROUND_TRUTH: Vicon
// poses). Used on the UTIAS MRCLAM robots (docs/real-data.md); the wheelchair's joystick ->
// power module path has the same form.
//
// Exact measurement model: Vicon poses differenced over a window [t0, t1] give the MEAN
// velocities over it (omega = wrap(dphi)/T, v = arc length/T with the constant-curvature chord
// correction), compared with the MEAN of the model's velocities over the same window (the
// model's response is integrated exactly on a fine grid). Windows: non-overlapping, ~0.25 s.
//
// Catalogue (model::CommandResponseParams terms, each fitted jointly with those accepted):
//   actuator_lag      (channel v|omega)  delay_s, time_constant_s
//   command_gain      (channel v: kind straight|arc; omega: kind turn_in_place|arc)  scale
//   deadband          (channel v|omega)  threshold (m/s | rad/s)
//   ignored_zero_commands (channels v+omega) short runs of (0,0) lines between moving
//                     commands have no effect (parameter: max_run_s, fixed)
// Forward selection: accept the best candidate if BIC drops by more than min_delta_bic AND its
// likelihood-ratio test is significant at alpha / (candidates tried), on the effective sample
// size of the autocorrelated window residuals (Bartlett), AND its parameters are plausible.
// What is left is regressed on a library of command features (1, v_cmd, omega_cmd,
// |omega_cmd|, v_cmd |omega_cmd|) per channel; terms passing the same evidence test are
// candidates for `unmodeled` terms of their channel.
//
// Held-out rule (issue 16; no term is kept on in-sample evidence alone), two steps:
//  1. Cross-validation on the FIT data: folds = the fit recordings (leave one out; one
//     recording: 4 time blocks). Per fold the gains and library coefficients are refitted on
//     the other folds (delays / time constants stay at the full fit) with and without each
//     term. A term stays only if, pooled over folds, (a) its channel's window residual drops
//     with a moving-block bootstrap (blocks of hac_lags windows) probability of no gain below
//     `cv_bootstrap_level`, and (b) the median 10-s open-loop position and heading drift are
//     not worse. Backward elimination: the worst failing term goes, the rest are refitted.
//  2. Gate on the VALIDATION recordings: with the model refitted on all fit data, each term
//     must lower its channel's window residual and make none of the four drift medians (10 s,
//     60 s, position, heading) worse; else it is removed (and the rest refitted).
// Removed terms are findings with validated = false, `rejected_by` ("cross_validation" /
// "validation") and the numbers in `heldout`; they are not in the model or its config.
//
// Before/after: open-loop drift on the validation recordings (windows of 10 s and 60 s started
// every `drift_start_every_s` at the true pose, the model integrated from the commands alone;
// median final position and |heading| error) for the nominal model (velocities equal the raw
// commands) and the selected model.
//
// Example:
//   auto res = diagnoseCommandResponse({r1, r2, r3}, {r4, r5}, CommandResponseOptions{});
//   std::cout << res.toJson().dump(2);
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/diagnosis/Finding.h"
#include "libwheelchair/io/Recording.h"
#include "libwheelchair/model/CommandDriven.h"

#include <nlohmann/json.hpp>

#include <array>
#include <map>
#include <string>
#include <vector>

namespace wheelchair::diagnosis {

struct CommandResponseOptions {
  double window_s = 0.25;               ///< velocity windows (non-overlapping)
  double grid_dt_s = 0.005;             ///< simulation grid of the model's response
  double max_delay_s = 0.6;             ///< search range of actuator_lag
  double max_time_constant_s = 0.8;     ///< search range of actuator_lag
  double max_zero_run_s = 0.1;          ///< ignored_zero_commands: longest (0,0) run that is a blip
  double alpha = 0.01;                  ///< family-wise false-alarm rate (Bonferroni)
  double min_delta_bic = 10;            ///< strong evidence (Kass & Raftery)
  int hac_lags = 20;                    ///< windows for the effective sample size (5 s at 0.25 s)
  double min_gain = 0.2, max_gain = 5;  ///< plausible command_gain range
  double drift_start_every_s = 5;       ///< open-loop drift windows
  double cv_bootstrap_level = 0.05;     ///< held-out rule, step 1 (a)
  double max_gt_gap_s = 0.5;            ///< ground-truth gap that invalidates a window end
};

struct DriftMetrics {
  double drift_10s_m = 0, drift_60s_m = 0;
  double heading_drift_10s_deg = 0, heading_drift_60s_deg = 0;
  std::size_t n_10s = 0, n_60s = 0;
};

/// Library terms added to the model's velocities (after the lag): per channel (0 v, 1 omega)
/// the coefficients of the command features 1, v_cmd, omega_cmd, |omega_cmd|,
/// v_cmd*|omega_cmd| (kLibraryNames order), evaluated on the current (undelayed) command.
struct UnmodeledTerms {
  std::array<std::array<double, 5>, 2> coef{};
  bool empty() const;
};
/// Names of the library features ("1", "v_cmd", "omega_cmd", "|omega_cmd|", "v_cmd*|omega_cmd|").
const std::array<const char*, 5>& commandLibraryNames();

struct CommandResponseFinding {
  std::string effect;   ///< actuator_lag, command_gain, deadband, ignored_zero_commands, unmodeled
  std::string channel;  ///< v, omega, v+omega
  std::string kind;     ///< command kind (command_gain) or library term (unmodeled)
  std::map<std::string, double> parameters;
  double delta_bic = 0, lr = 0, p_value = 1, n_eff = 0;
  int k = 0;  ///< parameters added
  /// Validation residual sum of squares without / with the term (other terms as fitted).
  double validation_rss_without = 0, validation_rss_with = 0;
  bool validated = false;
  double bonferroni_level = 0;  ///< the level its p-value was compared with
  /// Fit-recording times where the term changes the window mean by more than 2 sigma of the
  /// residual (merged over gaps < 1 s, at most 20).
  std::vector<std::pair<double, double>> segments;
  /// 1-sigma of the parameters: Gauss-Newton curvature of the residual sum of squares
  /// (numerical Hessian), variance inflated by n / n_eff (autocorrelation); unmodeled: HAC.
  std::map<std::string, double> uncertainty;
  /// Validation (held-out) open-loop drift and window residual RMS without / with the term
  /// (the other selected terms as fitted).
  DriftMetrics drift_without, drift_with;
  double validation_rms_without = 0, validation_rms_with = 0;
  /// Held-out rule: empty when kept, else "cross_validation" or "validation".
  std::string rejected_by;
  /// Numbers of the held-out rule: cross-validation (bootstrap probability of no gain, pooled
  /// window RSS and median 10-s drift without / with) and the validation gate.
  nlohmann::json heldout = nlohmann::json::object();
};

struct ChannelResidualStats {
  double rms_before = 0, rms_after = 0;  ///< window mean-velocity residual RMS
  std::size_t n = 0;
};

struct CommandResponseResult {
  std::vector<CommandResponseFinding> findings;
  model::CommandResponseParams params;  ///< the selected (validated) model
  bool ignore_zero_runs = false;
  double max_zero_run_s = 0.1;
  DriftMetrics fit_before, fit_after;                ///< on the VALIDATION recordings
  DriftMetrics fit_before_on_fit, fit_after_on_fit;  ///< on the fit recordings (reference)
  ChannelResidualStats validation_v, validation_omega;
  UnmodeledTerms unmodeled;          ///< validated unmodeled terms
  DriftMetrics fit_after_unmodeled;  ///< validation drift of params + unmodeled terms
  std::size_t fit_windows = 0, validation_windows = 0;
  /// RMS measurement-noise floor of a window mean on the fit data (m/s, rad/s).
  double noise_floor_v_m_s = 0, noise_floor_omega_rad_s = 0;
  nlohmann::json toJson() const;
};

/// True when the recording has a command stream and ground-truth poses.
bool hasCommandResponseData(const io::Recording& rec);

/// Throws std::invalid_argument when a list is empty or lacks JOYSTICK/GROUND_TRUTH data.
CommandResponseResult diagnoseCommandResponse(const std::vector<io::Recording>& fit,
                                              const std::vector<io::Recording>& validate,
                                              const CommandResponseOptions& options = {});

/// Open-loop drift of a command-driven model over `recordings` (see header comment).
DriftMetrics openLoopDrift(const std::vector<io::Recording>& recordings,
                           const model::CommandResponseParams& params, bool ignore_zero_runs,
                           const CommandResponseOptions& options = {},
                           const UnmodeledTerms* extra = nullptr);

/// Recordings cut at `fraction` of each one's command time span: (first parts, last parts),
/// for a fit / held-out split of one set of recordings (each part keeps its own streams).
std::pair<std::vector<io::Recording>, std::vector<io::Recording>> splitRecordingsInTime(
    const std::vector<io::Recording>& recs, double fraction);

/// Command stream of a recording as model input (duplicates: last wins; optional blip drop).
model::CommandSignal commandSignal(const io::Recording& rec, bool ignore_zero_runs,
                                   double max_zero_run_s = 0.1);

/// The result in the shared schema of `wheelchair diagnose` (Finding.h, issue 7): one
/// Finding per VALIDATED catalogue term (actuator_lag per channel: delay_s, time_constant_s;
/// command_gain: kind, scale; deadband: threshold_*; ignored_zero_commands: max_run_s) and one
/// `unmodeled` Finding per channel (library term -> coefficient, plus channel), each with
/// fit_before / fit_after = held-out open-loop drift (drift_10s_m, drift_60s_m,
/// heading_drift_10s_deg, heading_drift_60s_deg) and window residual RMS without / with it.
/// Sets rep.fit_before / rep.fit_after (nominal vs corrected, held-out drift) and puts the
/// analyser's own JSON into rep.validation["command_response"]. Terms removed by the held-out
/// rule are listed in rep.info["command_response_rejected"] with their parameters,
/// `rejected_by` and the `heldout` numbers, not as findings; the unmodeled finding of a
/// channel holds only its kept library terms (each passed the rule on its own).
void addCommandResponseFindings(const CommandResponseResult& r, DiagnosisReport& rep);

/// Writes the selected model into [mrclam_response] (the keys of config/mrclam.ini, read by
/// estimation::loadCommandDrivenEkfOptions): delays, time constants, deadbands, gains per
/// command kind, ignore_zero_runs; validated unmodeled terms as
/// [mrclam_response] unmodeled_v / unmodeled_omega = JSON {term: coefficient} (documented, not
/// read by the EKF).
/// addCommandResponseFindings stores the same keys in rep.config_updates, so
/// diagnosis::correctedConfig(cfg, rep) writes them too.
std::map<std::string, std::string> commandResponseConfigKeys(const CommandResponseResult& r);
void writeCommandResponseConfig(const CommandResponseResult& r, config::WheelchairConfig& cfg);

}  // namespace wheelchair::diagnosis
