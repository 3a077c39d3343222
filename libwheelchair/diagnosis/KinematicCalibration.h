// Diagnosis stage "kinematic calibration" (docs/discovery.md, "Real robot without a gyro"):
// whenever the recordings have wheel encoders and ground-truth poses (OptiTrack, Vicon, ...),
// with or without a gyro, the odometric geometry - effective rolling radius of each wheel and
// the track - is fitted to the ground truth and kept ONLY if it predicts held-out data better.
//
//   candidates  nested corrections of the configured geometry (identification/
//               OdometryCalibration.h, relative deltas of k_R, k_L, b): track; common scale;
//               scale + track; both wheels; both wheels + track. Each is fitted by
//               Levenberg-Marquardt on the dead-reckoned position error (start aligned).
//   choose      k-fold cross-validation over the fit recordings (one fold per recording, at
//               most 10 folds; a single recording is cut into 4 time blocks): the candidate
//               with the lowest mean position error on the left-out folds, if below the
//               nominal geometry's.
//   keep        the chosen candidate refitted on all fit data must lower the mean dead-reckoned
//               position error on the validation data (the --validate recordings, else the
//               held-out last part of each recording); otherwise nothing is reported.
//   uncertainty jackknife over the folds (1 sigma).
// The finding (effect "wheel_geometry") says it in words ("the right wheel's effective radius
// is 0.40 % larger than configured (+- 0.05 %) ...") and sets [vehicle] wheel_radius_right_m,
// wheel_radius_left_m, wheel_radius_m (their mean) and track_width_m in the corrected
// configuration.
//
// Example:
//   KinematicCalibration kc = calibrateKinematics(fit, val, cfg, opt);
//   addKinematicCalibration(kc, cfg, rep);   // finding + config updates + info
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/diagnosis/Diagnosis.h"
#include "libwheelchair/identification/OdometryCalibration.h"
#include "libwheelchair/io/Recording.h"

#include <nlohmann/json.hpp>

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
  std::vector<double> lags_s;  ///< per fit run: encoder stamps trail the truth by (s)
};

/// Runs the stage. `val` empty: fit on the first opt.fit_fraction of each recording.
KinematicCalibration calibrateKinematics(const std::vector<io::Recording>& fit,
                                         const std::vector<io::Recording>& val,
                                         const config::WheelchairConfig& cfg,
                                         const DiagnosisOptions& opt);

/// Adds the finding (if accepted), the [vehicle] config updates and info["kinematic_calibration"].
void addKinematicCalibration(const KinematicCalibration& kc, const config::WheelchairConfig& cfg,
                             DiagnosisReport& rep);

}  // namespace wheelchair::diagnosis
