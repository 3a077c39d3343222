#include "libwheelchair/config/WheelchairConfig.h"

#include "libwheelchair/util/AtomicFile.h"
#include "libwheelchair/util/Text.h"

#include <fmt/format.h>

#include <iostream>

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

// The shared sections: one key table each, bound to the struct members (load, sync, dump
// and the file-level key check all come from these).
std::vector<Options> tables(WheelchairConfig& c) {
  auto& v = c.vehicle;
  auto& g = v.geom;
  auto& e = c.encoders.params;
  auto& vc = c.motors.circuit;
  const Range pos = Range::above(0), nonneg = Range::atLeast(0);
  std::vector<Options> t;
  t.push_back(
      Options("vehicle")
          .real("wheel_radius_m", g.wheel_radius_m, "drive-wheel radius r (m)", pos)
          .real("wheel_radius_right_m", g.wheel_radius_right_m,
                "right wheel's effective rolling radius for odometry (m; 0: wheel_radius_m)",
                nonneg)
          .real("wheel_radius_left_m", g.wheel_radius_left_m,
                "left wheel's effective rolling radius for odometry (m; 0: wheel_radius_m)", nonneg)
          .real("odometry_travel_angle_rad", g.odometry_travel_angle_rad,
                "direction of travel relative to the ground truth's heading (rad, + left; "
                "odometry calibration only)")
          .real("track_width_m", g.track_width_m, "distance between the drive wheels l_w (m)", pos)
          .real("gear_ratio", g.gear_ratio, "motor turns per wheel turn r_G (-)", pos)
          .real("wheel_mass_kg", g.wheel_mass_kg, "mass of one drive wheel m_w (kg)", nonneg)
          .real("body_mass_kg", g.body_mass_kg, "chair body with user m_b (kg)", nonneg)
          .real("motor_inertia_kg_m2", v.motor_inertia_kg_m2, "motor rotor inertia J_m (kg m^2)",
                nonneg)
          .real("wheel_inertia_kg_m2", v.wheel_inertia_kg_m2, "drive-wheel inertia I_w,zz (kg m^2)",
                nonneg)
          .real("yaw_inertia_kg_m2", v.yaw_inertia_kg_m2, "body yaw inertia I_zz (kg m^2)", nonneg)
          .real("motor_viscous_Nm_s_rad", v.motor_viscous_Nm_s_rad,
                "motor viscous friction B_m (N m s/rad)", nonneg)
          .real("torque_constant_Nm_A", v.torque_constant_Nm_A, "motor torque constant k_m (N m/A)",
                pos)
          .real("gearbox_efficiency", v.gearbox_efficiency, "gearbox efficiency eta_G (-)",
                Range{0, 1, true, false})
          .real("armature_resistance_ohm", v.armature_resistance_ohm,
                "motor armature resistance R_m (ohm)", nonneg));
  t.push_back(Options("encoders")
                  .integer("encoder_pulley_teeth", e.encoder_pulley_teeth,
                           "teeth of the encoder-shaft pulley N_ep (-)", pos)
                  .integer("wheel_pulley_teeth", e.wheel_pulley_teeth,
                           "teeth of the drive-wheel pulley N_mp (-)", pos)
                  .integer("counts_per_rev", e.counts_per_rev,
                           "encoder counts per encoder-shaft revolution N_ec (-)", pos)
                  .real("rate_hz", c.encoders.rate_hz, "nominal sample rate (Hz)", pos));
  t.push_back(Options("imu")
                  .real("gyro_noise_rad_s", c.imu.gyro_noise_rad_s,
                        "gyro z white noise, 1 sigma per sample (rad/s)", nonneg)
                  .real("rate_hz", c.imu.rate_hz, "nominal sample rate (Hz)", pos));
  t.push_back(Options("motors")
                  .real("current_noise_A", c.motors.current_noise_A,
                        "current sensor noise, 1 sigma (A)", nonneg)
                  .real("vrc_noise_V", c.motors.vrc_noise_V, "V_RC noise, 1 sigma (V)", nonneg)
                  .real("rate_hz", c.motors.rate_hz, "nominal sample rate (Hz)", pos));
  t.push_back(Options("voltage_circuit")
                  .real("R1_ohm", vc.R1_ohm, "divider resistor R1 (ohm)", pos)
                  .real("R2_ohm", vc.R2_ohm, "divider resistor R2 (ohm)", pos)
                  .real("R3_ohm", vc.R3_ohm, "divider resistor R3 (ohm)", pos)
                  .real("R4_ohm", vc.R4_ohm, "divider resistor R4 (ohm)", pos)
                  .real("C_F", vc.C_F, "capacitor (F)", nonneg)
                  .flag("has_zener", vc.has_zener, "Zener diode present")
                  .real("zener_knee_V", vc.zener_knee_V, "Zener knee voltage V_d (V)", nonneg)
                  .real("zener_current_at_knee_A", vc.zener_current_at_knee_A,
                        "soft-knee current at the knee (A)", nonneg)
                  .real("zener_slope_V", vc.zener_slope_V, "soft-knee voltage slope (V)", pos));
  t.push_back(Options("sonar")
                  .real("x_m", c.sonar.x_m, "position on the body, x (m)")
                  .real("y_m", c.sonar.y_m, "position on the body, y (m)")
                  .real("yaw_deg", c.sonar.yaw_deg, "heading on the body (deg, 0 = forward)")
                  .real("cone_half_angle_deg", c.sonar.cone_half_angle_deg, "cone half-angle (deg)",
                        Range::between(0, 90))
                  .real("min_range_m", c.sonar.min_range_m, "valid range, lower limit (m)", nonneg)
                  .real("max_range_m", c.sonar.max_range_m, "valid range, upper limit (m)", pos)
                  .real("noise_m", c.sonar.noise_m, "range noise, 1 sigma (m)", nonneg)
                  .real("rate_hz", c.sonar.rate_hz, "nominal sample rate (Hz)", pos));
  t.push_back(Options("pozyx")
                  .real("lever_x_m", c.pozyx.lever_x_m, "tag lever arm in the body frame, x (m)")
                  .real("lever_y_m", c.pozyx.lever_y_m, "tag lever arm in the body frame, y (m)")
                  .real("noise_m", c.pozyx.noise_m, "position noise, 1 sigma (m)", nonneg)
                  .real("rate_hz", c.pozyx.rate_hz, "nominal sample rate (Hz)", pos));
  t.push_back(
      Options("joystick").real("rate_hz", c.joystick.rate_hz, "nominal sample rate (Hz)", pos));
  return t;
}

[[maybe_unused]] const bool kRegistered = registerOptions([] {
  auto c = std::make_shared<WheelchairConfig>();
  auto t = tables(*c);
  for (auto& o : t) o.keepAlive(c);
  return t;
});

}  // namespace

WheelchairConfig::WheelchairConfig() : ini_(std::make_shared<IniFile>("", "<nominal>")) {
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
      ini_(std::make_shared<IniFile>(o.text(), o.origin_)),
      origin_(o.origin_) {
  ini_->copyIndex(*o.ini_);  // errors keep naming the lines of the original file
}

WheelchairConfig& WheelchairConfig::operator=(const WheelchairConfig& o) {
  if (this != &o) *this = WheelchairConfig(o);
  return *this;
}

WheelchairConfig WheelchairConfig::load(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(fmt::format("{}: cannot open configuration file", path));
  // An INI is a few kB: refuse anything huge (a wrong path, a data file) before reading it.
  constexpr std::size_t kMaxConfigBytes = 4u << 20;
  std::string text(kMaxConfigBytes + 1, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<std::size_t>(in.gcount()));
  if (text.size() > kMaxConfigBytes)
    throw std::runtime_error(
        fmt::format("{}: larger than {} bytes, not a configuration file", path, kMaxConfigBytes));
  const IniFile probe(text, path);
  if (probe.entries().empty()) {
    const std::string m = fmt::format("{}: empty configuration (no section, no key)", path);
    if (!lenient()) throw std::runtime_error(m);
    std::cerr << "warning: " << m << " (the nominal values are used: --lenient)\n";
  }
  return fromText(text, path);
}

WheelchairConfig WheelchairConfig::fromText(const std::string& ini_text, const std::string& origin) {
  WheelchairConfig c;
  c.ini_ = std::make_shared<IniFile>(ini_text, origin);
  c.origin_ = origin;
  checkIni(*c.ini_);
  c.loadShared();
  c.syncToIni();  // keys absent from the file now show their (default) values in text()
  return c;
}

void WheelchairConfig::loadShared() {
  for (const auto& t : tables(*this)) t.load(*ini_);
}

void WheelchairConfig::syncToIni() {
  for (const auto& t : tables(*this)) t.save(*ini_);
}

void WheelchairConfig::set(const std::string& section, const std::string& key,
                           const std::string& value) {
  ini_->write(section, key, value);
  loadShared();
}

std::string WheelchairConfig::text() const { return ini_->getContent(); }

void WheelchairConfig::save(const std::string& path) const {
  util::writeFileAtomically(path, [&](std::ostream& out) {
    out << "# Written by libwheelchair from " << origin_ << "\n" << text();
  });
}

}  // namespace wheelchair::config
