// Diagnosis stage "kinematic calibration" (docs/discovery.md, "Real robot without a gyro"):
// whenever the recordings have wheel encoders and ground-truth poses (OptiTrack, Vicon, ...),
// with or without a gyro, the odometric geometry - effective rolling radius of each wheel, the
// track and the travel angle - is fitted to the ground truth and kept ONLY if it predicts
// held-out data better.
//
//   candidates  nested corrections of the configured geometry (identification/
//               OdometryCalibration.h, relative deltas of k_R, k_L, b): track; common scale;
//               scale + track; both wheels; both wheels + track. Each is fitted by
//               Levenberg-Marquardt on the dead-reckoned position error (start aligned);
//               and "heading-ls" / "heading+scale": the two-step least squares (heading
//               rates from heading increments, then the track from displacement increments),
//               optionally with one common scale refitted on the positions. Every candidate
//               also fits the travel angle beta (OdometryGeometry::travel_angle_rad: the body
//               travels at heading + beta; a motion-capture frame rotated off the axle or an
//               axle not square to the body), a rotation of each dead-reckoned run about its
//               start that no wheel geometry can produce.
//   timing      each fit run's truth is re-sampled at the encoder-lag-corrected times
//               (identification::estimateTimeOffset, +-0.25 s) before fitting: a lag biases
//               fits during fast turns; the held-out check uses the runs as recorded.
//   choose      k-fold cross-validation over the fit recordings (at most 10 folds of
//               contiguous recordings in the order given, so that runs of one experiment stay
//               together; a single recording is cut into 4 time blocks): the candidate with the
//               lowest mean position error on the left-out folds, if 5 % below the nominal
//               geometry's.
//   misspecification  a Hausman-type check before choosing: if the model is right, the
//               whole-run fit and the increment-domain fit ("heading-ls") estimate the same
//               turn gain G = (k_R + k_L) / (2 b) (heading per tick of wheel difference). The
//               fold-wise relative difference of G between the best whole-run candidate and
//               "heading-ls" (same folds) is jackknifed; beyond kMaxGainDisagreementZ sigma
//               (and >= kMinRelativeChange, the resolution of a reported correction) the
//               kinematics are misspecified: some heading change is not proportional to the
//               wheel-tick difference (slip or a transient in turns on the spot, ...). The
//               whole-run fit then folds it into the track, where it repeats in left-out runs
//               of the same path kind (so cross-validation on them cannot see it) but not on
//               other paths; the increment fit leaves it in the per-interval residual. So only
//               the increment-domain candidate may be chosen, and the finding says why.
//   keep        the chosen candidate refitted on all fit data must lower the mean dead-reckoned
//               position error on the validation data (the --validate recordings, else the
//               held-out last part of each recording); otherwise nothing is reported.
//   uncertainty jackknife over the folds (1 sigma).
//   established a whole-run candidate's radius / track change within kEstablishedZ sigma of
//               the configured value is not reported: the candidate is refitted without it
//               (at the configured value) and judged again (`keep`).
// The finding (effect "wheel_geometry") says it in words ("the right wheel's effective radius
// is 0.40 % larger than configured (+- 0.05 %) ...; the body travels 0.55 deg (+- 0.03 deg) to
// the left of the heading the ground truth measures ...") and sets [vehicle]
// wheel_radius_right_m, wheel_radius_left_m, wheel_radius_m (their mean), track_width_m and
// odometry_travel_angle_rad in the corrected configuration.
//
// Example:
//   KinematicCalibration kc = calibrateKinematics(fit, val, cfg, opt);
//   addKinematicCalibration(kc, cfg, rep);   // finding + config updates + info
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/diagnosis/Diagnosis.h"
#include "libwheelchair/diagnosis/Stages.h"
#include "libwheelchair/identification/OdometryCalibration.h"
#include "libwheelchair/io/Recording.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <string>
#include <vector>

namespace wheelchair::diagnosis {

inline constexpr const char* kWheelGeometryEffect = "wheel_geometry";

struct KinematicCalibration {
  bool tested = false;     ///< the recordings allowed the test (encoders + ground truth)
  std::string not_tested;  ///< why not, when !tested
  bool accepted = false;   ///< a correction that improves the held-out prediction
  std::string model;       ///< chosen candidate (track, scale, scale+track, wheels, wheels+track)
  identification::OdometryGeometry nominal, fitted;
  double sd_rel[3] = {0, 0, 0};  ///< 1-sigma of the relative corrections of k_R, k_L, b
  identification::OdometryError heldout_before, heldout_after;
  int fit_runs = 0, validation_runs = 0, folds = 0;
  nlohmann::json candidates = nlohmann::json::array();  ///< per candidate: CV error
  std::string validation;                               ///< what the held-out data were
  std::string rejected;                                 ///< why a chosen correction is not reported
  std::vector<double> lags_s;      ///< per fit run: encoder stamps trail the truth by (s)
  double sd_travel_angle_rad = 0;  ///< 1-sigma of fitted.travel_angle_rad
  /// Specification check: the best whole-run and increment-domain candidates, the relative
  /// difference of their turn gains (whole-run / increments - 1) and its jackknife 1-sigma.
  std::string whole_run_model, increment_model;
  double gain_difference_rel = 0, gain_difference_sd = 0;
  /// |difference| > kMaxGainDisagreementZ sigma and >= kMinRelativeChange
  bool whole_run_misspecified = false;
  /// The chosen candidate's parameters inside their uncertainty (kEstablishedZ), left at the
  /// configured geometry: what was dropped and why (empty: none)
  std::string rejected_parameters;
  /// foldRadiusIntoEncoderScale: what was folded (null: nothing)
  nlohmann::json folded;
  /// slopeYawCreep (only when the dynamics named a slope): the test's numbers (null: not run)
  nlohmann::json slope_creep;
};

/// A slope turns the chair downhill (issue 16): gravity's side component on the centre of mass
/// and on the tyres gives a yaw creep A sin(h - phi) (h the downhill heading the dynamics
/// named, start frame) that is not proportional to the wheel-tick difference. Whole-run or
/// increment fits of a flat-floor geometry fold it into the track or the radius ratio. Test,
/// over non-overlapping 1-s windows of the fit runs: the truth's heading increment minus the
/// odometric one (geometry g),
///     y = gamma dphi_odo + c T  [+ A sin(h - phi) T],
/// (phi the truth heading at the window's middle relative to the run's first, i.e. the start
/// frame of the dynamics' heading; T the window's length) with and without the creep column;
/// LR = n log(RSS_without / RSS_with) against chi2_1(1 - alpha). JSON {windows,
/// likelihood_ratio, needed, creep_rad_s (A), turn_gain_rel_without / _with (gamma),
/// significant}. MuJoCo excite 653117 (slope 1.53 deg): A = 0.0009 rad/s, LR 15 (the whole-run
/// `track` +0.57 % it would have reported is the creep).
nlohmann::json slopeYawCreep(const std::vector<identification::OdometryRun>& runs,
                             const identification::OdometryGeometry& g, double downhill_rad,
                             double alpha);

/// A candidate must lower the cross-validated error by this fraction of the nominal
/// geometry's to be chosen (smaller gains are within the run-to-run scatter), and the held-out
/// error by kMinHeldOutGain to be reported.
inline constexpr double kMinCvGain = 0.05;
inline constexpr double kMinHeldOutGain = 0.01;
/// ... and change some parameter by at least this fraction (0.1 %: 1 cm over 10 m driven):
/// smaller corrections are within the numerical and ground-truth resolution.
inline constexpr double kMinRelativeChange = 1e-3;
/// Whole-run and increment-domain fits disagree on the turn gain by more than this many
/// jackknife sigmas: the wheel kinematics are misspecified for whole-run fitting (see above).
inline constexpr double kMaxGainDisagreementZ = 3.0;
/// A geometry parameter (relative radius or track change) is reported only when it is at least
/// this many jackknife sigmas from the configured value; inside, it stays at the configured
/// value and the chosen candidate is refitted and judged without it (the travel angle alone
/// when no geometry parameter is established: model "travel_angle").
inline constexpr double kEstablishedZ = 2.0;

/// Runs the stage. `val` empty: fit on the first opt.fit_fraction of each recording.
/// `stage1`: encoder scales already found against the gyro (stage 1); the stage then tests
/// what remains (the configured geometry with those scales applied).
/// `slope_downhill_rad`: the downhill heading of a `ground_slope` the dynamics stage named (NaN:
/// none); then an accepted geometry is
/// tested against the slope's yaw creep (slopeYawCreep, on the configured geometry): when the
/// creep is significant the geometry cannot be told from it on these drives, it is not
/// reported (kc.rejected) and addKinematicCalibration says so in info.cannot_tell (what would
/// tell them apart: the same path on the flat, or across the slope in both directions).
KinematicCalibration calibrateKinematics(const std::vector<io::Recording>& fit,
                                         const std::vector<io::Recording>& val,
                                         const config::WheelchairConfig& cfg,
                                         const DiagnosisOptions& opt,
                                         const Corrections* stage1 = nullptr,
                                         double slope_downhill_rad = std::nan(""));

/// One observable, one name (issue 16): a wheel's metres per tick is its effective radius over
/// its encoder's scale, so without an independent speed reference for that wheel a radius
/// difference between the wheels and an encoder scale are the same fact. When stage 1 named an
/// `encoder_scale` on ONE side (the other encoder agrees with the gyro) and the accepted
/// calibration gives that side's radius a relative change dS different from the other side's
/// dO, the difference is folded into the named scale,
///     k_s' = k_s (1 + dO) / (1 + dS),
/// and that side's radius gets the other's change dO (the odometry, metres per tick per side,
/// and so every held-out number are unchanged). The encoder finding's scale (its uncertainty
/// combined with the radius' jackknife sigma), `corr.enc_scale[s]` and kc.nominal follow; when
/// no geometry change of at least kMinRelativeChange (nor travel angle) remains, nothing is
/// reported as `wheel_geometry` (kc.accepted = false, kc.rejected says why). JSON:
/// info.kinematic_calibration.folded_into_encoder_scale {side, scale_before, scale_after,
/// radius_rel_before, radius_rel_after}. Example (MuJoCo excite 368766, left encoder 1.01839
/// concealed): stage 1 left 1.01876, calibration radii -0.113 % right / -0.069 % left ->
/// left encoder 1.01831, radii -0.113 % both (the engine rolls at -0.127 %).
void foldRadiusIntoEncoderScale(KinematicCalibration& kc, Corrections& corr, DiagnosisReport& rep);

/// Adds the finding (if accepted), the [vehicle] config updates and info["kinematic_calibration"].
void addKinematicCalibration(const KinematicCalibration& kc, const config::WheelchairConfig& cfg,
                             DiagnosisReport& rep);

}  // namespace wheelchair::diagnosis
