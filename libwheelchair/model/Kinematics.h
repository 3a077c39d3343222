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

namespace wheelchair::model {

/// (xdot, ydot, phidot) of (1).
Eigen::Vector3d poseRate(double phi_rad, double v_m_s, double omega_rad_s);
/// d poseRate / d (x, y, phi), d poseRate / d (v, omega).
Eigen::Matrix3d poseRateJacobianPose(double phi_rad, double v_m_s);
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
