// The continuous-time state-space model an EKF linearises, with analytic Jacobians
// (docs/model.md, "The filter model"; checked against numerical differentiation in
// tests/model/test_filter_model.cpp).
//
// State  x = [v, omega, x, y, phi, o1, o2]'   (m/s, rad/s, m, m, rad, obstacle)
// Input  u = [i_R, i_L]'                      (A, positive drives the chair forward)
// where (o1, o2) is the static obstacle in the base frame, either
//   Cartesian (px, py) in m, rates (7):  pxdot = omega py - v,  pydot = -omega px
//   Polar     (d, beta), m and rad, (8): ddot = -v cos beta,  betadot = -omega + v sin beta / d
// and (x, y, phi) the pose of the base frame (axle midpoint) in the inertial frame, rates (1).
// Velocities follow the ODE form (6): vdot = a3 v + a1 (i_R + i_L),
// omegadot = a4 omega + a2 (i_R - i_L).
//
//   xdot = f(x, u),   F = df/dx (7x7),   G = df/du (7x2)
//
// Measurements (each with its Jacobian H = dh/dx):
//   h_v     = v                                   (1x7)
//   h_omega = omega                               (1x7)
//   h_sonar = |p - s|, the range from the sonar at body position s (sonar_offset_m) to the
//             obstacle p (p = d (cos beta, sin beta) in polar form)     (1x7)
//   h_pozyx = (x, y) + R(phi) l, the inertial position of a tag at body lever arm l (2x7)
// The Pozyx anchor frame is not the inertial frame; aligning the two is the caller's business
// (h_pozyx is the position in the inertial frame of this model).
//
// Example:
//   FilterModelParams p;
//   p.ode = odeCoefficients(VehicleParams{}.geom, lumpedTheta(VehicleParams{}));
//   p.form = ObstacleForm::Polar;
//   FilterModel m(p);
//   FilterState x = FilterState::Zero();  x(kIdxO1) = 2.0;      // obstacle 2 m ahead
//   FilterStateJacobian F = m.F(x, u);   FilterState x1 = m.rk4Step(x, u, 0.01);
#pragma once

#include "libwheelchair/model/VehicleParams.h"

#include <Eigen/Core>

namespace wheelchair::model {

/// How the obstacle is represented in the state: (px, py) per (7) or (d, beta) per (8).
enum class ObstacleForm { Cartesian, Polar };

constexpr int kFilterStateDim = 7;
constexpr int kFilterInputDim = 2;

/// Indices into the state vector.
enum FilterStateIndex : int {
  kIdxV = 0,
  kIdxOmega = 1,
  kIdxX = 2,
  kIdxY = 3,
  kIdxPhi = 4,
  kIdxO1 = 5,  ///< px (Cartesian) or d (polar)
  kIdxO2 = 6,  ///< py (Cartesian) or beta (polar)
};

using FilterState = Eigen::Matrix<double, kFilterStateDim, 1>;
using FilterInput = Eigen::Vector2d;
using FilterStateJacobian = Eigen::Matrix<double, kFilterStateDim, kFilterStateDim>;
using FilterInputJacobian = Eigen::Matrix<double, kFilterStateDim, kFilterInputDim>;
using ScalarMeasJacobian = Eigen::Matrix<double, 1, kFilterStateDim>;
using PozyxMeasJacobian = Eigen::Matrix<double, 2, kFilterStateDim>;

struct FilterModelParams {
  OdeCoefficients ode;                                                ///< a1..a4 of (6)
  ObstacleForm form = ObstacleForm::Cartesian;                        ///< obstacle representation
  Eigen::Vector2d sonar_offset_m = Eigen::Vector2d(0.45, 0.0);        ///< sonar in the body frame
  Eigen::Vector2d pozyx_lever_arm_m = Eigen::Vector2d(-0.20, -0.10);  ///< tag, body frame
};

class FilterModel {
 public:
  FilterModel() = default;
  explicit FilterModel(const FilterModelParams& p) : p_(p) {}

  const FilterModelParams& params() const { return p_; }
  ObstacleForm form() const { return p_.form; }

  // --- process model -------------------------------------------------------------------
  /// xdot = f(x, u).
  FilterState f(const FilterState& x, const FilterInput& u) const;
  /// F = df/dx. It does not depend on u (f is affine in u), the argument is for symmetry.
  FilterStateJacobian F(const FilterState& x, const FilterInput& u = FilterInput::Zero()) const;
  /// f and F together, cos/sin of phi (and of beta in polar form) computed once: what the
  /// CVODE right-hand side needs at every evaluation. Equal to f(x, u) and F(x) (tested).
  void fAndF(const FilterState& x, const FilterInput& u, FilterState& xdot,
             FilterStateJacobian& J) const;
  /// G = df/du (constant: only the velocity rows, [a1 a1; a2 -a2]).
  FilterInputJacobian G(const FilterState& x = FilterState::Zero()) const;
  /// One classical Runge-Kutta 4 step of xdot = f(x, u) with u held constant over dt.
  /// Angles are not wrapped (see wrapAngles).
  FilterState rk4Step(const FilterState& x, const FilterInput& u, double dt_s) const;
  /// Wraps phi (and beta in polar form) to (-pi, pi].
  FilterState wrapAngles(const FilterState& x) const;

  // --- measurements --------------------------------------------------------------------
  static double hV(const FilterState& x) { return x(kIdxV); }
  static ScalarMeasJacobian HV();
  static double hOmega(const FilterState& x) { return x(kIdxOmega); }
  static ScalarMeasJacobian HOmega();
  /// Range from the sonar to the obstacle (m).
  double hSonar(const FilterState& x) const;
  /// d hSonar / dx; a zero row where the range is 0 (the gradient is undefined there).
  ScalarMeasJacobian HSonar(const FilterState& x) const;
  /// Inertial position of the Pozyx tag (m).
  Eigen::Vector2d hPozyx(const FilterState& x) const;
  PozyxMeasJacobian HPozyx(const FilterState& x) const;

  // --- helpers -------------------------------------------------------------------------
  /// Obstacle in base-frame Cartesian coordinates whatever the form.
  Eigen::Vector2d obstacleCartesian(const FilterState& x) const;
  /// The same state with the obstacle expressed in the other form (change of variables of
  /// section II-E; beta in (-pi, pi]).
  static FilterState convertObstacle(const FilterState& x, ObstacleForm from, ObstacleForm to);
  /// Static obstacle given in the inertial frame -> (o1, o2) of the given form for pose
  /// (x, y, phi): p = R(phi)' (p0 - (x, y)).
  static Eigen::Vector2d obstacleFromWorld(const Eigen::Vector3d& pose,
                                           const Eigen::Vector2d& p_world_m, ObstacleForm form);

 private:
  FilterModelParams p_;
};

}  // namespace wheelchair::model
