#include "libwheelchair/model/FilterModel.h"

#include "libwheelchair/model/Kinematics.h"

#include <cmath>

namespace wheelchair::model {

namespace {

Eigen::Vector2d obstacleOf(const FilterState& x) {
  return x.segment<2>(kIdxO1);
}

}  // namespace

namespace {

// f and F take cos/sin of the heading from the caller, so that fAndF evaluates it once.

void rate(const FilterModelParams& p, const FilterState& x, const FilterInput& u,
          const HeadingTrig& h, FilterState& xd) {
  const double v = x(kIdxV), om = x(kIdxOmega);
  xd.segment<2>(kIdxV) = odeAcceleration(p.ode, v, om, u(0), u(1));
  xd.segment<3>(kIdxX) = poseRate(h, v, om);
  xd.segment<2>(kIdxO1) = (p.form == ObstacleForm::Cartesian)
                              ? obstacleCartesianRate(obstacleOf(x), v, om)
                              : obstaclePolarRate(obstacleOf(x), v, om);
}

void jacobian(const FilterModelParams& p, const FilterState& x, const HeadingTrig& h,
              FilterStateJacobian& J) {
  const double v = x(kIdxV);
  J.setZero();
  // (6): velocities are decoupled first-order lags.
  J(kIdxV, kIdxV) = p.ode.a3;
  J(kIdxOmega, kIdxOmega) = p.ode.a4;
  // (1): pose rates.
  J.block<3, 2>(kIdxX, kIdxV) = poseRateJacobianVel(h);
  J.block<3, 3>(kIdxX, kIdxX) = poseRateJacobianPose(h, v);
  // (7) or (8): the obstacle depends on itself and on (v, omega), never on the pose.
  const Eigen::Vector2d o = obstacleOf(x);
  if (p.form == ObstacleForm::Cartesian) {
    J.block<2, 2>(kIdxO1, kIdxV) = obstacleCartesianJacobianVel(o);
    J.block<2, 2>(kIdxO1, kIdxO1) = obstacleCartesianJacobianP(x(kIdxOmega));
  } else {
    J.block<2, 2>(kIdxO1, kIdxV) = obstaclePolarJacobianVel(o);
    J.block<2, 2>(kIdxO1, kIdxO1) = obstaclePolarJacobianQ(o, v);
  }
}

}  // namespace

FilterState FilterModel::f(const FilterState& x, const FilterInput& u) const {
  FilterState xd;
  rate(p_, x, u, HeadingTrig(x(kIdxPhi)), xd);
  return xd;
}

FilterStateJacobian FilterModel::F(const FilterState& x, const FilterInput& /*u*/) const {
  FilterStateJacobian J;
  jacobian(p_, x, HeadingTrig(x(kIdxPhi)), J);
  return J;
}

void FilterModel::fAndF(const FilterState& x, const FilterInput& u, FilterState& xd,
                        FilterStateJacobian& J) const {
  const HeadingTrig h(x(kIdxPhi));
  rate(p_, x, u, h, xd);
  jacobian(p_, x, h, J);
}

FilterInputJacobian FilterModel::G(const FilterState& /*x*/) const {
  FilterInputJacobian J = FilterInputJacobian::Zero();
  J(kIdxV, 0) = p_.ode.a1;
  J(kIdxV, 1) = p_.ode.a1;
  J(kIdxOmega, 0) = p_.ode.a2;
  J(kIdxOmega, 1) = -p_.ode.a2;
  return J;
}

FilterState FilterModel::rk4Step(const FilterState& x, const FilterInput& u, double dt) const {
  const FilterState k1 = f(x, u);
  const FilterState k2 = f(x + 0.5 * dt * k1, u);
  const FilterState k3 = f(x + 0.5 * dt * k2, u);
  const FilterState k4 = f(x + dt * k3, u);
  return x + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
}

FilterState FilterModel::wrapAngles(const FilterState& x) const {
  FilterState y = x;
  y(kIdxPhi) = wrapAngle(y(kIdxPhi));
  if (p_.form == ObstacleForm::Polar) y(kIdxO2) = wrapAngle(y(kIdxO2));
  return y;
}

ScalarMeasJacobian FilterModel::HV() {
  ScalarMeasJacobian H = ScalarMeasJacobian::Zero();
  H(kIdxV) = 1.0;
  return H;
}

ScalarMeasJacobian FilterModel::HOmega() {
  ScalarMeasJacobian H = ScalarMeasJacobian::Zero();
  H(kIdxOmega) = 1.0;
  return H;
}

Eigen::Vector2d FilterModel::obstacleCartesian(const FilterState& x) const {
  return (p_.form == ObstacleForm::Cartesian) ? obstacleOf(x) : polarToCartesian(obstacleOf(x));
}

double FilterModel::hSonar(const FilterState& x) const {
  return (obstacleCartesian(x) - p_.sonar_offset_m).norm();
}

ScalarMeasJacobian FilterModel::HSonar(const FilterState& x) const {
  ScalarMeasJacobian H = ScalarMeasJacobian::Zero();
  const Eigen::Vector2d q = obstacleCartesian(x) - p_.sonar_offset_m;
  const double range = q.norm();
  if (!(range > 0)) return H;
  // d range / d p = q' / range (unit vector from the sonar to the obstacle).
  const Eigen::RowVector2d dr_dp = q.transpose() / range;
  if (p_.form == ObstacleForm::Cartesian) {
    H.segment<2>(kIdxO1) = dr_dp;
  } else {
    // p = d (cos beta, sin beta): dp/dd = (cos beta, sin beta), dp/dbeta = d (-sin beta, cos beta).
    const double d = x(kIdxO1), c = std::cos(x(kIdxO2)), s = std::sin(x(kIdxO2));
    H(kIdxO1) = dr_dp * Eigen::Vector2d(c, s);
    H(kIdxO2) = dr_dp * Eigen::Vector2d(-d * s, d * c);
  }
  return H;
}

Eigen::Vector2d FilterModel::hPozyx(const FilterState& x) const {
  const double c = std::cos(x(kIdxPhi)), s = std::sin(x(kIdxPhi));
  const Eigen::Vector2d& l = p_.pozyx_lever_arm_m;
  return {x(kIdxX) + c * l.x() - s * l.y(), x(kIdxY) + s * l.x() + c * l.y()};
}

PozyxMeasJacobian FilterModel::HPozyx(const FilterState& x) const {
  const double c = std::cos(x(kIdxPhi)), s = std::sin(x(kIdxPhi));
  const Eigen::Vector2d& l = p_.pozyx_lever_arm_m;
  PozyxMeasJacobian H = PozyxMeasJacobian::Zero();
  H(0, kIdxX) = 1.0;
  H(1, kIdxY) = 1.0;
  H(0, kIdxPhi) = -s * l.x() - c * l.y();
  H(1, kIdxPhi) = c * l.x() - s * l.y();
  return H;
}

FilterState FilterModel::convertObstacle(const FilterState& x, ObstacleForm from, ObstacleForm to) {
  if (from == to) return x;
  FilterState y = x;
  y.segment<2>(kIdxO1) = (from == ObstacleForm::Cartesian) ? cartesianToPolar(obstacleOf(x))
                                                           : polarToCartesian(obstacleOf(x));
  return y;
}

Eigen::Vector2d FilterModel::obstacleFromWorld(const Eigen::Vector3d& pose,
                                               const Eigen::Vector2d& p_world, ObstacleForm form) {
  const double c = std::cos(pose(2)), s = std::sin(pose(2));
  const Eigen::Vector2d dw = p_world - pose.head<2>();
  const Eigen::Vector2d p(c * dw.x() + s * dw.y(), -s * dw.x() + c * dw.y());
  return (form == ObstacleForm::Cartesian) ? p : cartesianToPolar(p);
}

}  // namespace wheelchair::model
