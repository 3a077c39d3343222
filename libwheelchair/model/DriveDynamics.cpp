#include "libwheelchair/model/DriveDynamics.h"

#include <Eigen/LU>
#include <cmath>

namespace wheelchair::model {

namespace {

/// Smoothed sgn(u) = tanh(u / eps) and its derivative; eps <= 0 gives the hard sign.
double coulombShape(double u, double eps) {
  if (eps <= 0) return (u > 0) ? 1.0 : (u < 0 ? -1.0 : 0.0);
  return std::tanh(u / eps);
}
double coulombShapeDerivative(double u, double eps) {
  if (eps <= 0) return 0.0;
  const double t = std::tanh(u / eps);
  return (1.0 - t * t) / eps;
}

}  // namespace

DriveTrain DriveTrain::symmetric(const VehicleParams& p) {
  DriveTrain dt;
  dt.geom = p.geom;
  dt.wheel_inertia_kg_m2 = p.wheel_inertia_kg_m2;
  dt.yaw_inertia_kg_m2 = p.yaw_inertia_kg_m2;
  for (auto& s : dt.side) {
    s.torque_constant_Nm_A = p.torque_constant_Nm_A;
    s.gearbox_efficiency = p.gearbox_efficiency;
    s.motor_viscous_Nm_s_rad = p.motor_viscous_Nm_s_rad;
    s.motor_inertia_kg_m2 = p.motor_inertia_kg_m2;
    s.coulomb_A = 0;
  }
  return dt;
}

Eigen::Matrix2d DriveTrain::massMatrix() const {
  const double r = geom.wheel_radius_m, rG = geom.gear_ratio, lw = geom.track_width_m;
  const double mw = geom.wheel_mass_kg, mb = geom.body_mass_kg;
  Eigen::Matrix2d A;
  for (int i = 0; i < 2; ++i) {
    const double s = (i == 0) ? 1.0 : -1.0;
    const DriveSide& d = side[i];
    const double alpha = 1.0 / (d.gearbox_efficiency * d.torque_constant_Nm_A);
    // Current per unit rim acceleration from the rotating parts (motor and wheel).
    const double rot = d.motor_inertia_kg_m2 * rG / r + wheel_inertia_kg_m2 / (r * rG);
    A(i, 0) = alpha * (rot + r / rG * (mw + mb / 2));
    A(i, 1) = alpha * (s * lw / 2 * rot + r / rG * (mw * s * lw / 2 + s * yaw_inertia_kg_m2 / lw));
  }
  return A;
}

Eigen::Vector2d DriveTrain::biasCurrents(const MotionState& st) const {
  const double r = geom.wheel_radius_m, rG = geom.gear_ratio, lw = geom.track_width_m;
  const double mass = geom.body_mass_kg + 2 * geom.wheel_mass_kg;
  const double g_along =
      mass * gravity_m_s2 * std::sin(slope_rad) * std::cos(st.phi_rad - downhill_heading_rad);
  Eigen::Vector2d b;
  for (int i = 0; i < 2; ++i) {
    const double s = (i == 0) ? 1.0 : -1.0;
    const DriveSide& d = side[i];
    const double alpha = 1.0 / (d.gearbox_efficiency * d.torque_constant_Nm_A);
    const double u = st.v_m_s + s * lw * st.omega_rad_s / 2;
    b(i) = d.motor_viscous_Nm_s_rad / d.torque_constant_Nm_A * rG / r * u +
           d.coulomb_A * coulombShape(u, coulomb_smoothing_m_s) - alpha * r / rG * g_along / 2;
  }
  return b;
}

Eigen::Vector2d DriveTrain::currents(const MotionState& s, double vdot, double omegadot) const {
  return massMatrix() * Eigen::Vector2d(vdot, omegadot) + biasCurrents(s);
}

Eigen::Vector2d DriveTrain::acceleration(const MotionState& s,
                                         const Eigen::Vector2d& currents_A) const {
  return massMatrix().partialPivLu().solve(currents_A - biasCurrents(s));
}

Eigen::Matrix<double, 2, 3> DriveTrain::biasCurrentsJacobian(const MotionState& st) const {
  const double r = geom.wheel_radius_m, rG = geom.gear_ratio, lw = geom.track_width_m;
  const double mass = geom.body_mass_kg + 2 * geom.wheel_mass_kg;
  // d G_along / d phi
  const double dg_dphi =
      -mass * gravity_m_s2 * std::sin(slope_rad) * std::sin(st.phi_rad - downhill_heading_rad);
  Eigen::Matrix<double, 2, 3> J;
  for (int i = 0; i < 2; ++i) {
    const double s = (i == 0) ? 1.0 : -1.0;
    const DriveSide& d = side[i];
    const double alpha = 1.0 / (d.gearbox_efficiency * d.torque_constant_Nm_A);
    const double u = st.v_m_s + s * lw * st.omega_rad_s / 2;
    // d b_i / d u_i; u_i depends on v with slope 1 and on omega with slope s l_w / 2.
    const double db_du = d.motor_viscous_Nm_s_rad / d.torque_constant_Nm_A * rG / r +
                         d.coulomb_A * coulombShapeDerivative(u, coulomb_smoothing_m_s);
    J(i, 0) = db_du;
    J(i, 1) = db_du * s * lw / 2;
    J(i, 2) = -alpha * r / rG * dg_dphi / 2;
  }
  return J;
}

Eigen::Matrix<double, 2, 3> DriveTrain::accelerationJacobianState(const MotionState& s) const {
  return -massMatrix().partialPivLu().solve(biasCurrentsJacobian(s));
}

Eigen::Matrix2d DriveTrain::accelerationJacobianCurrents() const {
  return massMatrix().inverse();
}

LumpedTheta DriveTrain::sideTheta(int i) const {
  VehicleParams p;
  p.geom = geom;
  p.wheel_inertia_kg_m2 = wheel_inertia_kg_m2;
  p.yaw_inertia_kg_m2 = yaw_inertia_kg_m2;
  p.torque_constant_Nm_A = side[i].torque_constant_Nm_A;
  p.gearbox_efficiency = side[i].gearbox_efficiency;
  p.motor_viscous_Nm_s_rad = side[i].motor_viscous_Nm_s_rad;
  p.motor_inertia_kg_m2 = side[i].motor_inertia_kg_m2;
  return lumpedTheta(p);
}

}  // namespace wheelchair::model
