// Which encoder is off, decided by ground truth -- or, without it, by the motor currents --
// when the gyro cannot (issue 16).
//
// With the gyro scale free, stage 1 (gyro vs encoders) observes only c_i = g / k_i: "gyro
// scale g and a right-encoder scale k_R" and "gyro scale g' and a left-encoder scale k_L"
// predict the same residual whenever the ratio of the wheel distances is nearly constant
// (collinear columns; Diagnosis.cpp, encoderSideUndecided). The two explanations differ in the
// DISTANCE each wheel rolled, which ground-truth poses (OptiTrack, Vicon, a simulator's truth)
// measure: dead reckoning of the encoders alone with k_R (right corrected) and with k_L (left
// corrected) is compared with the truth over the fit recordings. With BOTH encoder scales
// accepted (no gyro scale) the alternatives are also "gyro scale + right" and "gyro scale +
// left" (the gyro sees only g / k_R and g / k_L).
//
//   gyro LR   (RSS_other - RSS_chosen) / sigma^2 of the two stage-1 fits, sigma^2 the
//             configured noise of one window (as encoderSideUndecided); >= chi2Quantile(1 -
//             alpha_b, 1): the gyro decides, nothing is done here.
//   truth     mean dead-reckoned position error (m) of each explanation the gyro cannot rule
//             out, over the fit recordings with encoders + GROUND_TRUTH (start aligned, each
//             side's scale applied to its metres per tick); decided when the best is at most
//             kTruthRatio (0.8) x every other -- a 20 % better prediction of where the wheels
//             went -- or when every explanation within that margin puts the larger encoder
//             error on the same side (evidence `near_tie`: only a small remainder, the other
//             encoder or the gyro scale, stays ambiguous; the best by the truth is taken).
//   dynamics  no ground truth but motor currents: the same with the RMS (A) of the motor-current
//             equation error left after a least-squares fit of all dynamic catalogue columns,
//             with each explanation's encoder scales applied (the wrong side leaves a wheel-
//             speed error the currents cannot absorb).
// JSON (rep.info["encoder_side"]): by (ground_truth | dynamics), gyro_likelihood_ratio per
// alternative, gyro_needed, mean_position_error_m | current_residual_rms_A and encoder_scales
// per explanation, decided, near_tie, explanation (e.g. "gyro_scale+right").
// When the truth picks the other side, `sel` is changed to it (the accepted candidate is
// swapped and the joint fit refitted), so the stage-1 finding, the corrections applied before
// the dynamics stage and the kinematic-calibration start all use the side the truth chose.
//
// Example:
//   auto d = resolveEncoderSide(fit_recs, 0.7, cfg, kf2, cands, sel, lags, alpha_b);
//   if (!d.evidence.empty()) rep.info["encoder_side"] = d.evidence;
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/diagnosis/Diagnosis.h"
#include "libwheelchair/diagnosis/Stages.h"
#include "libwheelchair/io/Recording.h"

#include <nlohmann/json.hpp>

#include <vector>

namespace wheelchair::diagnosis {

struct EncoderSideDecision {
  bool decided = false;  ///< the truth decided the side (sel holds it)
  nlohmann::json evidence = nlohmann::json::object();  ///< empty when not attempted
};

/// `fit_fraction` < 1: only the first fit_fraction of each recording is used (the rest is
/// the held-out part when there are no --validate recordings).
/// `dyn_fit` / `opt` (the fit streams, when they have motor currents): without ground truth the
/// dynamics decide instead -- the explanation whose encoder scales leave the smaller motor-
/// current equation error after a least-squares fit of all dynamic catalogue columns (RMS, A),
/// with the same 0.8 ratio (evidence "by": "dynamics", "current_residual_rms_A").
EncoderSideDecision resolveEncoderSide(const std::vector<io::Recording>& fit, double fit_fraction,
                                       const config::WheelchairConfig& cfg, const KinRows& k,
                                       const std::vector<Candidate>& cands, Selection& sel,
                                       int lags, double alpha_b,
                                       const std::vector<Streams>* dyn_fit = nullptr,
                                       const DiagnosisOptions* opt = nullptr);

/// The gyro scale decided against the ground-truth heading (issue 16: "use the ground truth to
/// break the gyro-vs-encoder scale ambiguity"). Stage 1 compares the gyro with the encoders'
/// yaw r (dpsi_R - dpsi_L) / l_w and so observes only g / k_yaw: a gyro scale g and an
/// effective odometric geometry (rolling radius, track) off by the same fraction give the same
/// residual. The ground truth's heading measures g alone: over windows of kGyroTruthWindow_s
/// of the truth samples (per fit recording, the gyro time stamps shifted by the stage-1 gyro
/// delay `delay_imu_s` > 0: gyro stamps lag the truth),
///     y_w = int gz dt - dpsi_truth = b dpsi_truth + bias T_w      (rad; g = 1 + b)
/// fitted by least squares with the Newey-West covariance (5 lags). With stage 1's gyro-scale
/// coefficient b1 (the gyro-vs-encoder yaw ratio - 1; sigma_1) and z = sqrt(chi2_1(1 -
/// alpha_b)), sigma_d = hypot(sigma_b, sigma_1):
///   - |b1| < z sigma_d: the truth cannot tell "the gyro is off by b1" from "the gyro is
///     right": nothing decided (`tested` false, verdict "truth_not_informative");
///   - else a gyro scale is reported only if the truth's b is significant (|b| >= z sigma_b)
///     and relevant (its contribution to the stage-1 rows, rms, >= `min_contribution_rms`);
///     otherwise b1 is the encoders' effective geometry, left to the kinematic calibration
///     against the truth poses ("encoder_geometry");
///   - reported: with stage 1's value when consistent (|b - b1| < z sigma_d, "confirmed"),
///     else with the truth's b ("gyro_and_encoder_geometry": the rest of b1 is geometry).
/// Without ground truth (or < kGyroTruthMinTurn_rad of turning in it, or < 20 windows)
/// nothing is decided (`tested` false).
/// E.g. MuJoCo, a concealed encoder scale: b1 = -0.0018 (the effective track), b = 0.00001
/// +- 0.00003: not the gyro.
inline constexpr double kGyroTruthWindow_s = 1.0;
/// Below this total |truth heading change| (rad) over the windows nothing is decided.
inline constexpr double kGyroTruthMinTurn_rad = 1.0;
struct GyroTruthDecision {
  bool tested = false;           ///< ground truth with enough turning in the fit recordings
  double b = 0, sd_b = 0;        ///< gyro scale - 1 against the truth, its 1-sigma
  double b_stage1 = 0;           ///< stage 1's gyro-vs-encoder coefficient
  bool report = false;           ///< a gyro scale is reported
  bool use_truth_value = false;  ///< ... with the truth's value b (stage 1's b1 otherwise)
  nlohmann::json evidence = nlohmann::json::object();  ///< rep.info["gyro_scale_by_truth"]
};
/// `gyro_col`: stage 1's gyro-scale column of the fit rows (rad per window), for relevance.
GyroTruthDecision gyroScaleAgainstTruth(const std::vector<Streams>& fit, double delay_imu_s,
                                        double b_stage1, double sd_stage1,
                                        const Eigen::VectorXd& gyro_col,
                                        double min_contribution_rms, double alpha_b);

}  // namespace wheelchair::diagnosis
