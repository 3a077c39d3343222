// What the MuJoCo truth engine's wheels roll (issue 16): measures, on the nominal chair with
// no effect, (a) how far each tyre sphere sinks into the floor at rest (soft contact), (b) the
// effective rolling radius = distance the axle midpoint travels / wheel hinge angle while
// driving straight at steady speed, and (c) the effective track = r_eff (dpsi_R - dpsi_L) /
// dphi in a steady turn. The kinematic-calibration stage reports a `wheel_geometry` of about
// -0.1 % radius and +0.05-0.1 % track on MuJoCo drives; this says whether that is the engine's
// physics (docs/discovery.md, "MuJoCo's wheel geometry").
//
//   ./build/bench/mujoco_rolling_radius [--current A] [--turn A]
#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/simulation/MujocoEngine.h"

#include <fmt/core.h>

#include <cmath>
#include <cstdlib>
#include <string>

using namespace wheelchair;

namespace {

struct Drive {
  double ds_m = 0, dpsi_r = 0, dpsi_l = 0, dphi = 0;
};

// Drives with the currents held for settle_s, then measures over measure_s.
Drive drive(const config::WheelchairConfig& cfg, double iR, double iL, double settle_s,
            double measure_s) {
  simulation::MujocoChair chair(cfg, simulation::MujocoOptions{}, {}, {});
  const double h = 0.005;
  const Eigen::Vector2d i(iR, iL);
  for (double t = 0; t < settle_s; t += h) chair.step(i, h);
  const auto a = chair.state();
  double s = 0;
  auto prev = a;
  for (double t = 0; t < measure_s; t += h) {
    chair.step(i, h);
    const auto b = chair.state();
    s += std::hypot(b.x_m - prev.x_m, b.y_m - prev.y_m);
    prev = b;
  }
  return {s, prev.psi_right_rad - a.psi_right_rad, prev.psi_left_rad - a.psi_left_rad,
          prev.phi_rad - a.phi_rad};
}

}  // namespace

int main(int argc, char** argv) {
  double current = 6, turn = 2;
  for (int k = 1; k + 1 < argc; k += 2) {
    const std::string a = argv[k];
    if (a == "--current")
      current = std::atof(argv[k + 1]);
    else if (a == "--turn")
      turn = std::atof(argv[k + 1]);
    else {
      fmt::print(stderr, "usage: mujoco_rolling_radius [--current A] [--turn A]\n");
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
  const Drive s = drive(cfg, current, current, 4, 6);
  const double r_eff = s.ds_m / (0.5 * (s.dpsi_r + s.dpsi_l));
  fmt::print(
      "straight ({} A each): {:.3f} m in 6 s, effective rolling radius {:.5f} m "
      "({:+.3f} % of the configured {:.4f} m)\n",
      current, s.ds_m, r_eff, 100 * (r_eff / r - 1), r);
  const Drive t = drive(cfg, current + turn, current - turn, 4, 6);
  const double b_eff = r_eff * (t.dpsi_r - t.dpsi_l) / t.dphi;
  fmt::print(
      "turning ({} / {} A): {:.2f} rad in 6 s, effective track {:.5f} m ({:+.3f} % of the "
      "configured {:.4f} m)\n",
      current + turn, current - turn, t.dphi, b_eff, 100 * (b_eff / b - 1), b);
  return 0;
}
