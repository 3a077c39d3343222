#include "libwheelchair/simulation/Supervisory.h"

#include <algorithm>
#include <cmath>

namespace wheelchair::simulation {

bool Footprint::contains(double x, double y, double phi, double px, double py,
                         double margin) const {
  const double dx = px - x, dy = py - y;
  const double c = std::cos(phi), s = std::sin(phi);
  const double lx = c * dx + s * dy, ly = -s * dx + c * dy;
  return lx >= -rear_m - margin && lx <= front_m + margin && std::abs(ly) <= half_width_m + margin;
}

double supervisoryScale(const SupervisoryParams& p, const Footprint& fp, double x, double y,
                        double phi, double v, double om, const std::vector<Obstacle>& obs) {
  if (obs.empty() || (std::abs(v) < 1e-6 && std::abs(om) < 1e-6)) return 1.0;
  const int n = std::max(1, static_cast<int>(std::ceil(p.horizon_s / p.prediction_step_s)));
  double t_hit = -1;
  for (int k = 0; k <= n && t_hit < 0; ++k) {
    const double t = k * p.prediction_step_s;
    // Exact arc of constant (v, omega).
    double px, py;
    const double pphi = phi + om * t;
    if (std::abs(om) < 1e-9) {
      px = x + v * t * std::cos(phi);
      py = y + v * t * std::sin(phi);
    } else {
      px = x + v / om * (std::sin(pphi) - std::sin(phi));
      py = y - v / om * (std::cos(pphi) - std::cos(phi));
    }
    for (const auto& o : obs)
      if (fp.contains(px, py, pphi, o.x_m, o.y_m, p.margin_m)) {
        t_hit = t;
        break;
      }
  }
  if (t_hit < 0) return 1.0;
  const double d = std::abs(v) > 0.05 ? std::abs(v) * t_hit : std::abs(om) * t_hit * fp.front_m;
  const double span = std::max(1e-6, p.slow_distance_m - p.stop_distance_m);
  return std::clamp((d - p.stop_distance_m) / span, 0.0, 1.0);
}

}  // namespace wheelchair::simulation
