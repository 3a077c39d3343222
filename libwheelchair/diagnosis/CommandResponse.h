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
// Every accepted term must then reduce the residual on the VALIDATION recordings (else it is
// reported with validated = false and not used). What is left is regressed on a library of
// command features (1, v_cmd, omega_cmd, |omega_cmd|, v_cmd |omega_cmd|) per channel; terms
// passing the same evidence test are reported as `unmodeled` with their channel.
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

#include "libwheelchair/io/Recording.h"
#include "libwheelchair/model/CommandDriven.h"

#include <nlohmann/json.hpp>

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
  double max_gt_gap_s = 0.5;            ///< ground-truth gap that invalidates a window end
};

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
};

struct DriftMetrics {
  double drift_10s_m = 0, drift_60s_m = 0;
  double heading_drift_10s_deg = 0, heading_drift_60s_deg = 0;
  std::size_t n_10s = 0, n_60s = 0;
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
  std::size_t fit_windows = 0, validation_windows = 0;
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
                           const CommandResponseOptions& options = {});

/// Command stream of a recording as model input (duplicates: last wins; optional blip drop).
model::CommandSignal commandSignal(const io::Recording& rec, bool ignore_zero_runs,
                                   double max_zero_run_s = 0.1);

}  // namespace wheelchair::diagnosis
