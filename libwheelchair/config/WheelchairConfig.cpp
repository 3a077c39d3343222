#include "libwheelchair/config/WheelchairConfig.h"

#include <fmt/format.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace wheelchair::config {

namespace {

// The shared keys, bound to the struct members once so that load and sync cannot diverge.
struct Binding {
  const char* section;
  const char* key;
  double* dval = nullptr;
  int* ival = nullptr;
  bool* bval = nullptr;
};

std::vector<Binding> bindings(WheelchairConfig& c) {
  auto& v = c.vehicle;
  auto& g = v.geom;
  auto& e = c.encoders.params;
  auto& vc = c.motors.circuit;
  return {
      {"vehicle", "wheel_radius_m", &g.wheel_radius_m},
      {"vehicle", "wheel_radius_right_m", &g.wheel_radius_right_m},
      {"vehicle", "wheel_radius_left_m", &g.wheel_radius_left_m},
      {"vehicle", "track_width_m", &g.track_width_m},
      {"vehicle", "gear_ratio", &g.gear_ratio},
      {"vehicle", "wheel_mass_kg", &g.wheel_mass_kg},
      {"vehicle", "body_mass_kg", &g.body_mass_kg},
      {"vehicle", "motor_inertia_kg_m2", &v.motor_inertia_kg_m2},
      {"vehicle", "wheel_inertia_kg_m2", &v.wheel_inertia_kg_m2},
      {"vehicle", "yaw_inertia_kg_m2", &v.yaw_inertia_kg_m2},
      {"vehicle", "motor_viscous_Nm_s_rad", &v.motor_viscous_Nm_s_rad},
      {"vehicle", "torque_constant_Nm_A", &v.torque_constant_Nm_A},
      {"vehicle", "gearbox_efficiency", &v.gearbox_efficiency},
      {"vehicle", "armature_resistance_ohm", &v.armature_resistance_ohm},
      {"encoders", "encoder_pulley_teeth", nullptr, &e.encoder_pulley_teeth},
      {"encoders", "wheel_pulley_teeth", nullptr, &e.wheel_pulley_teeth},
      {"encoders", "counts_per_rev", nullptr, &e.counts_per_rev},
      {"encoders", "rate_hz", &c.encoders.rate_hz},
      {"imu", "gyro_noise_rad_s", &c.imu.gyro_noise_rad_s},
      {"imu", "rate_hz", &c.imu.rate_hz},
      {"motors", "current_noise_A", &c.motors.current_noise_A},
      {"motors", "vrc_noise_V", &c.motors.vrc_noise_V},
      {"motors", "rate_hz", &c.motors.rate_hz},
      {"voltage_circuit", "R1_ohm", &vc.R1_ohm},
      {"voltage_circuit", "R2_ohm", &vc.R2_ohm},
      {"voltage_circuit", "R3_ohm", &vc.R3_ohm},
      {"voltage_circuit", "R4_ohm", &vc.R4_ohm},
      {"voltage_circuit", "C_F", &vc.C_F},
      {"voltage_circuit", "has_zener", nullptr, nullptr, &vc.has_zener},
      {"voltage_circuit", "zener_knee_V", &vc.zener_knee_V},
      {"voltage_circuit", "zener_current_at_knee_A", &vc.zener_current_at_knee_A},
      {"voltage_circuit", "zener_slope_V", &vc.zener_slope_V},
      {"sonar", "x_m", &c.sonar.x_m},
      {"sonar", "y_m", &c.sonar.y_m},
      {"sonar", "yaw_deg", &c.sonar.yaw_deg},
      {"sonar", "cone_half_angle_deg", &c.sonar.cone_half_angle_deg},
      {"sonar", "min_range_m", &c.sonar.min_range_m},
      {"sonar", "max_range_m", &c.sonar.max_range_m},
      {"sonar", "noise_m", &c.sonar.noise_m},
      {"sonar", "rate_hz", &c.sonar.rate_hz},
      {"pozyx", "lever_x_m", &c.pozyx.lever_x_m},
      {"pozyx", "lever_y_m", &c.pozyx.lever_y_m},
      {"pozyx", "noise_m", &c.pozyx.noise_m},
      {"pozyx", "rate_hz", &c.pozyx.rate_hz},
      {"joystick", "rate_hz", &c.joystick.rate_hz},
  };
}

std::string formatValue(double x) { return fmt::format("{}", x); }

// Strict number parsing: the whole value must be a finite number.
double parseNumber(const std::string& text, const std::string& where) {
  const char* s = text.c_str();
  char* end = nullptr;
  errno = 0;
  const double x = std::strtod(s, &end);
  while (end && (*end == ' ' || *end == '\t' || *end == '\r')) ++end;
  if (end == s || (end && *end != '\0') || errno == ERANGE || !std::isfinite(x)) {
    throw std::runtime_error(fmt::format("{}: '{}' is not a finite number", where, text));
  }
  return x;
}

}  // namespace

WheelchairConfig::WheelchairConfig() : ini_(std::make_shared<mrpt::config::CConfigFileMemory>()) {
  syncToIni();
}

WheelchairConfig::WheelchairConfig(const WheelchairConfig& o)
    : vehicle(o.vehicle),
      encoders(o.encoders),
      imu(o.imu),
      motors(o.motors),
      sonar(o.sonar),
      pozyx(o.pozyx),
      joystick(o.joystick),
      ini_(std::make_shared<mrpt::config::CConfigFileMemory>(o.text())),
      origin_(o.origin_) {}

WheelchairConfig& WheelchairConfig::operator=(const WheelchairConfig& o) {
  if (this != &o) *this = WheelchairConfig(o);
  return *this;
}

WheelchairConfig WheelchairConfig::load(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(fmt::format("{}: cannot open configuration file", path));
  std::stringstream ss;
  ss << in.rdbuf();
  return fromText(ss.str(), path);
}

WheelchairConfig WheelchairConfig::fromText(const std::string& ini_text, const std::string& origin) {
  WheelchairConfig c;
  c.ini_ = std::make_shared<mrpt::config::CConfigFileMemory>(ini_text);
  c.origin_ = origin;
  c.loadShared();
  c.syncToIni();  // keys absent from the file now show their (default) values in text()
  return c;
}

void WheelchairConfig::loadShared() {
  for (auto& b : bindings(*this)) {
    const std::string raw = ini_->read_string(b.section, b.key, "", false);
    if (raw.empty()) continue;  // missing key: keep the nominal value
    const std::string where = fmt::format("{}: [{}] {}", origin_, b.section, b.key);
    const double x = parseNumber(raw, where);
    if (b.dval) *b.dval = x;
    if (b.ival) {
      if (x != std::floor(x)) throw std::runtime_error(where + ": expected an integer");
      *b.ival = static_cast<int>(x);
    }
    if (b.bval) *b.bval = (x != 0);
  }
  const auto& g = vehicle.geom;
  auto positive = [&](double x, const char* what) {
    if (!(x > 0)) throw std::runtime_error(fmt::format("{}: {} must be > 0", origin_, what));
  };
  positive(g.wheel_radius_m, "[vehicle] wheel_radius_m");
  positive(g.track_width_m, "[vehicle] track_width_m");
  if (g.wheel_radius_right_m < 0 || g.wheel_radius_left_m < 0)
    throw std::runtime_error(fmt::format(
        "{}: [vehicle] wheel_radius_right_m / wheel_radius_left_m must be >= 0 (0 = wheel_radius_m)",
        origin_));
  positive(g.gear_ratio, "[vehicle] gear_ratio");
  positive(vehicle.torque_constant_Nm_A, "[vehicle] torque_constant_Nm_A");
  positive(vehicle.gearbox_efficiency, "[vehicle] gearbox_efficiency");
  positive(encoders.params.counts_per_rev, "[encoders] counts_per_rev");
  positive(encoders.params.encoder_pulley_teeth, "[encoders] encoder_pulley_teeth");
  positive(encoders.params.wheel_pulley_teeth, "[encoders] wheel_pulley_teeth");
}

void WheelchairConfig::syncToIni() {
  for (auto& b : bindings(*this)) {
    std::string v;
    if (b.dval) v = formatValue(*b.dval);
    if (b.ival) v = std::to_string(*b.ival);
    if (b.bval) v = *b.bval ? "1" : "0";
    ini_->write(b.section, b.key, v);
  }
}

void WheelchairConfig::set(const std::string& section, const std::string& key,
                           const std::string& value) {
  ini_->write(section, key, value);
  loadShared();
}

std::string WheelchairConfig::text() const { return ini_->getContent(); }

void WheelchairConfig::save(const std::string& path) const {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error(fmt::format("{}: cannot write", tmp));
    out << "# Written by libwheelchair from " << origin_ << "\n" << text();
    if (!out.flush()) throw std::runtime_error(fmt::format("{}: write failed", tmp));
  }
  std::filesystem::rename(tmp, path);
}

}  // namespace wheelchair::config
