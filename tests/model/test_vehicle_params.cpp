// The paper's two forms of the dynamics and their coefficients:
//   (a) the corrected regressor (2) times theta (3) gives the currents the ODE form (6) implies;
//   (b) a1..a4 of Appendix VI equal those of the per-wheel torque balance (DriveTrain), an
//       independent route (mass matrix inverse, not the Appendix formulas);
//   (c) the nominal values of vehicle.md, checked by hand in docs/model.md.
#include "libwheelchair/model/DriveDynamics.h"
#include "libwheelchair/model/VehicleParams.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <random>

namespace wheelchair::model {
namespace {

/// A physically plausible random vehicle around the nominal one (each value x0.5 .. x2).
VehicleParams randomVehicle(std::mt19937& rng) {
  std::uniform_real_distribution<double> f(0.5, 2.0);
  VehicleParams p;
  p.geom.wheel_radius_m *= f(rng);
  p.geom.track_width_m *= f(rng);
  p.geom.gear_ratio *= f(rng);
  p.geom.wheel_mass_kg *= f(rng);
  p.geom.body_mass_kg *= f(rng);
  p.motor_inertia_kg_m2 *= f(rng);
  p.wheel_inertia_kg_m2 *= f(rng);
  p.yaw_inertia_kg_m2 *= f(rng);
  p.motor_viscous_Nm_s_rad *= f(rng);
  p.torque_constant_Nm_A *= f(rng);
  p.gearbox_efficiency = std::min(1.0, p.gearbox_efficiency * f(rng));
  return p;
}

TEST(VehicleParams, LumpedThetaIsEquation3) {
  VehicleParams p;
  const LumpedTheta th = lumpedTheta(p);
  const double ek = 0.85 * 0.09;
  EXPECT_DOUBLE_EQ(th(0), 1 / ek);
  EXPECT_DOUBLE_EQ(th(1), 3.0e-4 / ek);
  EXPECT_DOUBLE_EQ(th(2), 0.15 / ek);
  EXPECT_DOUBLE_EQ(th(3), 8.0 / ek);
  EXPECT_DOUBLE_EQ(th(4), 2.3e-3 / 0.09);  // B_m / k_m: no efficiency on the viscous term
}

// (a) Y(v, vdot, omega, omegadot) theta == currentsFromOde(a, ...), random states.
TEST(VehicleParams, RegressorTimesThetaEqualsOdeCurrents) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int vehicle = 0; vehicle < 20; ++vehicle) {
    const VehicleParams p = vehicle == 0 ? VehicleParams{} : randomVehicle(rng);
    const LumpedTheta th = lumpedTheta(p);
    const OdeCoefficients a = odeCoefficients(p.geom, th);
    for (int k = 0; k < 50; ++k) {
      const double v = 2 * u(rng), vd = 3 * u(rng), om = 2 * u(rng), omd = 5 * u(rng);
      const Eigen::Vector2d iY = regressor(p.geom, v, vd, om, omd) * th;
      const Eigen::Vector2d iOde = currentsFromOde(a, v, vd, om, omd);
      EXPECT_LT((iY - iOde).norm(), 1e-9 * std::max(1.0, iOde.norm()))
          << "vehicle " << vehicle << " Y theta = " << iY.transpose()
          << " ODE = " << iOde.transpose();
      // And the round trip through the ODE form.
      const Eigen::Vector2d acc = odeAcceleration(a, v, om, iY(0), iY(1));
      EXPECT_NEAR(acc(0), vd, 1e-9);
      EXPECT_NEAR(acc(1), omd, 1e-9);
    }
  }
}

// The regressor form (2) is the per-wheel torque balance divided by eta k: with a symmetric
// drive train on a flat floor the two give the same currents.
TEST(VehicleParams, RegressorEqualsTorqueBalanceCurrents) {
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int vehicle = 0; vehicle < 20; ++vehicle) {
    const VehicleParams p = vehicle == 0 ? VehicleParams{} : randomVehicle(rng);
    const DriveTrain dt = DriveTrain::symmetric(p);
    for (int k = 0; k < 20; ++k) {
      const double v = 2 * u(rng), vd = 3 * u(rng), om = 2 * u(rng), omd = 5 * u(rng);
      const Eigen::Vector2d iY = regressor(p.geom, v, vd, om, omd) * lumpedTheta(p);
      const Eigen::Vector2d iDt = dt.currents({v, om, 3 * u(rng)}, vd, omd);
      EXPECT_LT((iY - iDt).norm(), 1e-9 * std::max(1.0, iY.norm()));
    }
  }
}

// The printed y_i2 = (r/r_G) udot is inconsistent with a1: the corrected (r_G/r) is what
// makes Y theta agree with (6). Guard against a regression to the printed factor.
TEST(VehicleParams, RegressorSecondColumnIsRgOverR) {
  const Geometry g;
  const auto Y = regressor(g, 0.0, 1.0, 0.0, 0.0);
  EXPECT_DOUBLE_EQ(Y(0, 1), g.gear_ratio / g.wheel_radius_m);
  EXPECT_DOUBLE_EQ(Y(1, 1), g.gear_ratio / g.wheel_radius_m);
}

// (b) a1..a4 from the Appendix formulas == the ones from the torque balance (DriveTrain).
TEST(VehicleParams, AppendixCoefficientsEqualTorqueBalance) {
  std::mt19937 rng(3);
  for (int vehicle = 0; vehicle < 50; ++vehicle) {
    const VehicleParams p = vehicle == 0 ? VehicleParams{} : randomVehicle(rng);
    const OdeCoefficients a = odeCoefficients(p.geom, lumpedTheta(p));
    const DriveTrain dt = DriveTrain::symmetric(p);

    // Route 1: invert the mass matrix: [vdot; omegadot] = A^-1 (I - b).
    const Eigen::Matrix2d Ainv = dt.massMatrix().inverse();
    EXPECT_NEAR(Ainv(0, 0), a.a1, 1e-12 * a.a1);  // d vdot / d i_R
    EXPECT_NEAR(Ainv(0, 1), a.a1, 1e-12 * a.a1);  // d vdot / d i_L
    EXPECT_NEAR(Ainv(1, 0), a.a2, 1e-12 * a.a2);
    EXPECT_NEAR(Ainv(1, 1), -a.a2, 1e-12 * a.a2);
    // a3 = d vdot / dv at zero current, a4 = d omegadot / d omega; b is linear in (v, omega).
    const Eigen::Vector2d accV = dt.acceleration({1.0, 0.0, 0.0}, Eigen::Vector2d::Zero());
    const Eigen::Vector2d accW = dt.acceleration({0.0, 1.0, 0.0}, Eigen::Vector2d::Zero());
    EXPECT_NEAR(accV(0), a.a3, 1e-12 * std::abs(a.a3));
    EXPECT_NEAR(accV(1), 0.0, 1e-12);  // v and omega uncoupled
    EXPECT_NEAR(accW(1), a.a4, 1e-12 * std::abs(a.a4));
    EXPECT_NEAR(accW(0), 0.0, 1e-12);

    // Route 2: closed forms with effective mass and inertia (docs/model.md).
    const double r = p.geom.wheel_radius_m, rG = p.geom.gear_ratio, lw = p.geom.track_width_m;
    const double ek = p.gearbox_efficiency * p.torque_constant_Nm_A;
    const double refl = p.wheel_inertia_kg_m2 / (r * r) + p.motor_inertia_kg_m2 * rG * rG / (r * r);
    const double Meff = p.geom.body_mass_kg + 2 * p.geom.wheel_mass_kg + 2 * refl;
    const double Ieff = p.yaw_inertia_kg_m2 + (p.geom.wheel_mass_kg + refl) * lw * lw / 2;
    const double Bw = p.gearbox_efficiency * p.motor_viscous_Nm_s_rad * rG * rG / (r * r);
    EXPECT_NEAR(a.a1, ek * rG / (r * Meff), 1e-12 * a.a1);
    EXPECT_NEAR(a.a2, ek * rG / r * (lw / 2) / Ieff, 1e-12 * a.a2);
    EXPECT_NEAR(a.a3, -2 * Bw / Meff, 1e-12 * std::abs(a.a3));
    EXPECT_NEAR(a.a4, -Bw * lw * lw / 2 / Ieff, 1e-12 * std::abs(a.a4));
    EXPECT_GT(a.a1, 0);
    EXPECT_GT(a.a2, 0);
    EXPECT_LT(a.a3, 0);
    EXPECT_LT(a.a4, 0);
  }
}

// (c) The nominal vehicle: exact values (to 4 significant digits), verified by hand in
// docs/model.md: M_eff = 163.107 kg, I_eff = 10.5037 kg m^2.
TEST(VehicleParams, NominalCoefficients) {
  const VehicleParams p;
  const OdeCoefficients a = odeCoefficients(p.geom, lumpedTheta(p));
  EXPECT_NEAR(a.a1, 0.04966, 0.00001);
  EXPECT_NEAR(a.a2, 0.2121, 0.0001);
  EXPECT_NEAR(a.a3, -0.2688, 0.0001);
  EXPECT_NEAR(a.a4, -0.3156, 0.0001);
  // Full precision (exact rational arithmetic on the vehicle.md values).
  EXPECT_NEAR(a.a1, 0.0496605710891425, 1e-14);
  EXPECT_NEAR(a.a2, 0.2120673808629652, 1e-14);
  EXPECT_NEAR(a.a3, -0.2687513258941831, 1e-14);
  EXPECT_NEAR(a.a4, -0.3156061609313541, 1e-14);
}

TEST(VehicleParams, CurrentsFromOdeInvertsOde) {
  const VehicleParams p;
  const OdeCoefficients a = odeCoefficients(p.geom, lumpedTheta(p));
  const Eigen::Vector2d acc = odeAcceleration(a, 0.7, -0.3, 12.0, 5.0);
  const Eigen::Vector2d i = currentsFromOde(a, 0.7, acc(0), -0.3, acc(1));
  EXPECT_NEAR(i(0), 12.0, 1e-12);
  EXPECT_NEAR(i(1), 5.0, 1e-12);
}

}  // namespace
}  // namespace wheelchair::model
