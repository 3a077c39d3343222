// Picture of the MuJoCo engine's multibody (docs/simulation.md, "MuJoCo engine"): top and side
// view of the compiled model after settling on the floor -- the bodies' centres of mass (disc
// area ~ mass, labelled), the tyre spheres, the axle, the castor forks, the chassis plate and
// the sonar's ray fan. Drawn from MujocoChair::parts(), i.e. from the model MuJoCo simulates.
//
//   build/bench/mujoco_schematic [--config F] [--effect ID:k=v ...] OUT.png
#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/simulation/MujocoEngine.h"
#include "libwheelchair/visualization/Plot.h"

#include <fmt/core.h>

#include <cmath>
#include <iostream>
#include <map>
#include <string>
#include <vector>

using namespace wheelchair;
namespace viz = wheelchair::visualization;

int main(int argc, char** argv) {
  std::string cfg_path, out;
  std::vector<effects::EffectSpec> effects;
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      if (a == "--config" && i + 1 < argc)
        cfg_path = argv[++i];
      else if (a == "--effect" && i + 1 < argc)
        effects.push_back(simulation::parseEngineEffect(argv[++i], "mujoco"));
      else if (!a.empty() && a[0] != '-' && out.empty())
        out = a;
      else
        throw std::invalid_argument("unexpected argument '" + a + "'");
    }
  } catch (const std::exception& e) {
    std::cerr << "mujoco_schematic: " << e.what()
              << "\nusage: mujoco_schematic [--config F] [--effect ID:k=v ...] OUT.png\n";
    return 2;
  }
  if (out.empty()) {
    std::cerr << "usage: mujoco_schematic [--config F] [--effect ID:k=v ...] OUT.png\n";
    return 2;
  }
  const auto cfg =
      cfg_path.empty() ? config::WheelchairConfig() : config::WheelchairConfig::load(cfg_path);
  simulation::MujocoOptions mo;
  mo.loadFromConfig(cfg.ini());
  const simulation::MujocoChair chair(cfg, mo, effects, {});
  const auto parts = chair.parts();

  // Two panels: top view (x right, y up) and side view (x right, z up), 500 px per metre.
  const double s = 500, x0 = -0.45, x1 = 1.15, W = (x1 - x0) * s + 80;
  const double top_h = 1.0 * s, side_h = 0.8 * s, H = top_h + side_h + 190;
  viz::Raster img(static_cast<int>(W), static_cast<int>(H));
  const double top_y0 = 60 + top_h / 2, side_y0 = 60 + top_h + 50 + side_h;
  auto TX = [&](double x) { return 40 + (x - x0) * s; };
  auto TY = [&](double y) { return top_y0 - y * s; };
  auto SZ = [&](double z) { return side_y0 - z * s; };
  img.text(W / 2, 10,
           fmt::format("MuJoCo chair: top view (x forward, y left) and side view; total {:.1f} kg",
                       chair.totalMass()),
           viz::colors::black, 0.9, 0, -1);
  img.text(40, 40, "top", viz::colors::gray, 0.8);
  img.text(40, 60 + top_h + 25, "side", viz::colors::gray, 0.8);
  // Floor and the chassis plate (the visual box of the MJCF).
  img.line(TX(x0), SZ(0), TX(x1), SZ(0), viz::colors::black, 2);
  const double r = cfg.vehicle.geom.wheel_radius_m;
  img.rect(TX(-0.20), TY(0.25), TX(0.50), TY(-0.25), viz::colors::gray, 1.5);
  img.fillRect(TX(-0.20), SZ(r + 0.08), TX(0.50), SZ(r + 0.02), viz::colors::light_gray, 1.0);
  // Sonar ray fan (top view).
  const auto& son = cfg.sonar;
  for (int k = 0; k < 7; ++k) {
    const double a = (son.yaw_deg + son.cone_half_angle_deg * (k / 3.0 - 1)) * M_PI / 180;
    img.line(TX(son.x_m), TY(son.y_m), TX(son.x_m + 0.35 * std::cos(a)),
             TY(son.y_m + 0.35 * std::sin(a)), viz::colors::orange, 1, 0.8);
  }
  img.text(TX(son.x_m + 0.36), TY(son.y_m), "sonar rays", viz::colors::orange, 0.7, -1, 0);
  // Tyres (spheres), axle and forks.
  std::map<std::string, simulation::MujocoPart> by_name;
  for (const auto& p : parts) by_name[p.name] = p;
  for (const auto& p : parts) {
    if (p.radius_m <= 0) continue;
    const auto c = p.name.rfind("castor", 0) == 0 ? viz::colors::purple : viz::colors::blue;
    std::vector<std::pair<double, double>> top, side;
    for (int k = 0; k <= 48; ++k) {
      const double a = 2 * M_PI * k / 48;
      top.push_back({TX(p.x_m + p.radius_m * std::cos(a)), TY(p.y_m + p.radius_m * std::sin(a))});
      side.push_back({TX(p.x_m + p.radius_m * std::cos(a)), SZ(p.z_m + p.radius_m * std::sin(a))});
    }
    img.polyline(top, c, 2);
    img.polyline(side, c, 2);
  }
  if (by_name.count("tyre_right") && by_name.count("tyre_left")) {
    const auto &a = by_name["tyre_right"], &b = by_name["tyre_left"];
    img.line(TX(a.x_m), TY(a.y_m), TX(b.x_m), TY(b.y_m), viz::colors::blue, 2.5);
    img.text(TX(a.x_m) + 6, TY(a.y_m) + 8, "drive wheel R (hinge, motor)", viz::colors::blue, 0.7);
    img.text(TX(b.x_m) + 6, TY(b.y_m) - 28, "drive wheel L", viz::colors::blue, 0.7);
  }
  for (const char* side : {"right", "left"}) {
    const std::string f = std::string("fork_") + side, t = std::string("castor_tyre_") + side;
    if (!by_name.count(f) || !by_name.count(t)) continue;
    const auto &fp = by_name[f], &tp = by_name[t];
    const double ax = fp.x_m + (fp.x_m - tp.x_m);  // swivel axis: the fork CoM is halfway
    img.line(TX(ax), TY(fp.y_m), TX(tp.x_m), TY(tp.y_m), viz::colors::purple, 2);
    img.disc(TX(ax), TY(fp.y_m), 4, viz::colors::purple);
    img.line(TX(ax), SZ(r + 0.02), TX(ax), SZ(tp.z_m), viz::colors::purple, 2);
    img.line(TX(ax), SZ(tp.z_m), TX(tp.x_m), SZ(tp.z_m), viz::colors::purple, 2);
  }
  img.text(TX(0.40), TY(-0.42), "castor forks swivel (trail behind axis)", viz::colors::purple,
           0.7);
  // Centres of mass: disc area ~ mass.
  for (const auto& p : parts) {
    if (p.mass_kg <= 0 || p.name.rfind("wheel_", 0) == 0) continue;
    const double rad = 3 + 1.6 * std::sqrt(p.mass_kg);
    img.disc(TX(p.x_m), TY(p.y_m), rad, viz::colors::red, 0.35);
    img.disc(TX(p.x_m), SZ(p.z_m), rad, viz::colors::red, 0.35);
    const std::string label = fmt::format("{} {:.1f} kg", p.name, p.mass_kg);
    if (p.mass_kg > 5) {
      img.text(TX(p.x_m) + rad + 4, SZ(p.z_m), label, viz::colors::red, 0.7, -1, 0);
    }
  }
  img.text(40, H - 45,
           "red: body centres of mass (area ~ mass); blue: drive tyres (spheres r); purple: "
           "castors; grey: chassis plate",
           viz::colors::black, 0.65);
  try {
    img.save(out);
  } catch (const std::exception& e) {
    std::cerr << "mujoco_schematic: " << e.what() << "\n";
    return 1;
  }
  std::cout << "wrote " << out << "\n";
  return 0;
}
