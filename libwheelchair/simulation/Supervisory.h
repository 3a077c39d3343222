// Assist-as-needed supervisory control (paper II.F) and the chair's footprint.
//
// Rule (docs/simulation.md): every 1/rate_hz s the supervisor predicts the motion the
// driver demands -- the arc of constant (v_d, omega_d) from the current pose -- for
// horizon_s, and finds the first obstacle that would enter the footprint inflated by
// margin_m. With d the distance to that contact along the path (|v_d| t_hit, or for a turn
// in place the arc swept by the front corners, |omega_d| t_hit * front_m), both demanded
// velocities are scaled by
//   s = clamp((d - stop_distance_m) / (slow_distance_m - stop_distance_m), 0, 1)
// -- the closer the obstacle, the lower the velocities; s = 1 when nothing is on the
// predicted path. The direction (curvature) the driver asks for is kept, so the chair
// stops in front of the obstacle until the driver steers elsewhere. The supervisor uses the
// obstacle positions it is given (the truth in the simulator; an estimate on the chair).
//
// A collision is an obstacle centre inside the (uninflated) footprint: the rectangle
// x in [-rear_m, front_m], |y| <= half_width_m of the body frame (between the wheels).
//
// Example:
//   double s = supervisoryScale(SupervisoryParams{}, Footprint{}, {x, y, phi}, 0.52, 0.27, obs);
#pragma once

#include "libwheelchair/simulation/Scenarios.h"

#include <vector>

namespace wheelchair::simulation {

struct Footprint {
  double front_m = 0.60;       ///< front edge ahead of the axle (footrests)
  double rear_m = 0.30;        ///< rear edge behind the axle
  double half_width_m = 0.33;  ///< half width (drive wheels at l_w/2 = 0.275 plus tyres)

  /// Is world point (px, py) inside the footprint of the chair at pose (x, y, phi)?
  bool contains(double x, double y, double phi, double px, double py, double margin_m = 0) const;
};

struct SupervisoryParams {
  bool enabled = false;
  double slow_distance_m = 1.2;   ///< below this distance the demands are scaled down
  double stop_distance_m = 0.15;  ///< at or below this distance the chair is stopped
  double horizon_s = 4.0;         ///< prediction horizon of the demanded arc
  double prediction_step_s = 0.05;
  double margin_m = 0.05;  ///< footprint inflation for the prediction
  double rate_hz = 20.0;   ///< how often the supervisor updates its scale
};

/// Scale factor in [0, 1] for the demanded (v, omega) at pose (x, y, phi).
double supervisoryScale(const SupervisoryParams& p, const Footprint& fp, double x, double y,
                        double phi, double v_demand, double omega_demand,
                        const std::vector<Obstacle>& obstacles);

}  // namespace wheelchair::simulation
