// What an `unmodeled` finding is, in a physicist's words (issue 16 item 3): the channel it
// acts on, the class of its dependence, a physical reading with its fitted value +- 1 sigma,
// and its held-out gain. Never a catalogue name.
//
// Stage 2 (motor currents): the terms the per-motor sparse regressions kept are refitted
// jointly on both motors' rows, each term j as a FORWARD column (the same on both motors:
// [c_R; c_L], a force along the heading splits equally) and a YAW column ([c_R; -c_L], a
// moment about the axle midpoint loads the motors oppositely). With HAC t-values (threshold
// t >= 3):
//   forward and yaw both significant and equal in size -> ONE MOTOR (right if they have the
//     same sign: the left motor's coefficient f - y is zero), e.g. a current-sensor offset;
//   else forward significant -> `forward` (per-wheel terms sgn(u), |u|, u^2: `wheels`),
//        yaw significant -> `yaw`.
// Readings convert the current coefficient b (A per motor per unit of the term) with the
// nominal drive: a forward force F = -(2 r_G / (alpha r)) b x term (N), a yaw moment
// M = -(l_w r_G / (alpha r)) b x term (N m), alpha = 1 / (eta k_m): a positive b is a load.
// cos(phi) and sin(phi) on one channel are one `heading` component (amplitude, direction).
// Held-out gain of a component: validation RMS of the joint fit without it (refitted on the
// fit rows) minus with it (A).
// Stage 1 (gyro_vs_encoders): each kept term is a component of that channel.
// Collinear readings (issue 16 item 5): a stage-2 component whose column is spanned (uncentred
// R^2 >= 0.9 over fit and validation rows, with the other kept columns) by a library term of
// another channel or dependence class lists those readings in `ambiguous_with` [{channel,
// dependence, term, r2}] (at most two, best first) and says in `ambiguity` what to drive to
// tell them apart: one ambiguous group, not a confident single reading (e.g. on a `square`
// drive at one speed, v and v*|v|).
//
// Vocabulary (shared with simulation/UnknownEffects.h, the campaign's truth):
//   channel    forward | yaw | wheels | current_right | current_left | gyro_vs_encoders
//   dependence constant | sign_of_rate | rate | rate_squared | rate_product | heading |
//              acceleration | command | castor_swivel (the castors turning round at turn
//              starts and reversals: Stages.h castorSwivelMoment)
//
// Example (JSON of one component in Finding::physics):
//   {"channel": "yaw", "dependence": "sign_of_rate", "term": "sgn(omega)",
//    "coefficient": 0.181, "sd": 0.004, "unit": "A per motor",
//    "physical": {"quantity": "yaw moment", "value": 0.81, "sd": 0.02, "unit": "N m"},
//    "reading": "a dry-friction moment opposing the turn: 0.81 +- 0.02 N m ...",
//    "heldout_gain_A": 0.05}
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/diagnosis/Finding.h"
#include "libwheelchair/stats/LeastSquares.h"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <functional>
#include <string>
#include <vector>

namespace wheelchair::diagnosis {

/// Dependence class of a library term ("v" -> "rate", "sgn(u)" -> "sign_of_rate", ...).
std::string dependenceOf(const std::string& term);
/// "rate -> viscous", ... for a class.
std::string dependenceWords(const std::string& dependence);

/// The stage-2 data the joint description needs: the library column j of one motor
/// (0 right, 1 left) on the fit or validation rows, the stacked residuals [right; left] after
/// the catalogue terms, their groups and the HAC lags.
struct DynamicTermData {
  std::function<Eigen::VectorXd(int j, int side, bool fit)> column;
  Eigen::VectorXd y_fit, y_val;
  stats::Groups groups_fit;
  stats::Groups groups_val;  ///< of y_val (empty: the held-out judgement of each term is off)
  int lags = 0;
  double t_threshold = 3.0;
  /// The held-out judgement of each component (heldOutWorse), as the forward selection's
  /// held-out check (Stages.cpp heldOutCheck): testable when its predicted likelihood-ratio
  /// gain on y_val is >= min_expected_lr; then worse when the realised one is < 0; untestable,
  /// worse when the realised one is < -worse_lr (chi^2_1 at 1 - alpha).
  double min_expected_lr = 9.0;
  double worse_lr = 6.63;
};

/// A component (library term, mode: 0 forward, 1 yaw, 2 right motor only, 3 left only)
/// describeDynamicTerms left out because its own held-out prediction gets worse.
struct DroppedComponent {
  int term = 0, mode = 0;
  double lr = 0, expected_lr = 0;  ///< realised and predicted held-out likelihood ratio
  std::string channel;             ///< as the components' "channel" (forward, yaw, wheels, ...)
};

/// Components (JSON as above) of the stage-2 terms `terms` (library indices, names `names`).
/// Each component is judged on the held-out rows on its own (issue 16 item 2: never report a
/// term whose own held-out prediction gets worse): with groups_val given, the component whose
/// removal improves the held-out prediction beyond noise (DynamicTermData's rule) is left out
/// and the rest refitted, until none is; those left out go to `dropped` (if given).
nlohmann::json describeDynamicTerms(const std::vector<int>& terms,
                                    const std::vector<std::string>& names,
                                    const DynamicTermData& data,
                                    const config::WheelchairConfig& cfg,
                                    std::vector<DroppedComponent>* dropped = nullptr);

/// An out-of-catalogue term that predicts the currents better than an accepted catalogue
/// term (issue 16 item 3: "do not force it onto the nearest catalogue name").
/// The forward selection tries the catalogue first, so a load the catalogue lacks but nearly
/// spans over the speeds driven is named after it (a forward drag c v|v| as Coulomb friction
/// sgn(u); a current-sensor offset of one motor, a constant, as that motor's Coulomb friction
/// when its wheel never reverses). The order of fitting must not decide: here out-of-sample
/// prediction does. Blocked K-fold cross-validation by TIME (fold k = the same time block on
/// both motors' rows; each fold predicted by the fit on the others) of the residuals y (fit
/// rows, stacked [right; left]):
///   D   = the accepted catalogue designs (column c the term under test),
///   alt = D without c, plus library term j in c's pattern (right only, left only, or the
///         same on both motors: forward [x_R; x_L]),
///   LR_alt = n_eff log(SSE_cv(D) / SSE_cv(alt)),  LR_c = n_eff log(SSE_cv(alt) / SSE_cv(alt + c))
/// (n_eff: Bartlett effective sample size of alt's residual, lags d.lags). c is superseded by the
/// j with the largest LR_alt among the j that (a) have another dependence class than c (a
/// rate law is not replaced by another rate law: same physics, and on a multibody any of them
/// also absorbs some of the other unmodeled loads) and (b) nearly span c together with the
/// rest of D (uncentred R^2 >= min_r2, 0.9: only there did the order of fitting decide) and
/// (c) for a one-motor c, are not a load of both motors (v*|v|, sgn(omega)), when
/// LR_alt >= crit (the alternative predicts significantly better)
/// AND LR_c < crit (c adds nothing once j is there). A true catalogue term is never superseded
/// by a different shape: Coulomb friction predicts no current at standstill, an offset does.
/// Example: excite drive with a forward drag 14.9 N s^2/m^2, c = coulomb_friction/both ->
/// {term: v*|v|, lr_alt: ~1e3, lr_c: ~0}.
struct CatalogueAlternative {
  int term = -1;    ///< library index; -1: c stands
  int pattern = 0;  ///< 0 both motors, 2 right only, 3 left only
  double lr_alt = 0, lr_c = 0, sse_cv_catalogue = 0, sse_cv_alt = 0;
  double r2 = 0;  ///< uncentred R^2 of c on the alternative model
};
/// D: fit rows x accepted catalogue columns; c: the column tested (a one-column term) and its
/// dependence class; candidates: library indices to try (names: the library's names); crit:
/// the chi-square level (1 dof) both tests use.
CatalogueAlternative betterOutOfCatalogue(const Eigen::MatrixXd& D, int c,
                                          const std::string& c_dependence,
                                          const std::vector<int>& candidates,
                                          const std::vector<std::string>& names,
                                          const DynamicTermData& d, double crit,
                                          double min_r2 = 0.9, int folds = 5);

/// Components of a stage-1 (gyro_vs_encoders) unmodeled finding from its own terms.
nlohmann::json describeKinematicTerms(const Finding& f);

/// One line summarising the components ("yaw: sign of rate -> dry friction (...); ...").
std::string physicsSummary(const nlohmann::json& components);

}  // namespace wheelchair::diagnosis
