// Figures and index of `wheelchair diagnose --report DIR` (docs/visualization.md, "Diagnosis
// report"; issue 7 step 5): what the corrected model changes on data NOT used for fitting.
//
// Inputs are the diagnosis JSON (the documented contract of docs/discovery.md, as written by
// `--json`), the input and the corrected configuration (with [model_extensions]) and the
// rawlog paths, so the figures can also be made later from files. The corrected model is
// applied exactly as `wheelchair filter` applies it (estimation::ModelExtensions: sensor
// effects inverted on the raw data, drive-train extension currents removed from the measured
// currents, payload written into [vehicle]); a ground_slope finding is added to the drive
// model of the current residuals (the filter cannot apply it without the heading).
//
// Validation data: the --validate recordings; without them the fit recordings, whose first
// `fit_fraction` (the part the diagnosis fitted on) is shaded in the time plots and left out
// of the statistics in the legends.
//
// Files (a suffix _<k> per validation recording when there are several):
//   residual_gyro_omega.png     gyro minus encoder omega, mean over windows of window_s
//                               (the stage-1 channel), before / after the correction (rad/s)
//   residual_current_right.png  measured minus model (6) current of the right motor, zero-phase
//   residual_current_left.png   filtered at cutoff_hz like the stage-2 channel, before / after (A)
//   trajectories.png            encoder odometry, encoder v + gyro omega and the EKF with the
//                               nominal (dashed) and the corrected (solid) model, ground truth
//   trajectory_error.png        their position error against the ground truth over time
//   drift.png                   command-driven recordings (MRCLAM): open-loop drift of the
//                               command-response model before / after (from the JSON)
//   index.md                    findings with parameters +- sigma, evidence, before/after
//                               numbers of the JSON, per-channel validation statistics, the
//                               trajectory errors, the figures and the corrected configuration
//   summary.txt, diagnosis.json the command's text summary and the full JSON
//
// Ground truth in the figures: the simulator's truth (<rawlog>.truth.json) when present, else
// the recording's Pozyx / ground-truth stream mapped into the start frame by the SE(2)
// alignment of the CORRECTED EKF over the first `align_first_s` seconds (one transform for
// every curve, so the drift of the uncorrected ones stays visible).
//
// Example:
//   DiagnosisFigureOptions o;  o.out_dir = "rep";  o.summary_text = text;
//   auto r = writeDiagnosisFigures(rep.toJson(), cfg, diagnosis::correctedConfig(cfg, rep),
//                                  {"a.rawlog"}, {"b.rawlog"}, o);
#pragma once

#include "libwheelchair/effects/Effect.h"

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/diagnosis/Diagnosis.h"
#include "libwheelchair/io/Recording.h"

#include <nlohmann/json.hpp>

#include <array>
#include <string>
#include <vector>

namespace wheelchair::visualization {

struct DiagnosisFigureOptions {
  std::string out_dir;
  int width = 1000, height = 620;  ///< time plots (px); the trajectory plot is wider
  /// The diagnosis' own options (window_s, cutoff_hz, grid_rate_hz, max_gap_s, edge_trim_s,
  /// fit_fraction): the figures recompute the residuals exactly as the diagnosis did.
  diagnosis::DiagnosisOptions diagnosis_options;
  double align_first_s = 10.0;     ///< ground-truth frame without a truth file (see above)
  std::size_t max_recordings = 4;  ///< validation recordings drawn (the index lists all)
  std::string summary_text;        ///< written as summary.txt and quoted in index.md
};

struct DiagnosisFigureResult {
  std::vector<std::string> figures;  ///< PNG paths written
  std::string index_path;
  std::vector<std::string> notes;  ///< what was skipped and why
};

/// Writes the figures, index.md, summary.txt and diagnosis.json into options.out_dir
/// (created). `report` is the diagnosis JSON. Throws on an unwritable directory; a recording
/// that cannot be read or drawn, or lacks the streams a figure needs, only skips its figures
/// (said in `notes` and index.md).
DiagnosisFigureResult writeDiagnosisFigures(const nlohmann::json& report,
                                            const config::WheelchairConfig& input_cfg,
                                            const config::WheelchairConfig& corrected_cfg,
                                            const std::vector<std::string>& fit_paths,
                                            const std::vector<std::string>& validate_paths,
                                            const DiagnosisFigureOptions& options);

// ---- building blocks (for reuse and tests) ----

/// A residual over time (recording clock).
struct ResidualSeries {
  std::vector<double> t_s, r;
};

/// Gyro minus encoder angular velocity (rad/s), each the mean over consecutive windows of
/// encoder samples of about window_s: (integral of gyro_z - odometric heading change) / T;
/// windows with an encoder gap over max_gap_s ([diagnosis] max_gap_s) are left out.
ResidualSeries gyroEncoderResidual(const io::Recording& rec, const config::WheelchairConfig& cfg,
                                   double window_s, double max_gap_s);

/// Per motor (0 right, 1 left): measured current minus the drive model's current for the
/// motion seen by the encoders, on the diagnosis' own signals (signals::prepare with the
/// [diagnosis] grid, cut-off, gap and edge trim): model::DriveTrain of cfg's [vehicle] with
/// the effects of `in_model` that change the drive model without an inverse on the data
/// (ground_slope) acting on it (effects/ registry).
std::array<ResidualSeries, 2> currentResiduals(
    const io::Recording& rec, const config::WheelchairConfig& cfg,
    const DiagnosisFigureOptions& options, const std::vector<effects::EffectSpec>& in_model = {});

/// The recording and configuration the corrected model sees: [model_extensions] of
/// `corrected_cfg` applied as the filter applies them (estimation::ModelExtensions).
void applyCorrection(const io::Recording& rec, const config::WheelchairConfig& corrected_cfg,
                     io::Recording& rec_out, config::WheelchairConfig& cfg_out);

}  // namespace wheelchair::visualization
