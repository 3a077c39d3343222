// What the MuJoCo truth engine's chair IS, measured on the multibody itself, independently of
// any diagnosis (issue 16): the campaign scorer (diagnosis/Campaign.h) uses it to tell the
// engine's own physics, found from the data, from false findings.
//
//   effective rolling radius  r_eff = distance the axle midpoint travels / mean wheel hinge
//                             angle, driving straight with both currents held (steady state);
//   effective track           b_eff = r_eff (dpsi_R - dpsi_L) / dphi in a steady turn;
//                             both as relative deviations from [vehicle] wheel_radius_m,
//                             track_width_m, over a set of operating points (min..max): the
//                             sphere tyres sink into MuJoCo's soft contact and creep, so the
//                             values depend on speed and turn rate;
//   mass moment               sum m_k x_k (kg m) of all bodies about the drive axle along the
//                             chassis x axis: the centre of mass d = moment / mass ahead of the
//                             axle, which model (6) leaves out. It adds to each motor current
//                             (A) the terms  +-(moment c / l_w) v omega  (right +, left -: the
//                             yaw moment m d v omega the drive wheels must supply) and
//                             -(moment c / 2) omega^2 (the forward force m d omega^2), with
//                             c = r / (eta k_m r_G) the current per newton of wheel force;
//   acceleration terms        the current per unit acceleration the multibody needs beyond
//                             model (6) with the same mass (castor wheels' spin, the payload's
//                             yaw inertia about the axle, ...): from rest, currents held 0.4 s
//                             (both +4 A: vdot; +-3 A: omegadot), accelerations from the wheel
//                             hinge speeds, minus (6)'s inverse dynamics (model::DriveTrain)
//                             at the measured motion, per unit acceleration.
//
// Example (nominal chair: r_eff -0.12 %, track +0.0..+0.45 % by turn rate, d = 0.070 m):
//   MujocoTruth t = measureMujocoTruth(cfg, {});
//   double k = t.vOmegaCurrentCoefficient(cfg);   // ~2.2 A per (m/s rad/s)
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/effects/Effect.h"
#include "libwheelchair/simulation/Simulator.h"

#include <vector>

namespace wheelchair::simulation {

/// One steady drive of the multibody with the two currents held (A).
struct MujocoSteadyDrive {
  double current_right_A = 0, current_left_A = 0;
  double distance_m = 0;  ///< path length of the axle midpoint over the measuring time
  double dpsi_right_rad = 0, dpsi_left_rad = 0, dphi_rad = 0;
  double speed_m_s = 0, turn_rate_rad_s = 0;  ///< means over the measuring time
};

/// Holds the currents for settle_s, then measures over measure_s (MuJoCo step 5 ms).
MujocoSteadyDrive mujocoSteadyDrive(const config::WheelchairConfig& cfg,
                                    const std::vector<effects::EffectSpec>& effects,
                                    double current_right_A, double current_left_A,
                                    double settle_s = 3, double measure_s = 4);

struct MujocoTruth {
  double radius_rel_min = 0, radius_rel_max = 0;  ///< r_eff / wheel_radius_m - 1
  double track_rel_min = 0, track_rel_max = 0;    ///< b_eff / track_width_m - 1
  double mass_kg = 0;                             ///< total mass of the multibody
  double mass_moment_kg_m = 0;                    ///< sum m x about the axle (kg m)
  /// Right motor current per unit acceleration beyond (6): vdot (A s^2/m; left the same),
  /// omegadot (A s^2/rad; left the opposite).
  double vdot_A = 0, omegadot_A = 0;
  std::vector<MujocoSteadyDrive> drives;  ///< the operating points measured
  /// Current per newton of wheel force, c = r / (eta k_m r_G) (A/N).
  static double currentPerNewton(const config::WheelchairConfig& cfg);
  /// Expected coefficient of v*omega in the RIGHT motor's current (A s^2/(m rad)); left: -.
  double vOmegaCurrentCoefficient(const config::WheelchairConfig& cfg) const;
  /// Expected coefficient of omega^2 in each motor's current (A s^2/rad^2).
  double omegaSquaredCurrentCoefficient(const config::WheelchairConfig& cfg) const;
};

/// Measures the chair with these effects (catalogue and MuJoCo-only; sensor effects do not
/// change it) at straight drives of 3 and 6 A and turns 6+-2 A, 3+-1.5 A and in place +-3 A.
/// Takes ~1 s.
MujocoTruth measureMujocoTruth(const config::WheelchairConfig& cfg,
                               const std::vector<effects::EffectSpec>& effects);

/// The odometric geometry the chair realises in ONE drive's own motion, from the engine's exact
/// state (body pose and wheel hinge angles of the truth trajectory; no sensor is used), so that
/// a `wheel_geometry` finding can be scored against the geometry of the drive it was found on
/// (the steady drives of measureMujocoTruth are operating points the drive may not visit: on
/// the 90-s excite drives the multibody rolls -0.09..-0.10 % short, with or without a payload,
/// where the steady 3 / 6 A drives give -0.13 / -0.14 %). Over non-overlapping windows of
/// window_s: ds the body's displacement along its mid-window heading, dphi its heading change,
/// dpsi_R, dpsi_L the hinge angles;
///     effective radius  r = sum(ds m) / sum(m^2),  m = (dpsi_R + dpsi_L) / 2  (least squares);
///     effective track   b = sum(d^2) / sum(d dphi), d = r (dpsi_R - dpsi_L)   (d = b dphi);
/// both relative to [vehicle] wheel_radius_m, track_width_m. Windows with no rolling (|m| below
/// 1e-6 rad) carry no information and are skipped; fewer than 10 windows (or no turn): windows = 0.
/// Example (MuJoCo excite 799554, nominal chair): radius -0.097 %, track +0.070 %.
struct RealisedGeometry {
  double radius_rel = 0, track_rel = 0;
  int windows = 0;
};
RealisedGeometry realisedGeometry(const config::WheelchairConfig& cfg,
                                  const std::vector<TruthSample>& truth, double window_s = 0.1);

}  // namespace wheelchair::simulation
