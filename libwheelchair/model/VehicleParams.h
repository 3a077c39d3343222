// Physical parameters of the wheelchair and the lumped parameters of the paper's model.
//
// Frames and signs (docs/model.md, vehicle.md): body frame at the drive-axle midpoint, x
// forward, y left; index 0 = right wheel/motor (the paper's 1), index 1 = left (the paper's 2);
// omega > 0 turns left; wheel rim speeds u_R = v + l_w*omega/2, u_L = v - l_w*omega/2; motor
// currents are positive when they drive the chair forward.
//
// The lumped parameter vector of eq. (3):
//   theta = (1/(eta_G k_m), J_m/(eta_G k_m), I_w/(eta_G k_m), I_zz/(eta_G k_m), B_m/k_m)'
// Example:
//   VehicleParams p;                       // nominal vehicle of vehicle.md
//   LumpedTheta th = lumpedTheta(p);       // eq. (3)
//   OdeCoefficients a = odeCoefficients(p.geometry(), th);   // Appendix VI: a1..a4
#pragma once

#include <Eigen/Core>

namespace wheelchair::model {

/// Geometry and masses: what the regressor Y needs besides the state.
struct Geometry {
  double wheel_radius_m = 0.17;  ///< r
  /// Effective rolling radius of each wheel for odometry (ticks -> rim distance), m; 0 = r.
  /// Set by odometry calibration (diagnosis/KinematicCalibration.h) or an importer whose
  /// robot has unequal wheels; the dynamics keep using r.
  double wheel_radius_right_m = 0;
  double wheel_radius_left_m = 0;
  double track_width_m = 0.55;   ///< l_w, distance between the drive wheels
  double gear_ratio = 18.0;      ///< r_G, motor turns per wheel turn
  double wheel_mass_kg = 8.0;    ///< m_w, one drive wheel with its rotating parts
  double body_mass_kg = 130.0;   ///< m_b, chair body with its user
  /// Direction of travel relative to the heading the ground truth measures, rad (+ = left):
  /// a motion-capture body frame rotated off the axle, or an axle not square to the body. Used
  /// by odometric dead reckoning against ground truth (identification/OdometryCalibration.h);
  /// the estimators do not use it.
  double odometry_travel_angle_rad = 0;

  /// Odometric radius of side 0 (right) / 1 (left): the per-side value if set, else r.
  double odometryRadius(int side) const {
    const double rs = side == 0 ? wheel_radius_right_m : wheel_radius_left_m;
    return rs > 0 ? rs : wheel_radius_m;
  }
};

/// Everything physical. Defaults are the nominal vehicle of vehicle.md; a program loads
/// them from configuration (config/VehicleConfig.h), never relies on these defaults.
struct VehicleParams {
  Geometry geom;
  double motor_inertia_kg_m2 = 3.0e-4;     ///< J_m
  double wheel_inertia_kg_m2 = 0.15;       ///< I_w,zz about the wheel's spin axis
  double yaw_inertia_kg_m2 = 8.0;          ///< I_zz of the body about z through the axle midpoint
  double motor_viscous_Nm_s_rad = 2.3e-3;  ///< B_m
  double torque_constant_Nm_A = 0.09;      ///< k_m (= back-EMF constant in SI)
  double gearbox_efficiency = 0.85;        ///< eta_G
  double armature_resistance_ohm = 0.35;   ///< R_m

  const Geometry& geometry() const { return geom; }
};

/// theta of eq. (3); index k holds theta_{k+1} of the paper.
using LumpedTheta = Eigen::Matrix<double, 5, 1>;

LumpedTheta lumpedTheta(const VehicleParams& p);

/// Coefficients of the ODE form (6):
///   vdot     = a3 v     + a1 (i_R + i_L)
///   omegadot = a4 omega + a2 (i_R - i_L)
struct OdeCoefficients {
  double a1 = 0;  ///< m/s^2 per A
  double a2 = 0;  ///< rad/s^2 per A
  double a3 = 0;  ///< 1/s (negative)
  double a4 = 0;  ///< 1/s (negative)
};

/// Appendix VI formulas (with the corrected r_G/r factor on theta_2, see docs/model.md).
OdeCoefficients odeCoefficients(const Geometry& g, const LumpedTheta& theta);

/// Regressor of eq. (2), corrected: currents (i_R, i_L) = Y(v, vdot, omega, omegadot) theta.
/// Row 0 is the right motor, row 1 the left one.
Eigen::Matrix<double, 2, 5> regressor(const Geometry& g, double v_m_s, double vdot_m_s2,
                                      double omega_rad_s, double omegadot_rad_s2);

/// Currents that the ODE form (6) implies for a given state and acceleration (its inverse):
/// i_R + i_L = (vdot - a3 v)/a1, i_R - i_L = (omegadot - a4 omega)/a2.
Eigen::Vector2d currentsFromOde(const OdeCoefficients& a, double v_m_s, double vdot_m_s2,
                                double omega_rad_s, double omegadot_rad_s2);

/// (vdot, omegadot) of the ODE form (6).
Eigen::Vector2d odeAcceleration(const OdeCoefficients& a, double v_m_s, double omega_rad_s,
                                double i_right_A, double i_left_A);

}  // namespace wheelchair::model
