#include "libwheelchair/diagnosis/Campaign.h"

#include "libwheelchair/diagnosis/KinematicCalibration.h"
#include "libwheelchair/diagnosis/Stages.h"
#include "libwheelchair/simulation/MujocoEngine.h"
#include "libwheelchair/simulation/MujocoTruth.h"
#include "libwheelchair/simulation/Simulator.h"
#include "libwheelchair/simulation/UnknownEffects.h"
#include "libwheelchair/stats/Descriptive.h"
#include "libwheelchair/stats/Distributions.h"

#include <fmt/format.h>
#include <Eigen/Dense>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <iostream>
#include <limits>
#include <map>
#include <set>

namespace wheelchair::diagnosis {

namespace {
double U(std::mt19937_64& rng, double a, double b) {
  return std::uniform_real_distribution<double>(a, b)(rng);
}
double sgn(std::mt19937_64& rng) {
  return U(rng, 0, 1) < 0.5 ? -1.0 : 1.0;
}
std::string side(std::mt19937_64& rng) {
  return U(rng, 0, 1) < 0.5 ? "right" : "left";
}
using stats::median;
using stats::quantile;
}  // namespace

effects::EffectSpec randomEffect(const std::string& id, std::mt19937_64& rng) {
  auto f = [](double x) { return fmt::format("{:.6g}", x); };
  effects::EffectSpec e;
  e.id = id;
  if (id == "gyro_bias") e.params["bias_rad_s"] = f(sgn(rng) * U(rng, 0.003, 0.02));
  if (id == "gyro_scale") e.params["scale"] = f(1 + sgn(rng) * U(rng, 0.01, 0.05));
  if (id == "encoder_scale")
    e.params = {{"side", side(rng)}, {"scale", f(1 + sgn(rng) * U(rng, 0.01, 0.05))}};
  if (id == "sensor_delay") {
    const char* s[] = {"imu", "encoders", "motors"};
    e.params = {{"sensor", s[std::uniform_int_distribution<int>(0, 2)(rng)]},
                {"delay_s", f(U(rng, 0.03, 0.1))}};
  }
  if (id == "motor_asymmetry")
    e.params = {{"side", side(rng)}, {"friction_ratio", f(U(rng, 1.15, 1.5))}};
  if (id == "coulomb_friction") e.params["current_A"] = f(U(rng, 0.2, 0.6));
  if (id == "ground_slope")
    e.params = {{"angle_deg", f(U(rng, 1.0, 3.0))}, {"downhill_heading_deg", f(U(rng, -180, 180))}};
  if (id == "payload_mass") e.params["body_mass_kg"] = f(130 + sgn(rng) * U(rng, 25, 60));
  return e;
}

double parameterError(const effects::EffectSpec& t, const Finding& f,
                      const config::WheelchairConfig& cfg) {
  auto num = [&](const char* k) {
    return f.parameters.contains(k) && f.parameters[k].is_number() ? f.parameters[k].get<double>()
                                                                   : std::nan("");
  };
  auto str = [&](const char* k) {
    return f.parameters.contains(k) && f.parameters[k].is_string()
               ? f.parameters[k].get<std::string>()
               : std::string();
  };
  auto rel = [](double est, double tru) { return std::abs(est - tru) / std::abs(tru); };
  const double nan = std::nan("");
  if (t.id == "gyro_bias") return rel(num("bias_rad_s"), t.number("bias_rad_s"));
  if (t.id == "gyro_scale") return rel(num("scale") - 1, t.number("scale") - 1);
  if (t.id == "encoder_scale")
    return str("side") == t.text("side") ? rel(num("scale") - 1, t.number("scale") - 1) : 1.0;
  if (t.id == "sensor_delay")
    return str("sensor") == t.text("sensor") ? rel(num("delay_s"), t.number("delay_s")) : 1.0;
  if (t.id == "motor_asymmetry")
    return str("side") == t.text("side")
               ? rel(num("friction_ratio") - 1, t.number("friction_ratio") - 1)
               : 1.0;
  if (t.id == "coulomb_friction") return rel(num("current_A"), t.number("current_A"));
  if (t.id == "ground_slope") {
    double a = t.number("angle_deg") * M_PI / 180,
           h = t.number("downhill_heading_deg") * M_PI / 180;
    double ae = num("angle_deg") * M_PI / 180, he = num("downhill_heading_deg") * M_PI / 180;
    // error of the slope vector relative to its length
    return std::hypot(std::sin(ae) * std::cos(he) - std::sin(a) * std::cos(h),
                      std::sin(ae) * std::sin(he) - std::sin(a) * std::sin(h)) /
           std::sin(a);
  }
  if (t.id == "payload_mass") {
    double m0 = cfg.vehicle.geom.body_mass_kg;
    return rel(num("body_mass_kg") - m0, t.number("body_mass_kg") - m0);
  }
  return nan;
}

bool engineTruthFinding(const Finding& f, const nlohmann::json& truth) {
  if (truth.is_null()) return false;
  auto num = [&](const char* k) {
    return f.parameters.contains(k) && f.parameters[k].is_number() ? f.parameters[k].get<double>()
                                                                   : std::nan("");
  };
  auto within = [](double x, const nlohmann::json& range) {
    const double lo = range[0].get<double>(), hi = range[1].get<double>();
    const double tol = 0.25 * std::max(std::abs(lo), std::abs(hi));
    return x >= lo - tol && x <= hi + tol;
  };
  if (f.effect == kWheelGeometryEffect) {
    bool ok = true;
    for (const char* k : {"wheel_radius_right_rel", "wheel_radius_left_rel"})
      if (const double x = num(k); x != 0) ok = ok && within(x, truth["radius_rel"]);
    if (const double x = num("track_rel"); x != 0) ok = ok && within(x, truth["track_rel"]);
    return ok;
  }
  if (f.effect == "unmodeled" && f.parameters.contains("channel")) {
    const std::string ch = f.parameters["channel"].get<std::string>();
    if (ch != "current_right" && ch != "current_left") return false;
    const double sign = ch == "current_right" ? 1.0 : -1.0;  // antisymmetric (yaw) terms
    auto close = [](double est, double tru) { return std::abs(est - tru) <= 0.25 * std::abs(tru); };
    int known = 0;
    for (auto it = f.parameters.begin(); it != f.parameters.end(); ++it) {
      const std::string& k = it.key();
      if (k == "channel") continue;
      if (k != "v*omega" && k != "omega^2" && k != "omegadot" && k != "cos(phi)" &&
          k != "sin(phi)" && !(k == "vdot" && truth.contains("vdot_in_drive_A")))
        return false;
      ++known;
    }
    if (known == 0) return false;
    if (f.parameters.contains("v*omega") &&
        !close(num("v*omega"), sign * truth["v_omega_A"].get<double>()))
      return false;
    if (f.parameters.contains("omega^2") && !close(num("omega^2"), truth["omega2_A"].get<double>()))
      return false;
    const int motor = ch == "current_right" ? 0 : 1;
    if (f.parameters.contains("vdot") &&
        !close(num("vdot"), truth["vdot_in_drive_A"][motor].get<double>()))
      return false;
    // the omegadot term realised in the drive (per motor) when measured, else the step's
    const double omegadot = truth.contains("omegadot_in_drive_A")
                                ? truth["omegadot_in_drive_A"][motor].get<double>()
                                : sign * truth["omegadot_A"].get<double>();
    if (f.parameters.contains("omegadot") && !close(num("omegadot"), omegadot)) return false;
    if (f.parameters.contains("cos(phi)") || f.parameters.contains("sin(phi)")) {
      const double c = f.parameters.contains("cos(phi)") ? num("cos(phi)") : 0.0;
      const double sn = f.parameters.contains("sin(phi)") ? num("sin(phi)") : 0.0;
      const double tc = sign * truth["slope_cos_A"].get<double>();
      const double ts = sign * truth["slope_sin_A"].get<double>();
      const double len = std::hypot(tc, ts);
      if (!(len > 0) || std::hypot(c - tc, sn - ts) > 0.25 * len) return false;
    }
    return true;
  }
  return false;
}

namespace {
nlohmann::json engineTruthJson(const config::WheelchairConfig& cfg,
                               const std::vector<effects::EffectSpec>& effects) {
  const simulation::MujocoTruth t = simulation::measureMujocoTruth(cfg, effects);
  // On a slope the centre of mass ahead of the axle turns the chair across the slope: the
  // right motor's current gets -A sin(h - phi) = -A sin(h) cos(phi) + A cos(h) sin(phi), with
  // A = c (sum m x) g sin(angle) / l_w (h = downhill heading), the left the opposite.
  double slope_cos = 0, slope_sin = 0;
  for (const auto& e : effects)
    if (e.id == "ground_slope") {
      const double a = e.number("angle_deg") * M_PI / 180,
                   h = e.number("downhill_heading_deg") * M_PI / 180;
      const double A = t.vOmegaCurrentCoefficient(cfg) * 9.81 * std::sin(a);
      slope_cos = -A * std::sin(h), slope_sin = A * std::cos(h);
    }
  return {{"radius_rel", {t.radius_rel_min, t.radius_rel_max}},
          {"slope_cos_A", slope_cos},
          {"slope_sin_A", slope_sin},
          {"track_rel", {t.track_rel_min, t.track_rel_max}},
          {"com_ahead_m", t.mass_moment_kg_m / t.mass_kg},
          {"v_omega_A", t.vOmegaCurrentCoefficient(cfg)},
          {"omega2_A", t.omegaSquaredCurrentCoefficient(cfg)},
          {"omegadot_A", t.omegadot_A},
          {"vdot_A", t.vdot_A}};
}
}  // namespace

nlohmann::json CaseResult::toJson() const {
  nlohmann::json j;
  std::vector<std::string> t;
  for (auto& e : truth) t.push_back(effects::formatEffect(e));
  j["truth"] = t;
  j["reported"] = reported;
  j["correct"] = correct;
  j["param_errors"] = param_errors;
  j["val_rms_before"] = val_rms_before;
  j["val_rms_after"] = val_rms_after;
  j["runtime_s"] = runtime_s;
  j["mismatch"] = mismatch;
  j["named_correct"] = named_correct;
  j["engine_correct"] = engine_correct;
  j["false_finding"] = false_finding;
  if (!cannot_tell.empty()) j["cannot_tell"] = cannot_tell;
  j["findings"] = findings;
  if (!engine_truth.is_null()) j["engine_truth"] = engine_truth;
  return j;
}

nlohmann::json unknownEffectScore(const std::vector<effects::EffectSpec>& truth,
                                  const nlohmann::json& findings, const std::string& engine) {
  nlohmann::json out = {{"located", false}, {"described", false}};
  if (truth.empty()) return out;
  const simulation::UnknownEffectTruth t = simulation::unknownEffectTruth(truth.front());
  out["truth"] = {{"channel", t.channel}, {"dependence", t.dependence}, {"physics", t.physics}};
  nlohmann::json seen = nlohmann::json::array();
  std::vector<std::string> catalogue;
  for (const auto& f : findings) {
    const std::string effect = f.value("effect", std::string());
    if (effect != "unmodeled") {
      catalogue.push_back(effect);
      continue;
    }
    for (const auto& c : f.value("physics", nlohmann::json::array())) {
      const std::string term = c.value("term", std::string());
      const std::string ch = c.value("channel", std::string());
      // The multibody's centre of mass ahead of the axle (on every clean MuJoCo drive,
      // engineTruthFinding) is the engine's, not this effect's: a rigid body whose centre of
      // mass lies a distance d ahead of the axle needs a forward force -m d omega^2 (the same
      // current on both motors) and a yaw moment m d v omega (opposite currents), and nothing
      // else of these two products (a lateral offset adds only vdot and omegadot terms). Those
      // readings, or one motor's share of them, are set aside; a YAW omega^2 or a FORWARD
      // v*omega is not the centre of mass (e.g. a yaw viscous moment on a `square` drive, whose
      // turns go one way at one rate, reads as a yaw omega^2 ambiguous with omega).
      const bool one_motor = ch == "current_right" || ch == "current_left";
      if (engine == "mujoco" && ((term == "omega^2" && (ch == "forward" || one_motor)) ||
                                 (term == "v*omega" && (ch == "yaw" || one_motor))))
        continue;
      const std::string dep = c.value("dependence", std::string());
      seen.push_back(ch + ": " + dep + " (" + term + ")");
      if (ch == t.channel) {
        out["located"] = true;
        if (dep == t.dependence) out["described"] = true;
      }
      // One ambiguous group (UnmodeledPhysics.h: collinear readings): the effect's reading
      // among the group's counts, and the score says it was found as part of a group.
      for (const auto& a : c.value("ambiguous_with", nlohmann::json::array()))
        if (a.value("channel", "") == t.channel) {
          out["located"] = true;
          seen.push_back(ch + ": " + dep + " (" + term + ") ambiguous with " +
                         a.value("channel", "") + ": " + a.value("dependence", "") + " (" +
                         a.value("term", "") + ")");
          if (a.value("dependence", "") == t.dependence) out["described_in_group"] = true;
        }
    }
  }
  if (out.value("described_in_group", false) && !out["described"].get<bool>())
    out["described"] = true;
  else
    out.erase("described_in_group");
  out["components"] = seen;
  out["catalogue_names"] = catalogue;
  return out;
}

namespace {
/// The true motion at each of `t_s` (nearest truth sample; truth rate >= sensor rates), with
/// accelerations by central differences: v, omega, vdot, omegadot, phi, rim speeds u_R, u_L.
struct MotionRow {
  double v, w, vdot, wdot, phi, u[2], udot[2];
  double castor = 0;  ///< castorSwivelMoment of the motion (set by withCastors)
};
std::vector<MotionRow> motionAt(const simulation::TruthTrajectory& T,
                                const std::vector<double>& t_s, double track_m) {
  const auto& S = T.samples;
  std::vector<MotionRow> out;
  if (S.size() < 3) return out;
  std::size_t k = 0;
  for (double t : t_s) {
    while (k + 1 < S.size() && std::abs(S[k + 1].t_s - t) <= std::abs(S[k].t_s - t)) ++k;
    const std::size_t a = k == 0 ? 0 : k - 1, b = std::min(k + 1, S.size() - 1);
    const double dt = std::max(1e-9, S[b].t_s - S[a].t_s);
    MotionRow m{};
    m.v = S[k].v_m_s, m.w = S[k].omega_rad_s, m.phi = S[k].phi_rad;
    m.vdot = (S[b].v_m_s - S[a].v_m_s) / dt, m.wdot = (S[b].omega_rad_s - S[a].omega_rad_s) / dt;
    for (int s : {0, 1}) {
      const double sg = s == 0 ? 0.5 : -0.5;
      m.u[s] = m.v + sg * track_m * m.w;
      m.udot[s] = m.vdot + sg * track_m * m.wdot;
    }
    out.push_back(m);
  }
  return out;
}

/// Rows with their castorSwivelMoment (the castors of `dopt`), rows at times t_s.
std::vector<MotionRow> withCastors(std::vector<MotionRow> rows, const std::vector<double>& t_s,
                                   const DiagnosisOptions& dopt) {
  std::vector<double> v, w;
  for (const MotionRow& m : rows) v.push_back(m.v), w.push_back(m.w);
  const std::vector<double> c = castorSwivelMoment(
      t_s, v, w, {dopt.castor_x_m, dopt.castor_half_spacing_m, dopt.castor_relaxation_m});
  for (std::size_t i = 0; i < rows.size() && i < c.size(); ++i) rows[i].castor = c[i];
  return rows;
}

/// How a stream y relates to the motion: least squares of y on the rows `lib` builds.
using RowLibrary = std::function<Eigen::VectorXd(const MotionRow&)>;
Eigen::VectorXd relationFit(const std::vector<MotionRow>& m, const std::vector<double>& y,
                            const RowLibrary& lib) {
  const std::size_t n = std::min(m.size(), y.size());
  const Eigen::Index k = lib(MotionRow{}).size();
  Eigen::MatrixXd A(n, k);
  Eigen::VectorXd b(n);
  for (std::size_t i = 0; i < n; ++i) A.row(i) = lib(m[i]).transpose(), b(i) = y[i];
  return n > static_cast<std::size_t>(k) ? Eigen::VectorXd(A.colPivHouseholderQr().solve(b))
                                         : Eigen::VectorXd::Zero(k);
}

/// The change of a stream's relation to the motion the effect makes, on the effect drive's
/// motion: lib(m_a) (beta_a - beta_b) per row (a drive diverging from its twin, e.g. a square
/// reaching a corner later, does not change the relation: only the effect does).
std::vector<double> relationChange(const std::vector<MotionRow>& ma, const std::vector<double>& ya,
                                   const std::vector<MotionRow>& mb, const std::vector<double>& yb,
                                   const RowLibrary& lib) {
  const Eigen::VectorXd db = relationFit(ma, ya, lib) - relationFit(mb, yb, lib);
  std::vector<double> d;
  for (std::size_t i = 0; i < std::min(ma.size(), ya.size()); ++i) d.push_back(lib(ma[i]).dot(db));
  return d;
}

/// rms(d) / sigma and sum(d^2) / sigma^2 of a stream's change d.
nlohmann::json streamChange(const std::vector<double>& d, double sigma) {
  double ss = 0;
  for (double x : d) ss += x * x;
  const double n = std::max<std::size_t>(1, d.size());
  return {{"rms_ratio", std::sqrt(ss / n) / sigma}, {"lr", ss / (sigma * sigma)}};
}

/// The law the engine realised (effectTrace): the change of the currents' relation to the
/// motion, as a forward (half sum) and a yaw (half difference) part, regressed on each
/// dependence class of v (forward) or omega (yaw) alone.
nlohmann::json realisedLaw(const std::vector<MotionRow>& m, const std::vector<double>& dr,
                           const std::vector<double>& dl) {
  const std::size_t n = std::min({m.size(), dr.size(), dl.size()});
  std::vector<double> df(n), dy(n);
  double ef = 0, ey = 0;
  for (std::size_t i = 0; i < n; ++i) {
    df[i] = 0.5 * (dr[i] + dl[i]), dy[i] = 0.5 * (dr[i] - dl[i]);
    ef += df[i] * df[i], ey += dy[i] * dy[i];
  }
  if (n < 3 || !(ef + ey > 0)) return nullptr;
  const bool yaw = ey > ef;
  const std::vector<double>& d = yaw ? dy : df;
  const double dd = yaw ? ey : ef;
  auto x = [&](std::size_t i) { return yaw ? m[i].w : m[i].v; };
  auto xdot = [&](std::size_t i) { return yaw ? m[i].wdot : m[i].vdot; };
  std::vector<std::pair<std::string, std::function<double(std::size_t)>>> classes = {
      {"constant", [](std::size_t) { return 1.0; }},
      {"sign_of_rate", [&](std::size_t i) { return double((x(i) > 0) - (x(i) < 0)); }},
      {"rate", x},
      {"rate_squared", [&](std::size_t i) { return x(i) * std::abs(x(i)); }},
      {"acceleration", xdot}};
  // The castors swivelling round (castorSwivelMoment of the true motion): a yaw class.
  if (yaw) classes.push_back({"castor_swivel", [&](std::size_t i) { return m[i].castor; }});
  nlohmann::json r2s = nlohmann::json::object();
  std::string best;
  double best_r2 = -1;
  for (const auto& [name, col] : classes) {
    double cc = 0, cd = 0;
    for (std::size_t i = 0; i < n; ++i) cc += col(i) * col(i), cd += col(i) * d[i];
    const double r = cc > 0 ? cd * cd / (cc * dd) : 0.0;
    r2s[name] = r;
    if (r > best_r2) best_r2 = r, best = name;
  }
  return {{"channel", yaw ? "yaw" : "forward"},
          {"dependence", best},
          {"r2", r2s},
          {"change_rms_A", std::sqrt(dd / n)}};
}

/// Rows of the currents' relation: the dependence classes of v and omega, the centre of
/// mass' v omega and omega^2, the heading's cos and sin, the castors' swivel moment.
Eigen::VectorXd currentLibrary(const MotionRow& m) {
  auto sg = [](double x) { return double((x > 0) - (x < 0)); };
  Eigen::VectorXd r(14);
  r << 1, sg(m.v), m.v, m.v * std::abs(m.v), m.vdot, sg(m.w), m.w, m.w * std::abs(m.w), m.wdot,
      m.v * m.w, m.w * m.w, std::cos(m.phi), std::sin(m.phi), m.castor;
  return r;
}

/// The multibody's current per unit acceleration beyond model (6), realised in THIS drive's
/// motion, per motor: the noise-free true currents of the MuJoCo drive and of its model-engine
/// twin (same scenario, seed and effects: the model engine IS (6) with the effects), each
/// regressed per motor on currentLibrary of the rim motion (v, omega and their derivatives
/// from the true wheel speeds, as the diagnosis sees them through the encoders); the
/// coefficients' difference of vdot (A s^2/m) and of omegadot (A s^2/rad), {right, left}. A
/// current step from rest measures +0.005 / +0.071 (MujocoTruth.h), a rolling start +0.13-0.15
/// for vdot, sinusoids 0.03 (0.1 Hz) .. 0.16 (1 Hz): the multibody's acceleration terms beyond
/// (6) depend on the motion's spectrum (contact compliance, chassis pitch, castor swivel), so
/// they are measured on the drive's own motion, independently of the diagnosis. E.g. clean
/// `square` (turns to the left): vdot +0.052, omegadot +0.116 right / -0.052 left; clean excite
/// 661751: omegadot +0.019 / -0.020; excite with a 188.6 kg chair: +0.511 / -0.500.
struct RealisedAcceleration {
  double vdot_A[2] = {0, 0}, omegadot_A[2] = {0, 0};
};
RealisedAcceleration realisedAccelerationTerms(const config::WheelchairConfig& cfg,
                                               const std::string& scenario, uint64_t seed,
                                               double duration_s,
                                               const std::vector<effects::EffectSpec>& effects,
                                               const simulation::SimulationResult& mj,
                                               const simulation::SimulationOptions& so) {
  simulation::SimulationOptions mo = so;
  mo.engine = "model";
  const auto twin = simulation::simulate(cfg, scenario, seed, duration_s, effects, mo);
  const double r = cfg.vehicle.geom.wheel_radius_m, lw = cfg.vehicle.geom.track_width_m;
  auto coefficients = [&](const simulation::TruthTrajectory& T, int motor) {
    const auto& S = T.samples;
    std::vector<MotionRow> m;
    std::vector<double> y;
    auto rim = [&](std::size_t k) {
      return std::pair{r * S[k].wheel_speed_right_rad_s, r * S[k].wheel_speed_left_rad_s};
    };
    for (std::size_t k = 1; k + 1 < S.size(); ++k) {
      const auto [uR, uL] = rim(k);
      const auto [aR, aL] = rim(k - 1);
      const auto [bR, bL] = rim(k + 1);
      const double dt = std::max(1e-9, S[k + 1].t_s - S[k - 1].t_s);
      MotionRow row{};
      row.v = 0.5 * (uR + uL), row.w = (uR - uL) / lw, row.phi = S[k].phi_rad;
      row.vdot = 0.5 * ((bR + bL) - (aR + aL)) / dt, row.wdot = ((bR - bL) - (aR - aL)) / lw / dt;
      m.push_back(row);
      y.push_back(motor == 0 ? S[k].current_right_A : S[k].current_left_A);
    }
    return relationFit(m, y, currentLibrary);
  };
  RealisedAcceleration out;
  for (int s : {0, 1}) {
    const Eigen::VectorXd d = coefficients(mj.truth, s) - coefficients(twin.truth, s);
    out.vdot_A[s] = d(4), out.omegadot_A[s] = d(8);  // currentLibrary: vdot 4, omegadot 8
  }
  return out;
}
}  // namespace

nlohmann::json effectTrace(const config::WheelchairConfig& cfg, const std::string& scenario,
                           uint64_t seed, double duration_s,
                           const std::vector<effects::EffectSpec>& effects,
                           const DiagnosisOptions& dopt, const std::string& engine) {
  simulation::SimulationOptions so;
  so.loadFromConfig(cfg.ini());
  so.engine = engine;
  so.record_ground_truth = false;
  const double dur = scenario == "excite" ? duration_s : 0;
  const auto a = simulation::simulate(cfg, scenario, seed, dur, effects, so);
  const auto b = simulation::simulate(cfg, scenario, seed, dur, {}, so);
  const double lw = cfg.vehicle.geom.track_width_m;
  nlohmann::json streams = nlohmann::json::object();
  std::vector<double> dcur[2];
  std::vector<MotionRow> ma_cur;
  {  // motor currents (measured) against the motion
    std::vector<double> ta, tb, ya[2], yb[2];
    for (const auto& s : a.recording.motors)
      ta.push_back(s.t_s), ya[0].push_back(s.current_right_A), ya[1].push_back(s.current_left_A);
    for (const auto& s : b.recording.motors)
      tb.push_back(s.t_s), yb[0].push_back(s.current_right_A), yb[1].push_back(s.current_left_A);
    ma_cur = withCastors(motionAt(a.truth, ta, lw), ta, dopt);
    const auto mb = withCastors(motionAt(b.truth, tb, lw), tb, dopt);
    for (int s : {0, 1}) {
      dcur[s] = relationChange(ma_cur, ya[s], mb, yb[s], currentLibrary);
      streams[s == 0 ? "current_right" : "current_left"] =
          streamChange(dcur[s], cfg.motors.current_noise_A);
    }
  }
  {  // gyro against the true turn rate
    std::vector<double> ta, tb, ya, yb;
    for (const auto& s : a.recording.imu) ta.push_back(s.t_s), ya.push_back(s.gyro_z_rad_s);
    for (const auto& s : b.recording.imu) tb.push_back(s.t_s), yb.push_back(s.gyro_z_rad_s);
    const RowLibrary lib = [](const MotionRow& m) {
      Eigen::VectorXd r(4);
      r << 1, m.w, m.w * std::abs(m.w), m.wdot;
      return r;
    };
    streams["gyro"] = streamChange(
        relationChange(motionAt(a.truth, ta, lw), ya, motionAt(b.truth, tb, lw), yb, lib),
        cfg.imu.gyro_noise_rad_s);
  }
  for (int s : {0, 1}) {  // encoder increments (ticks per sample) against the rim's motion
    auto increments = [&](const io::Recording& r, std::vector<double>& t, std::vector<double>& y) {
      for (std::size_t i = 1; i < r.encoders.size(); ++i) {
        const auto &e1 = r.encoders[i], &e0 = r.encoders[i - 1];
        t.push_back(e1.t_s);
        y.push_back(s == 0 ? double(int64_t(e1.right_ticks) - e0.right_ticks)
                           : double(int64_t(e1.left_ticks) - e0.left_ticks));
      }
    };
    std::vector<double> ta, tb, ya, yb;
    increments(a.recording, ta, ya), increments(b.recording, tb, yb);
    const RowLibrary lib = [s](const MotionRow& m) {  // (the fit scales m/s to ticks)
      Eigen::VectorXd r(4);
      r << m.u[s], m.u[s] * std::abs(m.u[s]), m.udot[s], m.u[s] * std::abs(m.udot[s]);
      return r;
    };
    streams[s == 0 ? "encoder_right" : "encoder_left"] = streamChange(
        relationChange(motionAt(a.truth, ta, lw), ya, motionAt(b.truth, tb, lw), yb, lib),
        std::sqrt(1.0 / 6.0));  // two roundings of a cumulative count
  }
  const double crit = stats::chi2Quantile(1 - dopt.alpha, 1);
  bool traced = false;
  std::string strongest;
  double top = -1;
  for (auto it = streams.begin(); it != streams.end(); ++it) {
    const double rr = (*it)["rms_ratio"].get<double>(), lr = (*it)["lr"].get<double>();
    traced = traced || (lr >= crit && rr >= dopt.min_relevance);
    if (rr > top) top = rr, strongest = it.key();
  }
  return {{"traced", traced},
          {"strongest", strongest},
          {"streams", streams},
          {"realised", realisedLaw(ma_cur, dcur[0], dcur[1])}};
}

namespace {
/// The concealed effects not named (rs: the reported effect names) that an info.cannot_tell
/// note names first (CaseResult::cannot_tell).
std::vector<std::string> untoldEffects(const std::vector<effects::EffectSpec>& effects,
                                       const std::multiset<std::string>& rs,
                                       const nlohmann::json& info) {
  std::vector<std::string> out;
  if (!info.contains("cannot_tell")) return out;
  for (const auto& e : effects) {
    if (rs.count(e.id)) continue;
    const std::string key = e.id + (e.has("side") ? "/" + e.text("side") : "") + " ";
    for (const auto& why : info["cannot_tell"])
      if (why.is_string() && why.get<std::string>().rfind(key, 0) == 0) {
        out.push_back(e.id);
        break;
      }
  }
  return out;
}

/// The drive's own operating point joins the engine's geometry range (MujocoTruth.h,
/// realisedGeometry: measured on the multibody's exact pose and hinge angles in this drive,
/// independently of the recorded sensors and of the diagnosis). The steady drives of
/// measureMujocoTruth are operating points (3 / 6 A straight) the drive need not visit.
void widenToRealisedGeometry(nlohmann::json& truth, const config::WheelchairConfig& cfg,
                             const simulation::TruthTrajectory& drive) {
  const simulation::RealisedGeometry g = simulation::realisedGeometry(cfg, drive.samples);
  if (g.windows == 0) return;
  truth["geometry_in_drive"] = {{"radius_rel", g.radius_rel},
                                {"track_rel", g.track_rel},
                                {"windows", g.windows},
                                {"steady_radius_rel", truth["radius_rel"]},
                                {"steady_track_rel", truth["track_rel"]}};
  for (const auto& [key, x] : {std::pair{"radius_rel", g.radius_rel}, {"track_rel", g.track_rel}}) {
    auto& range = truth[key];
    range[0] = std::min(range[0].get<double>(), x);
    range[1] = std::max(range[1].get<double>(), x);
  }
}
}  // namespace

CaseResult runCase(const config::WheelchairConfig& cfg, const std::string& scenario, uint64_t seed,
                   double duration_s, const std::vector<effects::EffectSpec>& effects,
                   const DiagnosisOptions& dopt, const std::string& engine) {
  CaseResult c;
  c.truth = effects;
  simulation::SimulationOptions so;
  so.loadFromConfig(cfg.ini());
  so.record_ground_truth = true;
  so.engine = engine;
  auto sim =
      simulation::simulate(cfg, scenario, seed, scenario == "excite" ? duration_s : 0, effects, so);
  auto t0 = std::chrono::steady_clock::now();
  DiagnosisReport rep = diagnose({sim.recording}, {}, cfg, dopt);
  c.runtime_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  c.mismatch = rep.mismatch;
  std::multiset<std::string> rs, ts;
  for (auto& f : rep.findings)
    c.reported.push_back(f.effect + (f.effectText().empty() ? "" : " " + f.effectText())),
        rs.insert(f.effect);
  for (auto& e : effects) ts.insert(e.id);
  std::set<std::string> rset(rs.begin(), rs.end()), tset(ts.begin(), ts.end());
  c.correct = rset == tset;
  rset.erase("unmodeled");
  c.named_correct = rset == tset;
  // Scored against the engine's own physics: MuJoCo's effective geometry and centre of mass
  // (measured on the multibody with this drive's effects; not for its mujoco-only effects,
  // whose truth is what the `unknown` drives ask the diagnosis to find).
  bool engine_only = false;
  for (const auto& e : effects) {
    for (const auto& m : simulation::mujocoEffectCatalogue()) engine_only |= m.id == e.id;
    engine_only |= simulation::findUnknownEffect(e.id) != nullptr;
  }
  if (engine == "mujoco" && !engine_only) {
    c.engine_truth = engineTruthJson(cfg, effects);
    widenToRealisedGeometry(c.engine_truth, cfg, sim.truth);
  }
  // An acceleration term (vdot, omegadot) is judged against the term the multibody realises
  // in this drive's motion, per motor (measured only when a finding has one: it needs the
  // model twin).
  bool acc_found = false;
  for (const auto& f : rep.findings)
    acc_found |= f.effect == "unmodeled" &&
                 (f.parameters.contains("vdot") || f.parameters.contains("omegadot"));
  if (!c.engine_truth.is_null() && acc_found) {
    const RealisedAcceleration a = realisedAccelerationTerms(
        cfg, scenario, seed, scenario == "excite" ? duration_s : 0, effects, sim, so);
    c.engine_truth["vdot_in_drive_A"] = {a.vdot_A[0], a.vdot_A[1]};
    c.engine_truth["omegadot_in_drive_A"] = {a.omegadot_A[0], a.omegadot_A[1]};
  }
  std::set<std::string> eset;
  bool engine_ok = true;
  for (const auto& f : rep.findings) {
    c.findings.push_back({{"effect", f.effect}, {"parameters", f.parameters}});
    if (!f.physics.empty()) c.findings.back()["physics"] = f.physics;
    if (f.effect == "unmodeled" || f.effect == kWheelGeometryEffect) {
      const bool ok = engineTruthFinding(f, c.engine_truth);
      c.findings.back()["engine_truth"] = ok;
      engine_ok = engine_ok && ok;
    } else
      eset.insert(f.effect);
  }
  c.engine_correct = engine_ok && eset == tset;
  c.false_finding =
      !engine_ok || !std::includes(tset.begin(), tset.end(), eset.begin(), eset.end());
  c.cannot_tell = untoldEffects(effects, rs, rep.info);
  for (auto& e : effects) {
    double err = 1.0;
    for (auto& f : rep.findings)
      if (f.effect == e.id) err = std::min(err, parameterError(e, f, cfg));
    c.param_errors.push_back(err);
  }
  auto rmsPair = [&](const char* when) {
    double s = 0;
    int n = 0;
    for (auto ch : {"current_right", "current_left"})
      if (rep.channels.contains(ch) && rep.channels[ch][when].contains("rms"))
        s += std::pow(rep.channels[ch][when]["rms"].get<double>(), 2), ++n;
    return n ? std::sqrt(s / n) : 0.0;
  };
  c.val_rms_before = rmsPair("before");
  c.val_rms_after = rmsPair("after");
  return c;
}

namespace {
/// What every campaign drive shares: the random source, the drive picker, the log and the
/// list of cases (one JSON per drive).
struct CampaignContext {
  const config::WheelchairConfig& cfg;
  const CampaignOptions& opt;
  const DiagnosisOptions& dopt;
  std::mt19937_64& rng;
  std::function<std::string()> pickScenario;
  std::function<void(const std::string&, const CaseResult&)> log;
  nlohmann::json& cases;
};

/// Drives without any concealed effect: every finding is false (or, on MuJoCo, the engine's
/// own physics: engine_false_alarms / catalogue_false_alarms).
nlohmann::json cleanRuns(CampaignContext& x) {
  const auto& [cfg, opt, dopt, rng, pickScenario, log, cases] = x;
  int n = 0, alarms = 0, named_alarms = 0, engine_alarms = 0, catalogue_alarms = 0;
  for (int k = 0; k < opt.clean_runs; ++k) {
    std::string sc = pickScenario();
    uint64_t seed = rng() % 1000000;
    if (opt.unknown_only) continue;  // drawn, not run
    CaseResult c = runCase(cfg, sc, seed, opt.duration_s, {}, dopt, opt.engine);
    log(sc, c);
    ++n, alarms += !c.correct, named_alarms += !c.named_correct;
    engine_alarms += !c.engine_correct;
    bool named = false;  // a catalogue name (not `unmodeled`, not `wheel_geometry`)
    for (const auto& f : c.findings) named |= !f.contains("engine_truth");
    catalogue_alarms += named;
    auto j = c.toJson();
    j["scenario"] = sc, j["seed"] = seed, j["kind"] = "clean";
    cases.push_back(j);
  }
  return {{"runs", n},
          {"false_alarms", alarms},
          {"rate", n ? double(alarms) / n : 0},
          {"named_false_alarms", named_alarms},
          {"engine_false_alarms", engine_alarms},
          {"catalogue_false_alarms", catalogue_alarms}};
}

/// Drives with effects outside the catalogue: flagged, located and described against the truth
/// the generator states (unknownEffectScore), and the catalogue names used for them.
nlohmann::json unknownRuns(CampaignContext& x) {
  const auto& [cfg, opt, dopt, rng, pickScenario, log, cases] = x;
  int n = 0, flagged = 0, located = 0, described = 0;
  int traced = 0, located_traced = 0, described_traced = 0, described_in_group = 0;
  nlohmann::json no_trace = nlohmann::json::array();
  std::map<std::string, int> named;
  nlohmann::json kinds = nlohmann::json::object();
  for (int k = 0; k < opt.unknown_runs; ++k) {
    const auto es = opt.unknown_effects(rng);
    std::string sc = pickScenario();
    uint64_t seed = rng() % 1000000;
    CaseResult c = runCase(cfg, sc, seed, opt.duration_s, es, dopt, opt.engine);
    log(sc, c);
    const nlohmann::json score = unknownEffectScore(es, c.findings, opt.engine);
    const nlohmann::json trace = effectTrace(cfg, sc, seed, opt.duration_s, es, dopt, opt.engine);
    ++n, flagged += c.mismatch || !c.reported.empty();
    located += score["located"].get<bool>(), described += score["described"].get<bool>();
    described_in_group += score.value("described_in_group", false);
    const bool has_trace = trace["traced"].get<bool>();
    if (has_trace)
      ++traced, located_traced += score["located"].get<bool>(),
          described_traced += score["described"].get<bool>();
    else
      for (const auto& e : es) no_trace.push_back(effects::formatEffect(e) + " (" + sc + ")");
    for (const auto& r : c.reported) ++named[r.substr(0, r.find(' '))];
    const std::string kind = es.empty() ? "none" : es.front().id;
    if (!kinds.contains(kind)) kinds[kind] = {{"runs", 0}, {"located", 0}, {"described", 0}};
    auto& kj = kinds[kind];
    kj["runs"] = kj.value("runs", 0) + 1;
    kj["traced"] = kj.value("traced", 0) + int(has_trace);
    kj["located"] = kj.value("located", 0) + score["located"].get<int>();
    kj["described"] = kj.value("described", 0) + score["described"].get<int>();
    auto j = c.toJson();
    j["scenario"] = sc, j["seed"] = seed, j["kind"] = "unknown";
    j["unknown_score"] = score;
    j["trace"] = trace;
    cases.push_back(j);
  }
  return {{"runs", n},
          {"flagged", flagged},
          {"rate", n ? double(flagged) / n : 0},
          {"located", located},
          {"described", described},
          {"located_rate", n ? double(located) / n : 0},
          {"described_rate", n ? double(described) / n : 0},
          {"by_effect", kinds},
          {"named", named},
          // The same over the drives whose effect leaves a trace (effectTrace); the bar is
          // judged on all drives above, these say how many misses had anything to find.
          {"described_in_group", described_in_group},
          {"traced", traced},
          {"located_traced", located_traced},
          {"described_traced", described_traced},
          {"described_traced_rate", traced ? double(described_traced) / traced : 0},
          {"no_trace", no_trace}};
}
}  // namespace

nlohmann::json runCampaign(const config::WheelchairConfig& cfg, const CampaignOptions& opt,
                           const DiagnosisOptions& dopt) {
  std::mt19937_64 rng(opt.seed);
  nlohmann::json out, cases = nlohmann::json::array();
  auto pickScenario = [&]() {
    return opt.scenarios[std::uniform_int_distribution<size_t>(0, opt.scenarios.size() - 1)(rng)];
  };
  auto log = [&](const std::string& label, const CaseResult& c) {
    if (opt.verbose)
      std::cerr << label << (c.correct ? " OK  " : " FAIL") << " " << c.toJson().dump() << "\n";
  };
  nlohmann::json single = nlohmann::json::object();
  int tot = 0, totc = 0, totn = 0, tote = 0;
  for (auto& id : opt.effects) {
    int n = 0, ok = 0, named = 0, eng = 0, untold = 0, wrong = 0;
    std::vector<double> errs;
    for (int k = 0; k < opt.runs_per_effect; ++k) {
      auto e = randomEffect(id, rng);
      std::string sc = pickScenario();
      uint64_t seed = rng();
      if (opt.unknown_only) continue;  // drawn, not run
      CaseResult c = runCase(cfg, sc, seed % 1000000, opt.duration_s, {e}, dopt, opt.engine);
      log(sc, c);
      ++n, ok += c.correct, named += c.named_correct, eng += c.engine_correct;
      untold += !c.cannot_tell.empty(), wrong += c.false_finding;
      errs.push_back(c.param_errors[0]);
      auto j = c.toJson();
      j["scenario"] = sc, j["seed"] = seed % 1000000, j["kind"] = "single";
      cases.push_back(j);
    }
    tot += n, totc += ok, totn += named, tote += eng;
    int within = 0;
    for (double e : errs) within += e <= 0.25;
    single[id] = {{"runs", n},
                  {"correct", ok},
                  {"named_correct", named},
                  {"engine_correct", eng},
                  {"cannot_tell", untold},
                  {"false_finding", wrong},
                  {"rate", n ? double(ok) / n : 0},
                  {"median_param_error", median(errs)},
                  {"p90_param_error", quantile(errs, 0.9)},
                  {"within_25pct", within}};
  }
  out["single"] = single;
  out["single_rate"] = tot ? double(totc) / tot : 0;
  out["single_named_rate"] = tot ? double(totn) / tot : 0;
  out["single_engine_rate"] = tot ? double(tote) / tot : 0;
  // Drives with k distinct concealed effects (pairs, triples): counts and parameter errors.
  auto combinations = [&](std::size_t k, int runs, const char* kind) {
    int n = 0, ok = 0, named = 0, eng = 0, untold = 0, wrong = 0;
    std::vector<double> errs;
    for (int r = 0; r < runs && opt.effects.size() >= k; ++r) {
      std::vector<std::size_t> idx;
      while (idx.size() < k) {
        const std::size_t a = std::uniform_int_distribution<size_t>(0, opt.effects.size() - 1)(rng);
        if (std::find(idx.begin(), idx.end(), a) == idx.end()) idx.push_back(a);
      }
      std::vector<effects::EffectSpec> es;
      for (std::size_t a : idx) es.push_back(randomEffect(opt.effects[a], rng));
      const std::string sc = pickScenario();
      const uint64_t seed = rng() % 1000000;
      if (opt.unknown_only) continue;  // drawn, not run
      const CaseResult c = runCase(cfg, sc, seed, opt.duration_s, es, dopt, opt.engine);
      log(sc, c);
      ++n, ok += c.correct, named += c.named_correct, eng += c.engine_correct;
      untold += !c.cannot_tell.empty(), wrong += c.false_finding;
      for (double e : c.param_errors) errs.push_back(e);
      auto j = c.toJson();
      j["scenario"] = sc, j["seed"] = seed, j["kind"] = kind;
      cases.push_back(j);
    }
    int within = 0;
    for (double e : errs) within += e <= 0.25;
    return nlohmann::json{{"runs", n},
                          {"correct", ok},
                          {"named_correct", named},
                          {"engine_correct", eng},
                          {"cannot_tell", untold},
                          {"false_finding", wrong},
                          {"rate", n ? double(ok) / n : 0},
                          {"median_param_error", median(errs)},
                          {"within_25pct", within},
                          {"params", errs.size()}};
  };
  out["pairs"] = combinations(2, opt.pair_runs, "pair");
  CampaignContext ctx{cfg, opt, dopt, rng, pickScenario, log, cases};
  out["clean"] = cleanRuns(ctx);
  if (opt.triple_runs > 0 && opt.effects.size() >= 3)
    out["triples"] = combinations(3, opt.triple_runs, "triple");
  if (opt.unknown_runs > 0 && opt.unknown_effects) out["unknown"] = unknownRuns(ctx);
  out["engine"] = opt.engine;
  out["cases"] = cases;
  return out;
}

}  // namespace wheelchair::diagnosis
