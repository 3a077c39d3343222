// The project's one configuration: an INI file in MRPT CConfigFile conventions
// (config/wheelchair.ini is the commented template). This struct holds the sections every
// module shares (vehicle, sensors); module-specific sections ([estimator], [simulation],
// [identification], [diagnosis], ...) are read by those modules' own option structs from
// `ini()`. Every section is described by a key table (config/Options.h), the one place where
// a key, its unit, range and default are defined. `text()` is the full configuration as used, to be
// recorded with every result.
//
// Example:
//   auto cfg = config::WheelchairConfig::load("config/wheelchair.ini");
//   double r = cfg.vehicle.geom.wheel_radius_m;
//   EkfOptions opt; opt.loadFromConfig(cfg.ini(), "estimator");
#pragma once

#include "libwheelchair/model/VehicleParams.h"
#include "libwheelchair/sensors/Encoders.h"
#include "libwheelchair/sensors/VoltageCircuit.h"

#include "libwheelchair/config/Options.h"

#include <memory>
#include <string>

namespace wheelchair::config {

/// Sonar: pose on the body (m, deg), cone, range limits, noise. Section [sonar].
struct SonarParams {
  double x_m = 0.45, y_m = 0.0, yaw_deg = 0.0;
  double cone_half_angle_deg = 15.0;
  double min_range_m = 0.2, max_range_m = 4.0;
  double noise_m = 0.02;  ///< 1-sigma range noise (datasheet)
  double rate_hz = 10;
};

/// Pozyx UWB tag: lever arm of the tag in the body frame (m), noise. Section [pozyx].
struct PozyxParams {
  double lever_x_m = -0.20, lever_y_m = -0.10;
  double noise_m = 0.10;
  double rate_hz = 10;
};

/// Encoders: Table I plus noise/rate. Section [encoders].
struct EncoderConfig {
  sensors::EncoderParams params;
  double rate_hz = 50;
};

/// IMU gyro z. Section [imu].
struct ImuParams {
  double gyro_noise_rad_s = 0.005;  ///< 1-sigma white noise per sample
  double rate_hz = 100;
};

/// Motor current sensors and voltage circuit. Sections [motors] and [voltage_circuit].
struct MotorSensorParams {
  double current_noise_A = 0.1;
  double vrc_noise_V = 0.01;
  double rate_hz = 100;
  sensors::VoltageCircuitParams circuit;
};

struct JoystickParams {
  double rate_hz = 50;
};

class WheelchairConfig {
 public:
  model::VehicleParams vehicle;
  EncoderConfig encoders;
  ImuParams imu;
  MotorSensorParams motors;
  SonarParams sonar;
  PozyxParams pozyx;
  JoystickParams joystick;

  /// Nominal configuration (the defaults above, i.e. vehicle.md), as INI text too.
  WheelchairConfig();
  /// Copies are independent (the INI is deep-copied).
  WheelchairConfig(const WheelchairConfig& other);
  WheelchairConfig& operator=(const WheelchairConfig& other);
  WheelchairConfig(WheelchairConfig&&) = default;
  WheelchairConfig& operator=(WheelchairConfig&&) = default;
  /// Loads `path` strictly (config/Options.h): every section and key must be known to a
  /// registered key table, numbers must parse whole and lie in range, an empty file is an
  /// error; throws std::runtime_error naming file, line and key (config::setLenient(true):
  /// unknown keys/sections and an empty file only warn).
  static WheelchairConfig load(const std::string& path);
  /// The same for INI text (e.g. a recording's embedded configuration); `origin` names it
  /// in errors. An empty text is the nominal configuration.
  static WheelchairConfig fromText(const std::string& ini_text, const std::string& origin);

  /// The INI as used (after any `set`), for module-specific sections.
  const mrpt::config::CConfigFileBase& ini() const { return *ini_; }
  /// Full INI text of this configuration, including every shared key's current value.
  std::string text() const;
  /// Where it came from ("<nominal>" or a path).
  const std::string& origin() const { return origin_; }

  /// Writes the shared sections back into the INI (after code changed a value, e.g. an
  /// identified parameter), keeping every other section and key.
  void syncToIni();
  /// Sets one key in the INI (any section); values are kept as text.
  void set(const std::string& section, const std::string& key, const std::string& value);
  /// Writes text() to `path` atomically (util::AtomicFile; throws naming `path` on failure).
  void save(const std::string& path) const;

 private:
  void loadShared();
  std::shared_ptr<IniFile> ini_;
  std::string origin_ = "<nominal>";
};

}  // namespace wheelchair::config
