// Per-wheel torque balance of the differential-drive chair, with per-side drive parameters
// and the physical terms the nominal model (6) leaves out.
//
// For each side i (s_R = +1, s_L = -1), with rim speed u_i = v + s_i l_w omega / 2 and the
// traction force F_i the ground exerts on that wheel:
//
//   eta_i k_i I_i = J_i (r_G/r) udot_i + eta_i B_i (r_G/r) u_i + (I_w udot_i + r F_i)/r_G
//                   + eta_i k_i c_i sgn(u_i)                                 [motor + gearbox]
//   F_R + F_L     = (m_b + 2 m_w) vdot - G_along                             [body, forward]
//   (F_R - F_L) l_w/2 = (I_zz + m_w l_w^2/2) omegadot                        [body, yaw]
//
// with F_i = m_w udot_i + m_b vdot/2 + s_i I_zz omegadot/l_w - G_along/2 solving the last two,
// G_along = (m_b + 2 m_w) g sin(slope) cos(phi - downhill_heading) the gravity component along
// the heading (positive downhill), and c_i a dry (Coulomb) friction expressed as the motor
// current it costs. Dividing by eta_i k_i gives the paper's regressor form (2) when the two
// sides are identical and there is no slope or dry friction, and (6) follows by solving
//   I = A [vdot; omegadot] + b(v, omega, phi)
// for the accelerations (docs/model.md has the derivation).
//
// Example:
//   DriveTrain dt = DriveTrain::symmetric(VehicleParams{});
//   dt.side[0].coulomb_A = 0.5;                          // right drive has dry friction
//   Eigen::Vector2d acc = dt.acceleration({v, omega, phi}, {iR, iL});
#pragma once

#include "libwheelchair/model/VehicleParams.h"

#include <Eigen/Core>

namespace wheelchair::model {

/// One motor with its gearbox (index 0 right, 1 left).
struct DriveSide {
  double torque_constant_Nm_A = 0.09;      ///< k_i
  double gearbox_efficiency = 0.85;        ///< eta_i
  double motor_viscous_Nm_s_rad = 2.3e-3;  ///< B_i
  double motor_inertia_kg_m2 = 3.0e-4;     ///< J_i
  double coulomb_A = 0.0;                  ///< c_i, dry friction as a current (A)
};

/// Velocity state the dynamics need: linear and angular speed and heading.
struct MotionState {
  double v_m_s = 0;
  double omega_rad_s = 0;
  double phi_rad = 0;  ///< heading in the start frame (only the slope term uses it)
};

struct DriveTrain {
  Geometry geom;
  double wheel_inertia_kg_m2 = 0.15;
  double yaw_inertia_kg_m2 = 8.0;
  DriveSide side[2];
  double slope_rad = 0.0;             ///< floor inclination
  double downhill_heading_rad = 0.0;  ///< heading (start frame) that points downhill
  double gravity_m_s2 = 9.81;
  double coulomb_smoothing_m_s = 0.01;  ///< sgn(u) ~ tanh(u / this): keeps the ODE smooth

  static DriveTrain symmetric(const VehicleParams& p);

  /// A of I = A [vdot; omegadot] + b: current per unit acceleration (A per m/s^2, A per rad/s^2).
  Eigen::Matrix2d massMatrix() const;
  /// b of I = A [vdot; omegadot] + b: currents at zero acceleration (A).
  Eigen::Vector2d biasCurrents(const MotionState& s) const;
  /// Motor currents needed for a given motion and acceleration (the inverse dynamics).
  Eigen::Vector2d currents(const MotionState& s, double vdot_m_s2, double omegadot_rad_s2) const;
  /// (vdot, omegadot) produced by motor currents (the forward dynamics).
  Eigen::Vector2d acceleration(const MotionState& s, const Eigen::Vector2d& currents_A) const;

  /// d biasCurrents / d (v, omega, phi), analytic (A per m/s, A per rad/s, A per rad).
  Eigen::Matrix<double, 2, 3> biasCurrentsJacobian(const MotionState& s) const;
  /// d acceleration / d (v, omega, phi) = -A^-1 d b / d (v, omega, phi). The currents do not
  /// enter it: the forward dynamics are affine in the currents.
  Eigen::Matrix<double, 2, 3> accelerationJacobianState(const MotionState& s) const;
  /// d acceleration / d (i_R, i_L) = A^-1 (constant).
  Eigen::Matrix2d accelerationJacobianCurrents() const;

  /// Lumped theta of side i: eq. (3) with that side's motor and gearbox.
  LumpedTheta sideTheta(int i) const;
};

/// Nominal vehicle as a drive train: both sides equal to p, flat floor, no dry friction.
inline DriveTrain makeDriveTrain(const VehicleParams& p) {
  return DriveTrain::symmetric(p);
}

}  // namespace wheelchair::model
