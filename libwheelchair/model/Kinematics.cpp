#include "libwheelchair/model/Kinematics.h"

#include <cmath>

namespace wheelchair::model {

Eigen::Vector3d poseRate(double phi, double v, double omega) {
  return poseRate(HeadingTrig(phi), v, omega);
}

Eigen::Matrix3d poseRateJacobianPose(double phi, double v) {
  return poseRateJacobianPose(HeadingTrig(phi), v);
}

Eigen::Matrix<double, 3, 2> poseRateJacobianVel(double phi) {
  return poseRateJacobianVel(HeadingTrig(phi));
}

Eigen::Vector2d obstacleCartesianRate(const Eigen::Vector2d& p, double v, double omega) {
  return {omega * p.y() - v, -omega * p.x()};
}

Eigen::Matrix2d obstacleCartesianJacobianP(double omega) {
  Eigen::Matrix2d J;
  J << 0, omega, -omega, 0;
  return J;
}

Eigen::Matrix2d obstacleCartesianJacobianVel(const Eigen::Vector2d& p) {
  Eigen::Matrix2d J;
  J << -1, p.y(), 0, -p.x();
  return J;
}

Eigen::Vector2d obstaclePolarRate(const Eigen::Vector2d& q, double v, double omega) {
  return {-v * std::cos(q(1)), -omega + v * std::sin(q(1)) / q(0)};
}

Eigen::Matrix2d obstaclePolarJacobianQ(const Eigen::Vector2d& q, double v) {
  const double d = q(0), b = q(1);
  Eigen::Matrix2d J;
  J << 0, v * std::sin(b), -v * std::sin(b) / (d * d), v * std::cos(b) / d;
  return J;
}

Eigen::Matrix2d obstaclePolarJacobianVel(const Eigen::Vector2d& q) {
  Eigen::Matrix2d J;
  J << -std::cos(q(1)), 0, std::sin(q(1)) / q(0), -1;
  return J;
}

Eigen::Vector2d cartesianToPolar(const Eigen::Vector2d& p) {
  return {p.norm(), std::atan2(p.y(), p.x())};
}

Eigen::Vector2d polarToCartesian(const Eigen::Vector2d& q) {
  return {q(0) * std::cos(q(1)), q(0) * std::sin(q(1))};
}

namespace {
/// sin(h)/h, with its Taylor series near 0 (no 0/0, full precision).
double sinc(double h) {
  if (std::abs(h) < 1e-4) return 1.0 - h * h / 6.0;
  return std::sin(h) / h;
}
}  // namespace

Eigen::Vector3d integratePoseArc(const Eigen::Vector3d& pose, double v, double omega, double dt) {
  // Exact solution of (1) for constant (v, omega): the chord of the arc has length
  // v dt sinc(dphi/2) and points along the mean heading phi + dphi/2. This form has no
  // division by omega, so it is accurate for straight, nearly straight and turning motion
  // alike (R (sin(phi+dphi) - sin(phi)) loses digits to cancellation when dphi is small).
  const double phi = pose(2);
  const double dphi = omega * dt;
  const double chord = v * dt * sinc(dphi / 2);
  const double mid = phi + dphi / 2;
  Eigen::Vector3d out = pose;
  out(0) += chord * std::cos(mid);
  out(1) += chord * std::sin(mid);
  out(2) = wrapAngle(phi + dphi);
  return out;
}

double wrapAngle(double a) {
  // Already in range: return it unchanged (the shift by pi below would round tiny angles).
  if (a > -M_PI && a <= M_PI) return a;
  a = std::fmod(a + M_PI, 2 * M_PI);
  if (a <= 0) a += 2 * M_PI;
  return a - M_PI;
}

}  // namespace wheelchair::model
