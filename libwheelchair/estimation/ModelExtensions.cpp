#include "libwheelchair/estimation/ModelExtensions.h"

#include "libwheelchair/sensors/Encoders.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace wheelchair::estimation {

namespace {

ModelExtension parseEntry(const std::string& text) {
  ModelExtension e;
  const auto colon = text.find(':');
  e.id = text.substr(0, colon);
  if (colon == std::string::npos) return e;
  std::stringstream ss(text.substr(colon + 1));
  std::string kv;
  while (std::getline(ss, kv, ',')) {
    const auto eq = kv.find('=');
    if (eq == std::string::npos)
      throw std::runtime_error(fmt::format("[model_extensions] '{}': '{}' is not key=value", text, kv));
    e.params[kv.substr(0, eq)] = kv.substr(eq + 1);
  }
  return e;
}

int sideIndex(const ModelExtension& e) {
  const auto it = e.params.find("side");
  if (it == e.params.end()) return -1;
  if (it->second == "right") return 0;
  if (it->second == "left") return 1;
  throw std::runtime_error(fmt::format("[model_extensions] {}: side '{}' is not right/left", e.id,
                                       it->second));
}

// Mean rim speeds of each encoder interval, looked up by time (zero-order hold).
struct RimSpeeds {
  std::vector<sensors::WheelSpeedInterval> iv;
  Eigen::Vector2d at(double t) const {
    if (iv.empty()) return Eigen::Vector2d::Zero();
    auto it = std::lower_bound(iv.begin(), iv.end(), t,
                               [](const sensors::WheelSpeedInterval& w, double x) { return w.t1_s < x; });
    if (it == iv.end()) --it;
    return {it->u_right_m_s, it->u_left_m_s};
  }
};

}  // namespace

double ModelExtension::number(const std::string& key, double fallback) const {
  const auto it = params.find(key);
  return it == params.end() ? fallback : std::stod(it->second);
}

ModelExtensions ModelExtensions::fromConfig(const mrpt::config::CConfigFileBase& ini) {
  ModelExtensions m;
  if (!ini.sectionExists("model_extensions")) return m;
  std::vector<std::string> keys;
  ini.getAllKeys("model_extensions", keys);
  for (const auto& k : keys) {
    if (k.rfind("effect_", 0) != 0) continue;
    m.effects.push_back(parseEntry(ini.read_string("model_extensions", k, "")));
  }
  return m;
}

io::Recording ModelExtensions::apply(const io::Recording& rec,
                                     const config::WheelchairConfig& cfg) const {
  io::Recording out = rec;
  const auto& ep = cfg.encoders.params;
  // 1. Sensor effects.
  for (const auto& e : effects) {
    if (e.id == "encoder_scale") {
      const int side = sideIndex(e);
      const double scale = e.number("scale", 1.0);
      if (side < 0 || !(scale > 0)) continue;
      sensors::TickUnwrapper unwrap;
      for (auto& s : out.encoders) {
        int32_t& raw = side == 0 ? s.right_ticks : s.left_ticks;
        raw = sensors::toHardwareCounter(std::llround(unwrap.unwrap(raw) / scale));
      }
    } else if (e.id == "gyro_bias") {
      const double b = e.number("bias_rad_s", 0.0);
      for (auto& s : out.imu) s.gyro_z_rad_s -= b;
    } else if (e.id == "gyro_scale") {
      const double g = e.number("scale", 1.0);
      if (g > 0)
        for (auto& s : out.imu) s.gyro_z_rad_s /= g;
    } else if (e.id == "sensor_delay") {
      const auto it = e.params.find("sensor");
      const double d = e.number("delay_s", 0.0);
      if (it == e.params.end()) continue;
      const std::string& sn = it->second;
      auto shift = [&](auto& v) {
        for (auto& s : v) s.t_s -= d;
      };
      if (sn == "encoders") shift(out.encoders);
      if (sn == "imu" || sn == "gyro") shift(out.imu);
      if (sn == "motors" || sn == "currents") shift(out.motors);
      if (sn == "sonar") shift(out.sonar);
      if (sn == "pozyx") shift(out.pozyx);
      if (sn == "joystick") shift(out.joystick);
    }
  }
  // 2. Drive-train effects, with the corrected encoders' rim speeds.
  RimSpeeds rims;
  rims.iv = sensors::wheelSpeedsFromTicks(out.encoders, ep, cfg.vehicle.geom.wheel_radius_m,
                                          cfg.vehicle.geom.track_width_m);
  const double viscous_A_per_m_s = cfg.vehicle.motor_viscous_Nm_s_rad /
                                   cfg.vehicle.torque_constant_Nm_A * cfg.vehicle.geom.gear_ratio /
                                   cfg.vehicle.geom.wheel_radius_m;
  for (const auto& e : effects) {
    if (e.id == "motor_asymmetry") {
      const int side = sideIndex(e);
      const double ratio = e.number("friction_ratio", 1.0);
      if (side < 0) continue;
      for (auto& s : out.motors) {
        double& i = side == 0 ? s.current_right_A : s.current_left_A;
        i -= (ratio - 1.0) * viscous_A_per_m_s * rims.at(s.t_s)(side);
      }
    } else if (e.id == "coulomb_friction") {
      const int side = sideIndex(e);
      const double c = e.number("current_A", 0.0);
      for (auto& s : out.motors) {
        const Eigen::Vector2d u = rims.at(s.t_s);
        if (side != 1) s.current_right_A -= c * std::tanh(u(0) / 0.01);
        if (side != 0) s.current_left_A -= c * std::tanh(u(1) / 0.01);
      }
    }
  }
  return out;
}

config::WheelchairConfig ModelExtensions::adjustConfig(const config::WheelchairConfig& cfg) const {
  config::WheelchairConfig c = cfg;
  for (const auto& e : effects)
    if (e.id == "payload_mass" && e.params.count("body_mass_kg"))
      c.set("vehicle", "body_mass_kg", e.params.at("body_mass_kg"));
  return c;
}

std::string ModelExtensions::summary() const {
  std::string s;
  for (const auto& e : effects) {
    if (!s.empty()) s += "; ";
    s += e.id;
    for (const auto& [k, v] : e.params) s += " " + k + "=" + v;
  }
  return s;
}

}  // namespace wheelchair::estimation
