// One type per effect of the catalogue (docs/effects.md): the physics and sensor faults the
// nominal model leaves out. Like a GTSAM factor, an effect is data plus what to do with it:
//
//   parameters   typed, with units, defaults and ranges (EffectInfo; parsed from
//                `id:key=value,...` in the INI's [model_extensions] and `simulate --effect`,
//                written to JSON as {"id", "params", "text"})
//   truth        how it acts on the simulated truth (actOnTruth: the drive train, the power
//                module, the sensors' distortions)
//   inverse      how a recording is corrected for it (correct: raw data in, the effect-free
//                data out; effects that need the state, e.g. a slope, have none)
//   residual     the columns and terms the diagnosis fits (kinematicColumns / driveColumns:
//                the derivative of the residual of a stage with respect to the term's
//                coefficient; terms: which columns, plausibility, coefficient <-> parameter)
//   words        its description (EffectInfo::description) and a fitted finding's parameters
//                and words (describe)
//
// The registry (effectRegistry) lists them in the order the diagnosis tries its terms; the
// simulator, ModelExtensions, the diagnosis and the figures iterate it instead of testing ids.
//
// Example:
//   EffectSpec e = parseValidEffect("gyro_bias:bias_rad_s=0.01");
//   TruthModel t = TruthModel::nominal(cfg.vehicle, 0.0, 0.1);
//   findEffect(e.id)->actOnTruth(e, t);        // t.sensors.gyro_bias_rad_s == 0.01
//   findEffect(e.id)->correct(e, recording, ctx);  // gyro_z - 0.01
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/io/Recording.h"
#include "libwheelchair/model/DriveDynamics.h"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <functional>
#include <map>
#include <string>
#include <vector>

namespace wheelchair::effects {

/// An effect as written: `id` and its parameters as text (`id:key=value,...`).
struct EffectSpec {
  std::string id;
  std::map<std::string, std::string> params;

  /// Value of a parameter as a number (the catalogue default when absent); throws
  /// std::invalid_argument when it is not a finite number or absent without default.
  double number(const std::string& key) const;
  /// Value as text (the catalogue default when absent).
  std::string text(const std::string& key) const;
  bool has(const std::string& key) const { return params.count(key) > 0; }
  bool operator==(const EffectSpec& o) const { return id == o.id && params == o.params; }
};

/// One typed parameter of an effect.
struct EffectParamInfo {
  std::string name;
  std::string unit;  ///< "-" for dimensionless, "enum" for a choice
  std::string description;
  std::string default_value;         ///< empty: required
  std::vector<std::string> choices;  ///< allowed values for enum parameters
  /// true: may be absent although it has no default (absent = leave the nominal value).
  bool optional = false;
  /// Allowed numeric range: (lo, hi] or [lo, hi] (lo_inclusive); unchecked when lo > hi.
  double lo = 1, hi = 0;
  bool lo_inclusive = true;
};

struct EffectInfo {
  std::string id;
  std::string description;
  std::vector<EffectParamInfo> params;
};

/// The sensor streams of a recording, in this order (sensor_delay's `sensor`).
const std::vector<std::string>& streamNames();
/// Index of a stream name in streamNames(); throws std::invalid_argument when unknown.
int streamIndex(const std::string& name);

/// What effects change on the sensor side of the truth simulator.
struct SensorDistortion {
  double encoder_scale[2] = {1, 1};  ///< reported / true wheel rotation (right, left)
  /// encoder_scale from_s (s since the start; 0: from the start): a step fault; before it the
  /// side reads true, from the first sample at or after it the reported angle is
  /// anchor + scale (psi - anchor), anchor the true angle there (the count stays continuous).
  double encoder_from_s[2] = {0, 0};
  double gyro_bias_rad_s = 0, gyro_scale = 1;
  double delay_s[6] = {0, 0, 0, 0, 0, 0};  ///< stamp lag per stream (streamNames order)
  double dropout_probability = 0, dropout_burst = 3;
  double outlier_rate = 0, outlier_magnitude_m = 1;
  double current_offset_A[2] = {0, 0};  ///< added to the measured motor currents (right, left)
};

/// The truth an effect acts on: the true drive train, the power module's response and the
/// sensors' distortions.
struct TruthModel {
  model::DriveTrain drive;
  double actuator_delay_s = 0, actuator_time_constant_s = 0.1;
  SensorDistortion sensors;
};

/// What a correction may look up: the configuration and the corrected encoders' mean rim
/// speeds (m/s, right and left) at a time (zero-order hold over encoder intervals).
struct CorrectionContext {
  const config::WheelchairConfig& cfg;
  std::function<Eigen::Vector2d(double t_s)> rim_speeds;
};

/// When a correction runs: sensor corrections first (raw data), then drive-train corrections
/// (they need the corrected encoders' speeds); `none`: no inverse on a recording.
enum class CorrectionPhase { none, sensor, drive };

/// One window of the diagnosis' stage 1 (kinematic consistency), with the current
/// corrections applied: y = integral of the gyro over the window - (dR - dL) / l_w (rad).
struct KinematicWindow {
  double T_s = 0;               ///< window length
  double dR_m = 0, dL_m = 0;    ///< rim distances of the window (scale-corrected)
  double track_m = 0;           ///< l_w
  double gyro_rate_change = 0;  ///< gyro omega(t1) - omega(t0) (rad/s)
};

/// One grid sample of one motor's equation error in the diagnosis' stage 2:
/// y = filtered current - model current (A).
struct DriveSample {
  int side = 0;                     ///< 0 right, 1 left
  double u_m_s = 0;                 ///< this side's rim speed (filtered)
  double sgn_u = 0;                 ///< tanh(u / eps), filtered like the current
  double vdot_m_s2 = 0;             ///< chair acceleration
  double cos_phi = 1, sin_phi = 0;  ///< heading in the start frame, filtered
  double dpred_A_s = 0;             ///< time derivative of the model current
  // Constants of the nominal vehicle.
  double theta5 = 0;  ///< B_m / k_m (A s / rad)
  double alpha = 0;   ///< 1 / (eta k_m) (A / N m)
  double r_m = 0, rG = 0;
  double Mg2_N = 0;  ///< (m_b + 2 m_w) g / 2
};

/// A column of a stage's regression: its name and value per window or sample.
struct KinematicColumn {
  std::string name;
  std::function<double(const KinematicWindow&)> value;
};
struct DriveColumn {
  std::string name;
  std::function<double(const DriveSample&)> value;
};

enum class Stage { kinematic, dynamic };

/// A term the diagnosis tests: coefficients, each the sum of named columns of its stage.
struct ResidualTerm {
  std::string name;  ///< e.g. "encoder_scale/right"
  Stage stage = Stage::kinematic;
  std::vector<std::vector<std::string>> coefficients;  ///< columns summed per coefficient
  std::vector<std::string> conflicts;  ///< terms that cannot be accepted together with it
  std::function<bool(const Eigen::VectorXd& coef)> plausible;
  /// The coefficients a true effect of this spec gives (first order; for the tests).
  std::function<Eigen::VectorXd(const EffectSpec&, const config::WheelchairConfig&)> coefficientOf;
};

/// The accepted terms of one diagnosis stage, as an effect's words need them: the first
/// coefficient of every accepted term and its 1-sigma, by term name.
struct TermFit {
  const config::WheelchairConfig* cfg = nullptr;
  std::map<std::string, double> coef, sigma;
  double delay_s = 0;  ///< refined stream delay (> 0: the stream of the term lags the encoders)
  bool has(const std::string& term) const { return coef.count(term) > 0; }
  double value(const std::string& term) const {
    auto it = coef.find(term);
    return it == coef.end() ? 0.0 : it->second;
  }
  double sd(const std::string& term) const {
    auto it = sigma.find(term);
    return it == sigma.end() ? 0.0 : it->second;
  }
};

/// What a finding of an accepted term says: the effect's parameters (the names of info()),
/// their 1-sigma, where it shows (empty: the stage's channels) and words with numbers.
struct FindingText {
  nlohmann::json parameters = nlohmann::json::object();
  nlohmann::json uncertainty = nlohmann::json::object();
  std::vector<std::string> channels;
  std::string description;
};

/// What the terms depend on.
struct TermOptions {
  double body_mass_kg = 0;   ///< the configured m_b (payload plausibility)
  bool enable_delay = true;  ///< stream delays are fitted
};

class Effect {
 public:
  virtual ~Effect() = default;
  /// Id, words, typed parameters.
  virtual const EffectInfo& info() const = 0;
  const std::string& id() const { return info().id; }
  /// Checks across parameters beyond their ranges (throws std::invalid_argument).
  virtual void validate(const EffectSpec&) const {}
  /// How it acts on the truth.
  virtual void actOnTruth(const EffectSpec& e, TruthModel& t) const = 0;
  /// When correct() runs; `none`: a recording is not corrected for it.
  virtual CorrectionPhase correctionPhase() const { return CorrectionPhase::none; }
  /// The recording with the effect removed (the inverse of actOnTruth on the data).
  virtual void correct(const EffectSpec&, io::Recording&, const CorrectionContext&) const {}
  /// Parametric effects: the configuration with the effect written into it.
  virtual void adjustConfig(const EffectSpec&, config::WheelchairConfig&) const {}
  /// Regression columns of the diagnosis stages.
  virtual std::vector<KinematicColumn> kinematicColumns() const { return {}; }
  virtual std::vector<DriveColumn> driveColumns() const { return {}; }
  /// Terms the diagnosis tests.
  virtual std::vector<ResidualTerm> residualTerms(const TermOptions&) const { return {}; }
  /// An accepted term as the effect's parameters and words: `term` its name, b and C its
  /// coefficients and their covariance, `fit` the stage's other accepted terms.
  virtual FindingText describe(const std::string& /*term*/, const Eigen::VectorXd& /*b*/,
                               const Eigen::MatrixXd& /*C*/, const TermFit& /*fit*/) const {
    return {};
  }
};

/// All effects, in the order the diagnosis tries their terms: sensor effects of the kinematic
/// stage, drive-train effects of the dynamic stage, sensor_delay (both), then the rest.
const std::vector<const Effect*>& effectRegistry();
/// Registry entry of an id, or nullptr.
const Effect* findEffect(const std::string& id);
/// The registry's descriptions, in its order.
const std::vector<EffectInfo>& effectCatalogue();

/// Parses `id:key=value,...` (also `id` alone). Whitespace around tokens is ignored.
/// Throws std::invalid_argument on malformed text; does not check the catalogue.
EffectSpec parseEffect(const std::string& text);
/// Checks keys, required keys, numbers and ranges against `info` (throws naming effect and key).
void validateAgainst(const EffectInfo& info, const EffectSpec& e);
/// Checks id, keys, values and ranges against the registry (and the effect's own checks).
void validateEffect(const EffectSpec& e);
/// parseEffect + validateEffect.
EffectSpec parseValidEffect(const std::string& text);
/// `id:key=value,...` with keys in alphabetical order (round-trips through parseEffect).
std::string formatEffect(const EffectSpec& e);
/// {"id", "params", "text"} and back.
nlohmann::json effectToJson(const EffectSpec& e);
EffectSpec effectFromJson(const nlohmann::json& j);

/// Side selector of an effect: 0 right, 1 left; `both` -> {0, 1}.
std::vector<int> effectSides(const EffectSpec& e, const std::string& key = "side");
/// The sides' names.
const std::vector<std::string>& sideChoices();      ///< right, left
const std::vector<std::string>& sideChoicesBoth();  ///< right, left, both

/// The effects applied to a truth model, in the given order (ids outside the registry, e.g. the
/// MuJoCo-only ones, are left to their engine).
void actOnTruth(const std::vector<EffectSpec>& effects, TruthModel& t);

}  // namespace wheelchair::effects
