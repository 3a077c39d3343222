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
      m.effects.push_back(effects::parseValidEffect(text));
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(fmt::format("[model_extensions] {}: {}", k, e.what()));
    }
  }
  return m;
}

io::Recording ModelExtensions::apply(const io::Recording& rec,
                                     const config::WheelchairConfig& cfg) const {
  io::Recording out = rec;
  RimSpeeds rims;
  const effects::CorrectionContext ctx{cfg, [&rims](double t) { return rims.at(t); }};
  // 1. Sensor effects, on the raw data.
  for (const auto& e : effects)
    if (const effects::Effect* eff = effects::findEffect(e.id);
        eff && eff->correctionPhase() == effects::CorrectionPhase::sensor)
      eff->correct(e, out, ctx);
  // 2. Drive-train effects, with the corrected encoders' rim speeds.
  rims.iv = sensors::wheelSpeedsFromTicks(out.encoders, cfg.encoders.params,
                                          cfg.vehicle.geom.wheel_radius_m,
                                          cfg.vehicle.geom.track_width_m);
  for (const auto& e : effects)
    if (const effects::Effect* eff = effects::findEffect(e.id);
        eff && eff->correctionPhase() == effects::CorrectionPhase::drive)
      eff->correct(e, out, ctx);
  return out;
}

config::WheelchairConfig ModelExtensions::adjustConfig(const config::WheelchairConfig& cfg) const {
  config::WheelchairConfig c = cfg;
  for (const auto& e : effects)
    if (const effects::Effect* eff = effects::findEffect(e.id)) eff->adjustConfig(e, c);
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
