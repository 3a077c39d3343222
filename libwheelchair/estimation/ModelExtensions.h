// Applies the model extensions that `wheelchair diagnose` writes into a corrected
// configuration (section [model_extensions]: `effect_N = id:key=value,...`, the effect ids and
// parameter names of docs/effects.md) to a recording before it is filtered, so that the
// corrected model is what the estimator and the dead-reckoning variants see.
//
// Each effect's own inverse (effects::Effect::correct) does the work, sensor effects first:
//   encoder_scale (side, scale)   that side's cumulative ticks divided by `scale` (the counter
//                                 is unwrapped first and re-wrapped after; < 1 tick error)
//   gyro_bias (bias_rad_s)        gyro_z - bias
//   gyro_scale (scale)            gyro_z / scale
//   sensor_delay (sensor, delay_s) that stream's timestamps moved earlier by delay_s
// Drive-train effects act as extra motor current that does not accelerate the chair; they
// are removed from the measured currents (the filter's input u) using the wheel speeds of the
// corrected encoders:
//   motor_asymmetry (side, friction_ratio)  i_side -= (ratio - 1) B_m/k_m (r_G/r) u_side
//   coulomb_friction (current_A[, side])    i -= c sgn(u)   (both motors unless `side`)
//   payload_mass (body_mass_kg)             [vehicle] body_mass_kg set in the configuration
// ground_slope and actuator_lag need the state (heading, command history) and are not
// applied here (reported by `diagnose`, used by the simulator).
//
// Example:
//   auto ext = ModelExtensions::fromConfig(cfg.ini());
//   io::Recording corrected = ext.apply(rec, cfg);
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/io/Recording.h"
#include "libwheelchair/effects/Effect.h"

#include <map>
#include <string>
#include <vector>

namespace wheelchair::estimation {

class ModelExtensions {
 public:
  /// In the effect grammar shared with `wheelchair simulate` (effects/Effect.h): ids,
  /// parameter names and catalogue defaults of docs/effects.md.
  std::vector<effects::EffectSpec> effects;

  /// Reads [model_extensions] (`effect_N` keys); empty when the section is absent. Throws on a
  /// malformed entry or one outside the catalogue.
  static ModelExtensions fromConfig(const mrpt::config::CConfigFileBase& ini);
  bool empty() const { return effects.empty(); }
  /// The recording with the sensor and drive-train effects removed (see the header comment).
  io::Recording apply(const io::Recording& rec, const config::WheelchairConfig& cfg) const;
  /// A copy of `cfg` with the parametric effects (payload_mass) written into [vehicle].
  config::WheelchairConfig adjustConfig(const config::WheelchairConfig& cfg) const;
  /// Short human-readable list ("encoder_scale left 0.95, ...").
  std::string summary() const;
};

}  // namespace wheelchair::estimation
