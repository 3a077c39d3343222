// Physics outside the diagnosis' catalogue, for the discovery campaign's `unknown` drives
// (issue 16 item 3): effects both truth engines apply (model engine: in the torque balance;
// MuJoCo: as a force and moment on the chassis), and for each effect, including the MuJoCo
// engine's own (mujocoEffectCatalogue), the TRUTH of what it is: the channel it acts on and
// the class of its dependence, stated here from the physics injected, never inferred from a
// diagnosis. The diagnosis does not know these names (they are not in effects/).
//
// Generic effects (forward force F along the heading, N; yaw moment M about the axle
// midpoint, N m; omega > 0 turns left; phi the heading in the start frame):
//   forward_viscous_drag   c_N_s_m          F = -c v                   (soft ground, grass)
//   forward_quadratic_drag c_N_s2_m2        F = -c v |v|               (aerodynamic / wading drag)
//   yaw_dry_friction       torque_Nm        M = -M0 tanh(omega / 0.02) (castor swivel / scrub)
//   yaw_viscous_friction   c_N_m_s_rad      M = -c omega               (castor swivel damping)
//   heading_yaw_torque     torque_Nm,       M = M0 sin(phi - heading)  (a weathervane torque:
//                          heading_deg                                   wind or a cross-slope
//                                                                        on an off-axle mass)
//   yaw_inertia            extra_kg_m2      M = -dI omegadot           (a load far from the axle)
//   current_offset         side, offset_A   the current sensor of one motor reads i + offset
// Truth vocabulary (the diagnosis' UnmodeledPhysics.h uses the same words):
//   channel    forward | yaw | wheels (each drive wheel, both sides) | current_right |
//              current_left | gyro_vs_encoders
//   dependence constant | sign_of_rate | rate | rate_squared | rate_product | heading |
//              acceleration | command | castor_swivel (a load while the castors swivel round)
//
// Example:
//   auto e = effects::parseEffect("yaw_dry_friction:torque_Nm=0.8");
//   ExternalLoad L = externalLoad({e});          // L.forceMoment(0.5, 0.3, 0) = (0, -0.8 N m)
//   UnknownEffectTruth t = unknownEffectTruth(e); // {"yaw", "sign_of_rate", ...}
#pragma once

#include "libwheelchair/effects/Effect.h"

#include <Eigen/Core>

#include <random>
#include <string>
#include <vector>

namespace wheelchair::simulation {

/// Generic out-of-catalogue effects (both engines).
const std::vector<effects::EffectInfo>& unknownEffectCatalogue();
/// Its entry for an id, or nullptr.
const effects::EffectInfo* findUnknownEffect(const std::string& id);

/// The generic effects' loads on the body, summed.
struct ExternalLoad {
  double viscous_N_s_m = 0, quadratic_N_s2_m2 = 0;
  double yaw_dry_Nm = 0, yaw_viscous_N_m_s_rad = 0;
  double heading_torque_Nm = 0, heading_rad = 0;
  double extra_yaw_inertia_kg_m2 = 0;
  double current_offset_A[2] = {0, 0};  ///< right, left: added to the measured current
  /// Forward force (N) and yaw moment (N m) at speed v (m/s), turn rate omega (rad/s),
  /// heading phi (rad); the yaw inertia is not in it (the engines add it to the body).
  Eigen::Vector2d forceMoment(double v_m_s, double omega_rad_s, double phi_rad) const;
  bool any() const;
};
ExternalLoad externalLoad(const std::vector<effects::EffectSpec>& effects);

/// One out-of-catalogue effect at a random magnitude for a campaign drive (docs/discovery.md
/// lists the ranges): a generic one, or on "mujoco" also one of the engine's own.
effects::EffectSpec randomUnknownEffect(const std::string& engine, std::mt19937_64& rng);

/// What an out-of-catalogue effect is: where it acts and what it depends on (vocabulary
/// above), and a physicist's sentence.
struct UnknownEffectTruth {
  std::string channel, dependence, physics;
};
/// Truth of a generic or MuJoCo-only effect; throws std::invalid_argument for other ids.
UnknownEffectTruth unknownEffectTruth(const effects::EffectSpec& e);

}  // namespace wheelchair::simulation
