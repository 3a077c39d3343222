#include "libwheelchair/simulation/UnknownEffects.h"

#include "libwheelchair/simulation/MujocoEngine.h"

#include <fmt/format.h>

#include <cmath>
#include <stdexcept>

namespace wheelchair::simulation {

namespace {
constexpr double kDeg = M_PI / 180.0;
constexpr double kYawDrySmoothing_rad_s = 0.02;  ///< tanh width of yaw_dry_friction
}  // namespace

const std::vector<effects::EffectInfo>& unknownEffectCatalogue() {
  static const std::vector<effects::EffectInfo> cat = {
      {"forward_viscous_drag",
       "(out of catalogue) A force opposing the motion, proportional to speed: F = -c v.",
       {{"c_N_s_m", "N s/m", "drag per unit speed", "", {}, false, 0, 200}}},
      {"forward_quadratic_drag",
       "(out of catalogue) A force opposing the motion, proportional to speed squared: "
       "F = -c v|v|.",
       {{"c_N_s2_m2", "N s^2/m^2", "drag per unit speed squared", "", {}, false, 0, 200}}},
      {"yaw_dry_friction",
       "(out of catalogue) A dry-friction moment opposing the turn: M = -M0 sgn(omega).",
       {{"torque_Nm", "N m", "friction moment", "", {}, false, 0, 50}}},
      {"yaw_viscous_friction",
       "(out of catalogue) A moment opposing the turn, proportional to the turn rate: "
       "M = -c omega.",
       {{"c_N_m_s_rad", "N m s/rad", "damping", "", {}, false, 0, 100}}},
      {"heading_yaw_torque",
       "(out of catalogue) A yaw moment that depends on the heading: M = M0 sin(phi - heading).",
       {{"torque_Nm", "N m", "amplitude", "", {}, false, 0, 50},
        {"heading_deg",
         "deg",
         "heading the moment turns the chair towards (start frame)",
         "0",
         {},
         false,
         -360,
         360}}},
      {"yaw_inertia",
       "(out of catalogue) Extra yaw inertia about the axle (a load far from it).",
       {{"extra_kg_m2", "kg m^2", "added yaw inertia", "", {}, false, 0, 100}}},
      {"current_offset",
       "(out of catalogue) The current sensor of one motor reads an offset.",
       {{"side", "enum", "motor", "right", effects::sideChoices()},
        {"offset_A", "A", "added to the measured current", "", {}, false, -10, 10}}},
  };
  return cat;
}

const effects::EffectInfo* findUnknownEffect(const std::string& id) {
  for (const auto& e : unknownEffectCatalogue())
    if (e.id == id) return &e;
  return nullptr;
}

Eigen::Vector2d ExternalLoad::forceMoment(double v, double w, double phi) const {
  const double F = -viscous_N_s_m * v - quadratic_N_s2_m2 * v * std::abs(v);
  const double M = -yaw_dry_Nm * std::tanh(w / kYawDrySmoothing_rad_s) - yaw_viscous_N_m_s_rad * w +
                   heading_torque_Nm * std::sin(phi - heading_rad);
  return {F, M};
}

bool ExternalLoad::any() const {
  return viscous_N_s_m != 0 || quadratic_N_s2_m2 != 0 || yaw_dry_Nm != 0 ||
         yaw_viscous_N_m_s_rad != 0 || heading_torque_Nm != 0 || extra_yaw_inertia_kg_m2 != 0 ||
         current_offset_A[0] != 0 || current_offset_A[1] != 0;
}

ExternalLoad externalLoad(const std::vector<effects::EffectSpec>& effects) {
  ExternalLoad L;
  auto num = [](const effects::EffectSpec& e, const std::string& key) {
    const effects::EffectInfo* info = findUnknownEffect(e.id);
    for (const auto& p : info->params)
      if (p.name == key) {
        const std::string t = e.has(key) ? e.params.at(key) : p.default_value;
        std::size_t end = 0;
        const double x = std::stod(t, &end);
        if (end != t.size() || !std::isfinite(x))
          throw std::invalid_argument("effect '" + e.id + "': " + key + " = '" + t +
                                      "' is not a finite number");
        return x;
      }
    throw std::invalid_argument("effect '" + e.id + "': no parameter " + key);
  };
  for (const auto& e : effects) {
    if (e.id == "forward_viscous_drag") L.viscous_N_s_m += num(e, "c_N_s_m");
    if (e.id == "forward_quadratic_drag") L.quadratic_N_s2_m2 += num(e, "c_N_s2_m2");
    if (e.id == "yaw_dry_friction") L.yaw_dry_Nm += num(e, "torque_Nm");
    if (e.id == "yaw_viscous_friction") L.yaw_viscous_N_m_s_rad += num(e, "c_N_m_s_rad");
    if (e.id == "heading_yaw_torque")
      L.heading_torque_Nm = num(e, "torque_Nm"), L.heading_rad = num(e, "heading_deg") * kDeg;
    if (e.id == "yaw_inertia") L.extra_yaw_inertia_kg_m2 += num(e, "extra_kg_m2");
    if (e.id == "current_offset")
      L.current_offset_A[e.text("side") == "left" ? 1 : 0] += num(e, "offset_A");
  }
  return L;
}

effects::EffectSpec randomUnknownEffect(const std::string& engine, std::mt19937_64& rng) {
  auto U = [&](double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); };
  auto f = [](double x) { return fmt::format("{:.4g}", x); };
  std::vector<std::string> ids;
  for (const auto& e : unknownEffectCatalogue()) ids.push_back(e.id);
  if (engine == "mujoco")
    for (const auto& e : mujocoEffectCatalogue()) ids.push_back(e.id);
  effects::EffectSpec e;
  e.id = ids[std::uniform_int_distribution<size_t>(0, ids.size() - 1)(rng)];
  const std::string& id = e.id;
  // Magnitudes: a contribution of roughly 0.5 .. 3 current-noise sigmas per sample.
  if (id == "forward_viscous_drag") e.params["c_N_s_m"] = f(U(3, 12));
  if (id == "forward_quadratic_drag") e.params["c_N_s2_m2"] = f(U(4, 15));
  if (id == "yaw_dry_friction") e.params["torque_Nm"] = f(U(0.4, 1.5));
  if (id == "yaw_viscous_friction") e.params["c_N_m_s_rad"] = f(U(1, 4));
  if (id == "heading_yaw_torque")
    e.params["torque_Nm"] = f(U(0.4, 1.5)), e.params["heading_deg"] = f(U(-180, 180));
  if (id == "yaw_inertia") e.params["extra_kg_m2"] = f(U(1.5, 4));
  if (id == "current_offset") {
    e.params["side"] = U(0, 1) < 0.5 ? "right" : "left";
    e.params["offset_A"] = f((U(0, 1) < 0.5 ? -1 : 1) * U(0.1, 0.4));
  }
  // The MuJoCo engine's own (ranges as before this generator).
  if (id == "castor_friction") e.params["swivel_friction_Nm"] = f(U(0.5, 3));
  if (id == "tyre_scrub") e.params["torsion_m"] = f(U(0.005, 0.03));
  if (id == "rolling_resistance") e.params["coefficient_m"] = f(U(0.001, 0.004));
  if (id == "soft_tyre") e.params["growth_m"] = f(U(0.002, 0.008));
  if (id == "tyre_grip") e.params["mu"] = f(U(0.15, 0.4));
  validateEngineEffect(e, engine);
  return e;
}

UnknownEffectTruth unknownEffectTruth(const effects::EffectSpec& e) {
  const std::string& id = e.id;
  if (id == "forward_viscous_drag")
    return {"forward", "rate", "a force along the heading opposing motion, proportional to speed"};
  if (id == "forward_quadratic_drag")
    return {"forward", "rate_squared", "a drag force along the heading, proportional to v|v|"};
  if (id == "yaw_dry_friction")
    return {"yaw", "sign_of_rate", "a dry-friction moment opposing the turn"};
  if (id == "yaw_viscous_friction") return {"yaw", "rate", "a viscous moment opposing the turn"};
  if (id == "heading_yaw_torque") return {"yaw", "heading", "a yaw moment set by the heading"};
  if (id == "yaw_inertia") return {"yaw", "acceleration", "yaw inertia beyond the model's"};
  if (id == "current_offset")
    return {"current_" + e.text("side"), "constant", "an offset of one motor's current sensor"};
  // The MuJoCo engine's own (MujocoEngine.h): the law the multibody REALISES, measured on the
  // engine (diagnosis::effectTrace: the change of the true-motion relation of the currents,
  // with and without the effect, same seed, regressed on each dependence class; the method
  // tells an injected -M0 tanh(omega/0.02) (dry, R^2 0.96 vs 0.74 viscous) from -c omega
  // (viscous, 1.00 vs 0.63) on the same multibody; test_diagnosis EffectTrace.*,
  // docs/discovery.md "Out of catalogue: traces, realised laws, where excited"). The contact
  // laws are dry, but MuJoCo's soft contact regularises dry friction:
  //   tyre_scrub (torsional friction)    yaw, rate: R^2 rate 0.84-0.87 vs sign 0.60-0.70
  //   rolling_resistance (rolling fr.)   forward, rate: R^2 rate 0.98-1.00 vs sign 0.67-0.73
  //   castor_friction (swivel friction)  yaw, castor_swivel: the castors turning round at
  //                                      the start of a turn (diagnosis::castorSwivelMoment;
  //                                      before that class existed it read as acceleration,
  //                                      R^2 0.79-0.86 on excite, 0.33 on square)
  if (id == "tyre_scrub")
    return {"yaw", "rate",
            "torsional friction of the contact patches (dry), realised by MuJoCo's soft contact "
            "as a viscous moment opposing the turn"};
  if (id == "castor_friction")
    return {"yaw", "castor_swivel",
            "dry friction in the castor swivels, realised as a yaw moment while the castors "
            "swivel round at the start of each turn and when it reverses"};
  if (id == "rolling_resistance")
    return {"forward", "rate",
            "rolling resistance (dry rolling friction), realised by MuJoCo's soft contact as "
            "a force along the heading proportional to speed"};
  if (id == "soft_tyre")
    return {"gyro_vs_encoders", "rate_squared",
            "the drive tyres' rolling radius grows with the square of their speed"};
  if (id == "tyre_grip")
    return {"gyro_vs_encoders", "acceleration",
            "low tyre grip: the wheels slip when the traction demand is high"};
  throw std::invalid_argument("unknownEffectTruth: '" + id + "' is not an out-of-catalogue effect");
}

}  // namespace wheelchair::simulation
