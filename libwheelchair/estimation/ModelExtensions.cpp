#include "libwheelchair/estimation/ModelExtensions.h"

#include "libwheelchair/config/Options.h"

#include "libwheelchair/sensors/Encoders.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace wheelchair::estimation {

namespace {

// Mean rim speeds of each encoder interval, looked up by time (zero-order hold).
struct RimSpeeds {
  std::vector<sensors::WheelSpeedInterval> iv;
  Eigen::Vector2d at(double t) const {
    if (iv.empty()) return Eigen::Vector2d::Zero();
    auto it =
        std::lower_bound(iv.begin(), iv.end(), t,
                         [](const sensors::WheelSpeedInterval& w, double x) { return w.t1_s < x; });
    if (it == iv.end()) --it;
    return {it->u_right_m_s, it->u_left_m_s};
  }
};

}  // namespace

namespace {
// Written by `wheelchair diagnose --write-config`; read here (effect_N) and by the reports.
[[maybe_unused]] const bool kRegistered = config::registerOptions([] {
  auto count = std::make_shared<int>(0);
  config::Options t("model_extensions", "model extensions found by `wheelchair diagnose`");
  t.integer("count", *count, "number of effects (count)", config::Range::atLeast(0))
      .numberedKeys("effect_", "an effect `id:key=value,...` (docs/effects.md)")
      .numberedKeys("sigma_", "its parameters' 1-sigma uncertainties (key=value,...)")
      .numberedKeys("unmodeled_", "terms outside the catalogue (JSON)")
      .keepAlive(count);
  return std::vector<config::Options>{t};
});
}  // namespace

ModelExtensions ModelExtensions::fromConfig(const mrpt::config::CConfigFileBase& ini) {
  ModelExtensions m;
  if (!ini.sectionExists("model_extensions")) return m;
  std::vector<std::string> keys;
  ini.getAllKeys("model_extensions", keys);
  for (const auto& k : keys) {
    if (k.rfind("effect_", 0) != 0) continue;
    const std::string text = ini.read_string("model_extensions", k, "");
    try {
      m.effects.push_back(simulation::parseValidEffect(text));
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(fmt::format("[model_extensions] {}: {}", k, e.what()));
    }
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
      const double scale = e.number("scale");
      if (!(scale > 0)) continue;
      for (const int side : simulation::effectSides(e)) {
        sensors::TickUnwrapper unwrap;
        for (auto& s : out.encoders) {
          int32_t& raw = side == 0 ? s.right_ticks : s.left_ticks;
          raw = sensors::toHardwareCounter(std::llround(unwrap.unwrap(raw) / scale));
        }
      }
    } else if (e.id == "gyro_bias") {
      const double b = e.number("bias_rad_s");
      for (auto& s : out.imu) s.gyro_z_rad_s -= b;
    } else if (e.id == "gyro_scale") {
      const double g = e.number("scale");
      if (g > 0)
        for (auto& s : out.imu) s.gyro_z_rad_s /= g;
    } else if (e.id == "sensor_delay") {
      const std::string sn = e.text("sensor");
      const double d = e.number("delay_s");
      auto shift = [&](auto& v) {
        for (auto& s : v) s.t_s -= d;
      };
      if (sn == "encoders") shift(out.encoders);
      if (sn == "imu") shift(out.imu);
      if (sn == "motors") shift(out.motors);
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
      const double ratio = e.number("friction_ratio");
      for (const int side : simulation::effectSides(e))
        for (auto& s : out.motors) {
          double& i = side == 0 ? s.current_right_A : s.current_left_A;
          i -= (ratio - 1.0) * viscous_A_per_m_s * rims.at(s.t_s)(side);
        }
    } else if (e.id == "coulomb_friction") {
      const double c = e.number("current_A");
      for (const int side : simulation::effectSides(e))
        for (auto& s : out.motors) {
          double& i = side == 0 ? s.current_right_A : s.current_left_A;
          i -= c * std::tanh(rims.at(s.t_s)(side) / 0.01);
        }
    }
  }
  return out;
}

config::WheelchairConfig ModelExtensions::adjustConfig(const config::WheelchairConfig& cfg) const {
  config::WheelchairConfig c = cfg;
  for (const auto& e : effects)
    if (e.id == "payload_mass") c.set("vehicle", "body_mass_kg", e.text("body_mass_kg"));
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
