#include "libwheelchair/simulation/MujocoTruth.h"

#include "libwheelchair/model/DriveDynamics.h"
#include "libwheelchair/simulation/MujocoEngine.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace wheelchair::simulation {

namespace {
MujocoOptions optionsOf(const config::WheelchairConfig& cfg) {
  MujocoOptions mo;
  mo.loadFromConfig(cfg.ini(), "mujoco");
  return mo;
}
/// The effects that change the multibody's rolling; a slope would make the steady drives
/// accelerate (the geometry of the chair does not depend on it).
std::vector<effects::EffectSpec> chairEffects(const std::vector<effects::EffectSpec>& effects) {
  std::vector<effects::EffectSpec> out;
  for (const auto& e : effects)
    if (e.id != "ground_slope") out.push_back(e);
  return out;
}
/// The right motor's current per unit acceleration beyond (6), from rest with the currents
/// (iR, iL) held: accelerations from the hinge speeds over [0.1, 0.4] s (after the first
/// transient), (6)'s currents for that motion with the chair's true body mass subtracted.
double accelerationTerm(const config::WheelchairConfig& cfg,
                        const std::vector<effects::EffectSpec>& effects, double iR, double iL,
                        bool yaw) {
  std::vector<effects::EffectSpec> mass;
  model::VehicleParams P = cfg.vehicle;
  for (const auto& e : effects)
    if (e.id == "payload_mass") mass.push_back(e), P.geom.body_mass_kg = e.number("body_mass_kg");
  MujocoChair chair(cfg, optionsOf(cfg), mass, {});
  const double h = 0.005, r = cfg.vehicle.geom.wheel_radius_m;
  const double lw = cfg.vehicle.geom.track_width_m;
  const Eigen::Vector2d i(iR, iL);
  auto motion = [&]() {
    const ChairState s = chair.state();
    const double uR = r * s.psidot_right_rad_s, uL = r * s.psidot_left_rad_s;
    return Eigen::Vector2d(0.5 * (uR + uL), (uR - uL) / lw);
  };
  double t = 0;
  for (; t < 0.1 - 1e-9; t += h) chair.step(i, h);
  const Eigen::Vector2d m1 = motion();
  for (; t < 0.4 - 1e-9; t += h) chair.step(i, h);
  const Eigen::Vector2d m2 = motion();
  const Eigen::Vector2d acc = (m2 - m1) / 0.3, mid = 0.5 * (m1 + m2);
  const model::DriveTrain dt = model::DriveTrain::symmetric(P);
  const Eigen::Vector2d pred = dt.currents({mid(0), mid(1), 0.0}, acc(0), acc(1));
  return (iR - pred(0)) / (yaw ? acc(1) : acc(0));
}
}  // namespace

MujocoSteadyDrive mujocoSteadyDrive(const config::WheelchairConfig& cfg,
                                    const std::vector<effects::EffectSpec>& effects,
                                    double current_right_A, double current_left_A, double settle_s,
                                    double measure_s) {
  MujocoChair chair(cfg, optionsOf(cfg), chairEffects(effects), {});
  const double h = 0.005;
  const Eigen::Vector2d i(current_right_A, current_left_A);
  for (double t = 0; t < settle_s; t += h) chair.step(i, h);
  const ChairState a = chair.state();
  ChairState prev = a;
  MujocoSteadyDrive d;
  d.current_right_A = current_right_A, d.current_left_A = current_left_A;
  double T = 0;
  for (; T < measure_s; T += h) {
    chair.step(i, h);
    const ChairState b = chair.state();
    d.distance_m += std::hypot(b.x_m - prev.x_m, b.y_m - prev.y_m);
    prev = b;
  }
  d.dpsi_right_rad = prev.psi_right_rad - a.psi_right_rad;
  d.dpsi_left_rad = prev.psi_left_rad - a.psi_left_rad;
  d.dphi_rad = prev.phi_rad - a.phi_rad;
  d.speed_m_s = d.distance_m / T, d.turn_rate_rad_s = d.dphi_rad / T;
  return d;
}

double MujocoTruth::currentPerNewton(const config::WheelchairConfig& cfg) {
  const auto& P = cfg.vehicle;
  return P.geom.wheel_radius_m /
         (P.gearbox_efficiency * P.torque_constant_Nm_A * P.geom.gear_ratio);
}

double MujocoTruth::vOmegaCurrentCoefficient(const config::WheelchairConfig& cfg) const {
  return mass_moment_kg_m * currentPerNewton(cfg) / cfg.vehicle.geom.track_width_m;
}

double MujocoTruth::omegaSquaredCurrentCoefficient(const config::WheelchairConfig& cfg) const {
  return -0.5 * mass_moment_kg_m * currentPerNewton(cfg);
}

MujocoTruth measureMujocoTruth(const config::WheelchairConfig& cfg,
                               const std::vector<effects::EffectSpec>& effects) {
  MujocoTruth t;
  {
    // At rest after settling: the chassis frame is the axle midpoint, heading 0.
    MujocoChair chair(cfg, optionsOf(cfg), chairEffects(effects), {});
    const ChairState s = chair.state();
    for (const MujocoPart& p : chair.parts())
      if (p.mass_kg > 0) t.mass_kg += p.mass_kg, t.mass_moment_kg_m += p.mass_kg * (p.x_m - s.x_m);
  }
  t.vdot_A = accelerationTerm(cfg, effects, 4, 4, false);
  t.omegadot_A = accelerationTerm(cfg, effects, 3, -3, true);
  const double r = cfg.vehicle.geom.wheel_radius_m, b = cfg.vehicle.geom.track_width_m;
  const double inf = std::numeric_limits<double>::infinity();
  t.radius_rel_min = t.track_rel_min = inf;
  t.radius_rel_max = t.track_rel_max = -inf;
  double r_eff_sum = 0;
  for (const double i : {3.0, 6.0}) {
    MujocoSteadyDrive d = mujocoSteadyDrive(cfg, effects, i, i);
    const double r_eff = d.distance_m / (0.5 * (d.dpsi_right_rad + d.dpsi_left_rad));
    r_eff_sum += r_eff;
    t.radius_rel_min = std::min(t.radius_rel_min, r_eff / r - 1);
    t.radius_rel_max = std::max(t.radius_rel_max, r_eff / r - 1);
    t.drives.push_back(d);
  }
  const double r_eff = 0.5 * r_eff_sum;
  for (const auto& [iR, iL] : {std::pair{8.0, 4.0}, {4.5, 1.5}, {3.0, -3.0}}) {
    MujocoSteadyDrive d = mujocoSteadyDrive(cfg, effects, iR, iL);
    const double b_eff = r_eff * (d.dpsi_right_rad - d.dpsi_left_rad) / d.dphi_rad;
    t.track_rel_min = std::min(t.track_rel_min, b_eff / b - 1);
    t.track_rel_max = std::max(t.track_rel_max, b_eff / b - 1);
    t.drives.push_back(d);
  }
  return t;
}

RealisedGeometry realisedGeometry(const config::WheelchairConfig& cfg,
                                  const std::vector<TruthSample>& truth, double window_s) {
  struct Window {
    double ds, dphi, dR, dL;
  };
  std::vector<Window> w;
  for (std::size_t i = 0, j = 1; j < truth.size(); ++j) {
    const TruthSample &a = truth[i], &b = truth[j];
    if (b.t_s - a.t_s < window_s) continue;
    const double h = 0.5 * (a.phi_rad + b.phi_rad);
    const double ds = (b.x_m - a.x_m) * std::cos(h) + (b.y_m - a.y_m) * std::sin(h);
    const double dR = b.wheel_angle_right_rad - a.wheel_angle_right_rad,
                 dL = b.wheel_angle_left_rad - a.wheel_angle_left_rad;
    if (std::abs(0.5 * (dR + dL)) > 1e-6 || std::abs(dR - dL) > 1e-6)
      w.push_back({ds, b.phi_rad - a.phi_rad, dR, dL});
    i = j;
  }
  RealisedGeometry g;
  if (w.size() < 10) return g;
  double sm = 0, mm = 0;
  for (const auto& x : w) {
    const double m = 0.5 * (x.dR + x.dL);
    sm += x.ds * m, mm += m * m;
  }
  const double r = sm / mm;
  double dd = 0, dp = 0;
  for (const auto& x : w) {
    const double d = r * (x.dR - x.dL);
    dd += d * d, dp += d * x.dphi;
  }
  if (!(dp > 0)) return g;  // no turn: the track is not realised in this drive
  g.radius_rel = r / cfg.vehicle.geom.wheel_radius_m - 1;
  g.track_rel = dd / dp / cfg.vehicle.geom.track_width_m - 1;
  g.windows = static_cast<int>(w.size());
  return g;
}

}  // namespace wheelchair::simulation
