// What the MuJoCo truth engine's wheels roll (issue 16): measures, on the nominal chair with
// no effect, (a) how far each tyre sphere sinks into the floor at rest (soft contact), (b) the
// effective rolling radius = distance the axle midpoint travels / wheel hinge angle while
// driving straight at steady speed, and (c) the effective track = r_eff (dpsi_R - dpsi_L) /
// dphi in a steady turn. The kinematic-calibration stage reports a `wheel_geometry` of about
// -0.1 % radius and +0.05-0.1 % track on MuJoCo drives; this says whether that is the engine's
// physics (docs/discovery.md, "MuJoCo's wheel geometry").
//
//   ./build/bench/mujoco_rolling_radius [--current A] [--turn A] [--body-mass KG]
// (the last line: the engine truth of simulation/MujocoTruth.h, which the campaign scores with)
#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/simulation/MujocoEngine.h"
#include "libwheelchair/simulation/MujocoTruth.h"

#include <fmt/core.h>

#include <cmath>
#include <cstdlib>
#include <string>

using namespace wheelchair;

int main(int argc, char** argv) {
  double current = 6, turn = 2, payload_kg = 0;
  for (int k = 1; k + 1 < argc; k += 2) {
    const std::string a = argv[k];
    if (a == "--current")
      current = std::atof(argv[k + 1]);
    else if (a == "--turn")
      turn = std::atof(argv[k + 1]);
    else if (a == "--body-mass")
      payload_kg = std::atof(argv[k + 1]);
    else {
      fmt::print(stderr,
                 "usage: mujoco_rolling_radius [--current A] [--turn A] [--body-mass KG]\n");
      return 2;
    }
  }
  const config::WheelchairConfig cfg;
  const double r = cfg.vehicle.geom.wheel_radius_m, b = cfg.vehicle.geom.track_width_m;
  {
    simulation::MujocoChair chair(cfg, simulation::MujocoOptions{}, {}, {});
    for (const auto& p : chair.parts())
      if (p.radius_m > 0)
        fmt::print(
            "tyre {}: radius {:.5f} m, centre {:.6f} m above the floor: sinks {:.3f} mm "
            "({:+.3f} % of the radius)\n",
            p.name, p.radius_m, p.z_m, 1e3 * (p.radius_m - p.z_m), 100 * (p.z_m / p.radius_m - 1));
  }
  const auto s = simulation::mujocoSteadyDrive(cfg, {}, current, current, 4, 6);
  const double r_eff = s.distance_m / (0.5 * (s.dpsi_right_rad + s.dpsi_left_rad));
  fmt::print(
      "straight ({} A each): {:.3f} m in 6 s, effective rolling radius {:.5f} m "
      "({:+.3f} % of the configured {:.4f} m)\n",
      current, s.distance_m, r_eff, 100 * (r_eff / r - 1), r);
  const auto t = simulation::mujocoSteadyDrive(cfg, {}, current + turn, current - turn, 4, 6);
  const double b_eff = r_eff * (t.dpsi_right_rad - t.dpsi_left_rad) / t.dphi_rad;
  fmt::print(
      "turning ({} / {} A): {:.2f} rad in 6 s, effective track {:.5f} m ({:+.3f} % of the "
      "configured {:.4f} m)\n",
      current + turn, current - turn, t.dphi_rad, b_eff, 100 * (b_eff / b - 1), b);
  // The engine truth the discovery campaign scores against (MujocoTruth.h).
  std::vector<effects::EffectSpec> effects;
  if (payload_kg > 0)  // the engine truth of a chair with payload_mass:body_mass_kg=KG
    effects.push_back(
        effects::parseValidEffect(fmt::format("payload_mass:body_mass_kg={}", payload_kg)));
  const auto truth = simulation::measureMujocoTruth(cfg, effects);
  for (const auto& d : truth.drives)
    fmt::print("  operating point {:+.1f} / {:+.1f} A: v {:.2f} m/s, omega {:+.2f} rad/s\n",
               d.current_right_A, d.current_left_A, d.speed_m_s, d.turn_rate_rad_s);
  fmt::print(
      "engine truth: radius {:+.3f} .. {:+.3f} %, track {:+.3f} .. {:+.3f} %, mass {:.1f} kg, "
      "centre of mass {:.4f} m ahead of the axle; current terms per side: v*omega {:+.3f} "
      "(right; left -), omega^2 {:+.3f}, vdot {:+.3f} (both), omegadot {:+.3f} A (right; left -)\n",
      100 * truth.radius_rel_min, 100 * truth.radius_rel_max, 100 * truth.track_rel_min,
      100 * truth.track_rel_max, truth.mass_kg, truth.mass_moment_kg_m / truth.mass_kg,
      truth.vOmegaCurrentCoefficient(cfg), truth.omegaSquaredCurrentCoefficient(cfg), truth.vdot_A,
      truth.omegadot_A);
  return 0;
}
