// Planar kinematics (1) and the static obstacle seen from the moving base, (7) and (8),
// with their analytic Jacobians (checked against numerical differentiation in
// tests/model/test_kinematics.cpp).
//
// Pose (x, y, phi) in the inertial (start) frame, m and rad:
//   xdot = v cos phi,  ydot = v sin phi,  phidot = omega                        (1)
// Obstacle in the base frame, Cartesian p = (px, py) in m:
//   pdot = -S(omega) p - (v, 0)'  i.e.  pxdot = omega py - v,  pydot = -omega px     (7)
// Obstacle in the base frame, polar (d, beta) with p = d (cos beta, sin beta):
//   ddot = -v cos beta,   betadot = -omega + v sin beta / d                      (8)
// Example:
//   Eigen::Vector2d pdot = obstacleCartesianRate({2.0, 0.5}, 0.4, 0.1);
#pragma once

#include <Eigen/Core>

#include <cmath>

namespace wheelchair::model {

/// cos and sin of the heading phi, for callers that evaluate (1) and its Jacobians together
/// (the CD-EKF's right-hand side) and want the trigonometry once.
/// Inline: they sit on the filter's right-hand side path.
struct HeadingTrig {
  double cos_phi, sin_phi;
  explicit HeadingTrig(double phi_rad) : cos_phi(std::cos(phi_rad)), sin_phi(std::sin(phi_rad)) {}
};

/// (xdot, ydot, phidot) of (1).
inline Eigen::Vector3d poseRate(const HeadingTrig& h, double v_m_s, double omega_rad_s) {
  return {v_m_s * h.cos_phi, v_m_s * h.sin_phi, omega_rad_s};
}
Eigen::Vector3d poseRate(double phi_rad, double v_m_s, double omega_rad_s);
/// d poseRate / d (x, y, phi), d poseRate / d (v, omega).
inline Eigen::Matrix3d poseRateJacobianPose(const HeadingTrig& h, double v_m_s) {
  Eigen::Matrix3d J = Eigen::Matrix3d::Zero();
  J(0, 2) = -v_m_s * h.sin_phi;
  J(1, 2) = v_m_s * h.cos_phi;
  return J;
}
Eigen::Matrix3d poseRateJacobianPose(double phi_rad, double v_m_s);
inline Eigen::Matrix<double, 3, 2> poseRateJacobianVel(const HeadingTrig& h) {
  Eigen::Matrix<double, 3, 2> J = Eigen::Matrix<double, 3, 2>::Zero();
  J(0, 0) = h.cos_phi;
  J(1, 0) = h.sin_phi;
  J(2, 1) = 1.0;
  return J;
}
Eigen::Matrix<double, 3, 2> poseRateJacobianVel(double phi_rad);

/// (pxdot, pydot) of (7).
Eigen::Vector2d obstacleCartesianRate(const Eigen::Vector2d& p_m, double v_m_s, double omega_rad_s);
Eigen::Matrix2d obstacleCartesianJacobianP(double omega_rad_s);
/// d/d(v, omega)
Eigen::Matrix2d obstacleCartesianJacobianVel(const Eigen::Vector2d& p_m);

/// (ddot, betadot) of (8); q = (d_m, beta_rad), d > 0.
Eigen::Vector2d obstaclePolarRate(const Eigen::Vector2d& q, double v_m_s, double omega_rad_s);
Eigen::Matrix2d obstaclePolarJacobianQ(const Eigen::Vector2d& q, double v_m_s);
Eigen::Matrix2d obstaclePolarJacobianVel(const Eigen::Vector2d& q);

/// Change of variables between the two forms (beta in (-pi, pi]).
Eigen::Vector2d cartesianToPolar(const Eigen::Vector2d& p_m);
Eigen::Vector2d polarToCartesian(const Eigen::Vector2d& q);

/// Exact pose increment over dt for constant (v, omega) (arc integration of (1)).
Eigen::Vector3d integratePoseArc(const Eigen::Vector3d& pose, double v_m_s, double omega_rad_s,
                                 double dt_s);

/// Wraps an angle to (-pi, pi].
double wrapAngle(double a_rad);

}  // namespace wheelchair::model
