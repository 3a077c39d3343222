// (d) The per-wheel torque balance beyond the nominal model: per-side parameters couple v and
// omega, the slope accelerates the chair downhill, Coulomb friction opposes the motion; and the
// analytic Jacobians of DriveTrain::acceleration.
#include "libwheelchair/model/DriveDynamics.h"
#include "libwheelchair/model/VehicleParams.h"

#include "NumDiff.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace wheelchair::model {
namespace {

using testing::numericJacobian;
using testing::relativeError;

/// Integrates (v, omega, phi) under constant currents with RK4 for t seconds.
MotionState drive(const DriveTrain& dt, MotionState s, const Eigen::Vector2d& I, double t) {
  const double h = 1e-3;
  auto rate = [&](const Eigen::Vector3d& y) {
    const Eigen::Vector2d a = dt.acceleration({y(0), y(1), y(2)}, I);
    return Eigen::Vector3d(a(0), a(1), y(1));
  };
  Eigen::Vector3d y(s.v_m_s, s.omega_rad_s, s.phi_rad);
  for (int k = 0; k < static_cast<int>(std::lround(t / h)); ++k) {
    const Eigen::Vector3d k1 = rate(y), k2 = rate(y + h / 2 * k1), k3 = rate(y + h / 2 * k2),
                          k4 = rate(y + h * k3);
    y += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
  }
  return {y(0), y(1), y(2)};
}

TEST(DriveDynamics, SymmetricHasNoCoupling) {
  const DriveTrain dt = DriveTrain::symmetric(VehicleParams{});
  const auto J = dt.accelerationJacobianState({0.8, 0.3, 0.2});
  EXPECT_NEAR(J(0, 1), 0.0, 1e-12);
  EXPECT_NEAR(J(1, 0), 0.0, 1e-12);
  // Equal currents from rest: straight line.
  const MotionState s = drive(dt, {}, {6.0, 6.0}, 5.0);
  EXPECT_GT(s.v_m_s, 0.5);
  EXPECT_NEAR(s.omega_rad_s, 0.0, 1e-12);
}

// Unequal viscous friction: equal currents make the chair turn towards the side with more
// friction (that wheel is slower), and v and omega are coupled.
TEST(DriveDynamics, UnequalViscousFrictionTurnsTowardsTheDraggingSide) {
  DriveTrain right = DriveTrain::symmetric(VehicleParams{});
  right.side[0].motor_viscous_Nm_s_rad *= 2.0;  // right side drags
  const MotionState sr = drive(right, {}, {6.0, 6.0}, 5.0);
  EXPECT_GT(sr.v_m_s, 0.5);
  EXPECT_LT(sr.omega_rad_s, -1e-3);  // turns right (clockwise)
  EXPECT_LT(sr.phi_rad, 0.0);
  const auto J = right.accelerationJacobianState({1.0, 0.0, 0.0});
  EXPECT_LT(J(1, 0), 0.0);  // forward speed drives omegadot negative: coupling
  EXPECT_GT(std::abs(J(0, 1)), 1e-4);

  DriveTrain left = DriveTrain::symmetric(VehicleParams{});
  left.side[1].motor_viscous_Nm_s_rad *= 2.0;  // left side drags
  const MotionState sl = drive(left, {}, {6.0, 6.0}, 5.0);
  EXPECT_GT(sl.omega_rad_s, 1e-3);                     // turns left
  EXPECT_NEAR(sl.omega_rad_s, -sr.omega_rad_s, 1e-9);  // mirror image
  EXPECT_NEAR(sl.v_m_s, sr.v_m_s, 1e-9);
}

TEST(DriveDynamics, UnequalCoulombFrictionTurnsTowardsTheDraggingSide) {
  DriveTrain dt = DriveTrain::symmetric(VehicleParams{});
  dt.side[1].coulomb_A = 1.0;  // left side drags
  const MotionState s = drive(dt, {}, {6.0, 6.0}, 5.0);
  EXPECT_GT(s.v_m_s, 0.5);
  EXPECT_GT(s.omega_rad_s, 1e-3);
}

// Unequal torque constants: equal currents give unequal torques; the weaker motor's side lags.
TEST(DriveDynamics, WeakerMotorSideLags) {
  DriveTrain dt = DriveTrain::symmetric(VehicleParams{});
  dt.side[0].torque_constant_Nm_A *= 0.9;  // right motor weaker
  const Eigen::Vector2d acc = dt.acceleration({}, {6.0, 6.0});
  EXPECT_GT(acc(0), 0.0);
  EXPECT_LT(acc(1), 0.0);
}

// Slope: zero current, at rest, facing downhill: vdot = g sin(alpha) M / M_eff with
// M = m_b + 2 m_w and M_eff = M + 2 I_w / r^2 + 2 J_m (r_G / r)^2 (rotating parts are spun up
// too). Uphill the sign flips, across the slope there is no acceleration.
TEST(DriveDynamics, SlopeAcceleratesDownhill) {
  const VehicleParams p;
  DriveTrain dt = DriveTrain::symmetric(p);
  dt.slope_rad = 5.0 * M_PI / 180;
  dt.downhill_heading_rad = 0.7;
  const double r = p.geom.wheel_radius_m, rG = p.geom.gear_ratio;
  const double M = p.geom.body_mass_kg + 2 * p.geom.wheel_mass_kg;
  const double Meff =
      M + 2 * p.wheel_inertia_kg_m2 / (r * r) + 2 * p.motor_inertia_kg_m2 * rG * rG / (r * r);
  const double expected = dt.gravity_m_s2 * std::sin(dt.slope_rad) * M / Meff;
  EXPECT_NEAR(Meff, 163.107266, 1e-5);

  const Eigen::Vector2d down = dt.acceleration({0, 0, 0.7}, Eigen::Vector2d::Zero());
  EXPECT_NEAR(down(0), expected, 1e-12);
  EXPECT_NEAR(down(1), 0.0, 1e-12);
  EXPECT_NEAR(down(0), 0.7653, 1e-4);  // 9.81 sin 5deg * 146 / 163.107

  const Eigen::Vector2d up = dt.acceleration({0, 0, 0.7 + M_PI}, Eigen::Vector2d::Zero());
  EXPECT_NEAR(up(0), -expected, 1e-12);
  const Eigen::Vector2d across = dt.acceleration({0, 0, 0.7 + M_PI / 2}, Eigen::Vector2d::Zero());
  EXPECT_NEAR(across(0), 0.0, 1e-12);

  // Terminal speed downhill: the viscous term balances gravity, v = -vdot_g / a3.
  const OdeCoefficients a = odeCoefficients(p.geom, lumpedTheta(p));
  const MotionState s = drive(dt, {0, 0, 0.7}, Eigen::Vector2d::Zero(), 60.0);
  EXPECT_NEAR(s.v_m_s, -expected / a.a3, 1e-3);
}

// Coulomb friction opposes the rim speed and, as a current, costs 2 a1 c of deceleration.
TEST(DriveDynamics, CoulombOpposesMotion) {
  const VehicleParams p;
  const OdeCoefficients a = odeCoefficients(p.geom, lumpedTheta(p));
  DriveTrain dt = DriveTrain::symmetric(p);
  dt.side[0].coulomb_A = dt.side[1].coulomb_A = 0.8;
  // Only the Coulomb part: subtract the viscous part a3 v.
  const Eigen::Vector2d fwd = dt.acceleration({1.0, 0, 0}, Eigen::Vector2d::Zero());
  EXPECT_NEAR(fwd(0) - a.a3 * 1.0, -2 * a.a1 * 0.8, 1e-9);
  const Eigen::Vector2d back = dt.acceleration({-1.0, 0, 0}, Eigen::Vector2d::Zero());
  EXPECT_NEAR(back(0) - a.a3 * -1.0, 2 * a.a1 * 0.8, 1e-9);
  // At rest the smoothed sign is 0: no phantom acceleration.
  const Eigen::Vector2d rest = dt.acceleration({0, 0, 0}, Eigen::Vector2d::Zero());
  EXPECT_NEAR(rest.norm(), 0.0, 1e-15);
  // Spinning on the spot (u_R > 0, u_L < 0): friction opposes omega.
  const Eigen::Vector2d spin = dt.acceleration({0, 1.0, 0}, Eigen::Vector2d::Zero());
  EXPECT_LT(spin(1) - a.a4 * 1.0, 0.0);
  EXPECT_NEAR(spin(0), 0.0, 1e-12);
  // Hard sign when smoothing is off.
  dt.coulomb_smoothing_m_s = 0;
  const Eigen::Vector2d hard = dt.acceleration({0.001, 0, 0}, Eigen::Vector2d::Zero());
  EXPECT_NEAR(hard(0) - a.a3 * 0.001, -2 * a.a1 * 0.8, 1e-9);
}

TEST(DriveDynamics, CurrentsInvertAcceleration) {
  DriveTrain dt = DriveTrain::symmetric(VehicleParams{});
  dt.side[0].torque_constant_Nm_A = 0.1;
  dt.side[1].coulomb_A = 0.4;
  dt.slope_rad = 0.05;
  const MotionState s{0.6, -0.4, 1.1};
  const Eigen::Vector2d acc = dt.acceleration(s, {7.0, 3.0});
  const Eigen::Vector2d I = dt.currents(s, acc(0), acc(1));
  EXPECT_NEAR(I(0), 7.0, 1e-10);
  EXPECT_NEAR(I(1), 3.0, 1e-10);
}

// Analytic Jacobians of the forward dynamics against central differences, with per-side
// parameters, Coulomb friction and a slope all active.
TEST(DriveDynamics, JacobiansMatchNumerical) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int k = 0; k < 200; ++k) {
    DriveTrain dt = DriveTrain::symmetric(VehicleParams{});
    dt.side[0].torque_constant_Nm_A *= 1 + 0.2 * u(rng);
    dt.side[1].gearbox_efficiency *= 1 + 0.1 * u(rng);
    dt.side[0].motor_viscous_Nm_s_rad *= 1 + 0.5 * u(rng);
    dt.side[1].motor_inertia_kg_m2 *= 1 + 0.5 * u(rng);
    dt.side[0].coulomb_A = 0.5 + 0.5 * u(rng);
    dt.side[1].coulomb_A = 0.5 + 0.5 * u(rng);
    dt.coulomb_smoothing_m_s = 0.05;
    dt.slope_rad = 0.1 * u(rng);
    dt.downhill_heading_rad = 3 * u(rng);
    const Eigen::Vector3d x(1.5 * u(rng), 1.5 * u(rng), 4 * u(rng));
    const Eigen::Vector2d I(20 * u(rng), 20 * u(rng));

    auto accOfState = [&](const Eigen::Vector3d& y) {
      return Eigen::Vector2d(dt.acceleration({y(0), y(1), y(2)}, I));
    };
    auto accOfCurrents = [&](const Eigen::Vector2d& i) {
      return Eigen::Vector2d(dt.acceleration({x(0), x(1), x(2)}, i));
    };
    auto biasOfState = [&](const Eigen::Vector3d& y) {
      return Eigen::Vector2d(dt.biasCurrents({y(0), y(1), y(2)}));
    };
    const MotionState s{x(0), x(1), x(2)};
    EXPECT_LT(relativeError(dt.accelerationJacobianState(s), numericJacobian<2, 3>(accOfState, x)),
              1e-6);
    EXPECT_LT(
        relativeError(dt.accelerationJacobianCurrents(), numericJacobian<2, 2>(accOfCurrents, I)),
        1e-6);
    EXPECT_LT(relativeError(dt.biasCurrentsJacobian(s), numericJacobian<2, 3>(biasOfState, x)),
              1e-6);
  }
}

TEST(DriveDynamics, SideThetaIsEquation3PerSide) {
  DriveTrain dt = DriveTrain::symmetric(VehicleParams{});
  dt.side[1].torque_constant_Nm_A = 0.1;
  EXPECT_DOUBLE_EQ(dt.sideTheta(0)(0), lumpedTheta(VehicleParams{})(0));
  EXPECT_DOUBLE_EQ(dt.sideTheta(1)(0), 1.0 / (0.85 * 0.1));
  EXPECT_DOUBLE_EQ(dt.sideTheta(1)(4), 2.3e-3 / 0.1);
}

}  // namespace
}  // namespace wheelchair::model
