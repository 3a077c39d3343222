// Kinematics (1), obstacle forms (7) and (8): Jacobians against central differences (e),
// the arc integration against a fine RK4 of (1) and wrapAngle edge cases (g).
#include "libwheelchair/model/Kinematics.h"

#include "NumDiff.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace wheelchair::model {
namespace {

using testing::numericJacobian;
using testing::relativeError;

constexpr double kTol = 1e-6;

TEST(Kinematics, PoseRateJacobians) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int k = 0; k < 200; ++k) {
    const Eigen::Vector3d pose(5 * u(rng), 5 * u(rng), 4 * u(rng));
    const Eigen::Vector2d vel(2 * u(rng), 2 * u(rng));
    auto ofPose = [&](const Eigen::Vector3d& q) { return poseRate(q(2), vel(0), vel(1)); };
    auto ofVel = [&](const Eigen::Vector2d& w) { return poseRate(pose(2), w(0), w(1)); };
    EXPECT_LT(
        relativeError(poseRateJacobianPose(pose(2), vel(0)), numericJacobian<3, 3>(ofPose, pose)),
        kTol);
    EXPECT_LT(relativeError(poseRateJacobianVel(pose(2)), numericJacobian<3, 2>(ofVel, vel)), kTol);
  }
}

TEST(Kinematics, ObstacleCartesianJacobians) {
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int k = 0; k < 200; ++k) {
    const Eigen::Vector2d p(5 * u(rng), 5 * u(rng));
    const Eigen::Vector2d vel(2 * u(rng), 2 * u(rng));
    auto ofP = [&](const Eigen::Vector2d& q) { return obstacleCartesianRate(q, vel(0), vel(1)); };
    auto ofVel = [&](const Eigen::Vector2d& w) { return obstacleCartesianRate(p, w(0), w(1)); };
    EXPECT_LT(relativeError(obstacleCartesianJacobianP(vel(1)), numericJacobian<2, 2>(ofP, p)),
              kTol);
    EXPECT_LT(relativeError(obstacleCartesianJacobianVel(p), numericJacobian<2, 2>(ofVel, vel)),
              kTol);
  }
}

TEST(Kinematics, ObstaclePolarJacobians) {
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int k = 0; k < 200; ++k) {
    const Eigen::Vector2d q(0.3 + 5 * std::abs(u(rng)), 4 * u(rng));  // d > 0
    const Eigen::Vector2d vel(2 * u(rng), 2 * u(rng));
    auto ofQ = [&](const Eigen::Vector2d& z) { return obstaclePolarRate(z, vel(0), vel(1)); };
    auto ofVel = [&](const Eigen::Vector2d& w) { return obstaclePolarRate(q, w(0), w(1)); };
    EXPECT_LT(relativeError(obstaclePolarJacobianQ(q, vel(0)), numericJacobian<2, 2>(ofQ, q)),
              kTol);
    EXPECT_LT(relativeError(obstaclePolarJacobianVel(q), numericJacobian<2, 2>(ofVel, vel)), kTol);
  }
}

// (8) is (7) under p = d (cos beta, sin beta): the chain rule maps one rate onto the other.
TEST(Kinematics, PolarRateIsCartesianRateChangedVariables) {
  std::mt19937 rng(14);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int k = 0; k < 200; ++k) {
    const Eigen::Vector2d q(0.3 + 5 * std::abs(u(rng)), 3 * u(rng));
    const double v = 2 * u(rng), om = 2 * u(rng);
    const Eigen::Vector2d p = polarToCartesian(q);
    const Eigen::Vector2d qd = obstaclePolarRate(q, v, om);
    Eigen::Matrix2d dp_dq;
    dp_dq << std::cos(q(1)), -q(0) * std::sin(q(1)), std::sin(q(1)), q(0) * std::cos(q(1));
    EXPECT_LT((dp_dq * qd - obstacleCartesianRate(p, v, om)).norm(), 1e-12);
  }
}

TEST(Kinematics, PolarCartesianRoundTrip) {
  for (double b : {0.0, 0.5, 1.6, 3.0, -0.5, -1.6, -3.0, M_PI}) {
    const Eigen::Vector2d q(2.5, b);
    const Eigen::Vector2d back = cartesianToPolar(polarToCartesian(q));
    EXPECT_NEAR(back(0), 2.5, 1e-12);
    EXPECT_NEAR(wrapAngle(back(1) - b), 0.0, 1e-12);
    EXPECT_GT(back(1), -M_PI);
    EXPECT_LE(back(1), M_PI);
  }
  // Behind the chair: beta near +-pi, the quadrant is kept (atan2, not atan).
  EXPECT_NEAR(cartesianToPolar({-1.0, 1e-3})(1), M_PI - 1e-3, 1e-9);
  EXPECT_NEAR(cartesianToPolar({-1.0, -1e-3})(1), -M_PI + 1e-3, 1e-9);
}

/// RK4 of (1) with constant (v, omega), n steps over dt.
Eigen::Vector3d rk4Pose(Eigen::Vector3d pose, double v, double om, double dt, int n) {
  const double h = dt / n;
  for (int k = 0; k < n; ++k) {
    const Eigen::Vector3d k1 = poseRate(pose(2), v, om);
    const Eigen::Vector3d k2 = poseRate(pose(2) + h / 2 * k1(2), v, om);
    const Eigen::Vector3d k3 = poseRate(pose(2) + h / 2 * k2(2), v, om);
    const Eigen::Vector3d k4 = poseRate(pose(2) + h * k3(2), v, om);
    pose += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
  }
  return pose;
}

// (g) The arc integration is the exact solution of (1): it matches a fine RK4 for turning,
// straight, nearly straight and on-the-spot motion, at any heading.
TEST(Kinematics, IntegratePoseArcMatchesRk4) {
  const double cases[][3] = {
      // v, omega, dt
      {0.8, 0.4, 1.0},   {0.8, -0.4, 1.0}, {1.2, 0.0, 2.0},   {1.2, 1e-7, 2.0},
      {1.2, -3e-9, 2.0}, {0.0, 1.5, 1.0},  {-0.5, 0.7, 1.5},  {0.5, 6.0, 1.0},
      {1.0, 1e-5, 1.0},  {1.0, 2e-4, 1.0}, {-1.0, -2.5, 0.3}, {2.0, 3.0, 4.0},
  };
  for (double phi0 : {0.0, 0.3, 1.5, -2.0, 3.1}) {
    for (const auto& c : cases) {
      const Eigen::Vector3d start(1.0, -2.0, phi0);
      const Eigen::Vector3d arc = integratePoseArc(start, c[0], c[1], c[2]);
      const Eigen::Vector3d ref = rk4Pose(start, c[0], c[1], c[2], 4000);
      EXPECT_NEAR(arc(0), ref(0), 1e-11) << c[0] << " " << c[1] << " " << c[2];
      EXPECT_NEAR(arc(1), ref(1), 1e-11) << c[0] << " " << c[1] << " " << c[2];
      EXPECT_NEAR(wrapAngle(arc(2) - ref(2)), 0.0, 1e-12);
      EXPECT_GT(arc(2), -M_PI);
      EXPECT_LE(arc(2), M_PI);
    }
  }
}

// Nearly straight motion is where R (sin(phi + dphi) - sin(phi)) with R = v/omega cancels;
// compare against the exact chord form evaluated independently.
TEST(Kinematics, IntegratePoseArcNearlyStraightIsAccurate) {
  for (double om : {1e-8, 3e-8, 1e-7, 1e-6}) {
    const double v = 1.0, dt = 1.0, phi = 0.9;
    const Eigen::Vector3d arc = integratePoseArc({0, 0, phi}, v, om, dt);
    // Series of the exact solution: x = v dt (cos phi - dphi/2 sin phi - dphi^2/6 cos phi)
    const double d = om * dt;
    const double xs = v * dt * (std::cos(phi) - d / 2 * std::sin(phi) - d * d / 6 * std::cos(phi));
    const double ys = v * dt * (std::sin(phi) + d / 2 * std::cos(phi) - d * d / 6 * std::sin(phi));
    EXPECT_NEAR(arc(0), xs, 1e-14);
    EXPECT_NEAR(arc(1), ys, 1e-14);
  }
}

TEST(Kinematics, IntegratePoseArcComposes) {
  // Two half steps = one full step (constant v, omega).
  const Eigen::Vector3d a = integratePoseArc({0.3, 0.1, 2.9}, 0.7, 0.9, 1.2);
  const Eigen::Vector3d b =
      integratePoseArc(integratePoseArc({0.3, 0.1, 2.9}, 0.7, 0.9, 0.6), 0.7, 0.9, 0.6);
  EXPECT_NEAR((a.head<2>() - b.head<2>()).norm(), 0.0, 1e-14);
  EXPECT_NEAR(wrapAngle(a(2) - b(2)), 0.0, 1e-14);
}

TEST(Kinematics, WrapAngleEdgeCases) {
  EXPECT_EQ(wrapAngle(0.0), 0.0);
  EXPECT_EQ(wrapAngle(M_PI), M_PI);                         // upper end is included
  EXPECT_EQ(wrapAngle(-M_PI), M_PI);                        // lower end is not
  EXPECT_NEAR(std::abs(wrapAngle(3 * M_PI)), M_PI, 1e-12);  // +-pi up to rounding of 3 pi
  EXPECT_NEAR(std::abs(wrapAngle(-3 * M_PI)), M_PI, 1e-12);
  EXPECT_NEAR(wrapAngle(2 * M_PI), 0.0, 1e-15);
  EXPECT_NEAR(wrapAngle(-2 * M_PI), 0.0, 1e-15);
  EXPECT_EQ(wrapAngle(1e-20), 1e-20);  // tiny angles are not rounded away
  EXPECT_EQ(wrapAngle(-1e-20), -1e-20);
  EXPECT_EQ(wrapAngle(1.0), 1.0);
  EXPECT_NEAR(wrapAngle(M_PI + 1e-9), -M_PI + 1e-9, 1e-15);
  EXPECT_NEAR(wrapAngle(-M_PI - 1e-9), M_PI - 1e-9, 1e-15);
  EXPECT_NEAR(wrapAngle(7.5), 7.5 - 2 * M_PI, 1e-15);
  EXPECT_NEAR(wrapAngle(-7.5), -7.5 + 2 * M_PI, 1e-15);
  for (double a : {1000.5, -1000.5, 1e6 + 0.25, 123.456}) {
    const double w = wrapAngle(a);
    EXPECT_GT(w, -M_PI);
    EXPECT_LE(w, M_PI);
    EXPECT_NEAR(std::sin(w), std::sin(a), 1e-9);
    EXPECT_NEAR(std::cos(w), std::cos(a), 1e-9);
  }
  EXPECT_TRUE(std::isnan(wrapAngle(std::nan(""))));
}

}  // namespace
}  // namespace wheelchair::model
