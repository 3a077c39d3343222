// The effect catalogue: physics and sensor faults the simulator can add to its "truth" on top
// of the nominal vehicle, each switchable and with a magnitude (docs/effects.md).
//
// An effect is written `id:key=value,key=value`, e.g.
//   motor_asymmetry:side=right,friction_ratio=1.3
//   encoder_scale:side=left,scale=0.95
//   gyro_bias:bias_rad_s=0.01
//   sensor_delay:sensor=imu,delay_s=0.05
// The ids and parameter names are a contract shared with the diagnosis tool (which fits the
// same terms): motor_asymmetry(side, friction_ratio[, km_ratio]), encoder_scale(side, scale),
// gyro_bias(bias_rad_s), gyro_scale(scale), coulomb_friction(current_A[, side]),
// ground_slope(angle_deg[, downhill_heading_deg]), sensor_delay(sensor, delay_s),
// payload_mass(body_mass_kg), actuator_lag(delay_s, time_constant_s),
// sonar_dropout(probability[, burst_length]), pozyx_outliers(rate[, magnitude_m]).
//
// Example:
//   EffectSpec e = parseEffect("gyro_bias:bias_rad_s=0.01");
//   validateEffect(e);                 // throws std::invalid_argument on unknown id/key/value
//   double b = e.number("bias_rad_s");
#pragma once

#include <map>
#include <string>
#include <vector>

namespace wheelchair::simulation {

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

/// One parameter of an effect in the catalogue.
struct EffectParamInfo {
  std::string name;
  std::string unit;  ///< "-" for dimensionless, "enum" for a choice
  std::string description;
  std::string default_value;         ///< empty: required
  std::vector<std::string> choices;  ///< allowed values for enum parameters
  /// true: may be absent although it has no default (absent = leave the nominal value).
  bool optional = false;
};

struct EffectInfo {
  std::string id;
  std::string description;
  std::vector<EffectParamInfo> params;
};

/// All known effects, in documentation order.
const std::vector<EffectInfo>& effectCatalogue();
/// Catalogue entry of an id, or nullptr.
const EffectInfo* findEffect(const std::string& id);

/// Parses `id:key=value,...` (also `id` alone). Whitespace around tokens is ignored.
/// Throws std::invalid_argument on malformed text; does not check the catalogue.
EffectSpec parseEffect(const std::string& text);
/// Checks id, keys, required keys, numeric values and their ranges against the catalogue.
/// Throws std::invalid_argument with a message naming the effect and key.
void validateEffect(const EffectSpec& e);
/// parseEffect + validateEffect.
EffectSpec parseValidEffect(const std::string& text);
/// `id:key=value,...` with keys in alphabetical order (round-trips through parseEffect).
std::string formatEffect(const EffectSpec& e);

/// Side selector of an effect: 0 right, 1 left; `both` -> {0, 1}.
std::vector<int> effectSides(const EffectSpec& e, const std::string& key = "side");

}  // namespace wheelchair::simulation
