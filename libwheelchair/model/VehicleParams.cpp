#include "libwheelchair/model/VehicleParams.h"

namespace wheelchair::model {

LumpedTheta lumpedTheta(const VehicleParams& p) {
  const double etak = p.gearbox_efficiency * p.torque_constant_Nm_A;
  LumpedTheta th;
  th << 1.0 / etak, p.motor_inertia_kg_m2 / etak, p.wheel_inertia_kg_m2 / etak,
      p.yaw_inertia_kg_m2 / etak, p.motor_viscous_Nm_s_rad / p.torque_constant_Nm_A;
  return th;
}

OdeCoefficients odeCoefficients(const Geometry& g, const LumpedTheta& th) {
  const double r = g.wheel_radius_m, rG = g.gear_ratio, lw = g.track_width_m;
  const double mw = g.wheel_mass_kg, mb = g.body_mass_kg;
  const double rho = r / rG;  // wheel radius per gear ratio
  OdeCoefficients a;
  a.a1 = 0.5 / (rho * th(0) * (mw + mb / 2) + th(1) / rho + th(2) / (r * rG));
  a.a2 = 0.5 / (rho * (th(0) * mw * lw / 2 + th(3) / lw) + th(1) / rho * lw / 2 +
                th(2) / (r * rG) * lw / 2);
  a.a3 = -1.0 /
         (rho * rho * th(0) / th(4) * (mw + mb / 2) + th(1) / th(4) + th(2) / (rG * rG * th(4)));
  a.a4 = -1.0 / (rho * rho / th(4) * (mw * th(0) + 2 * th(3) / (lw * lw)) +
                 (th(1) + th(2) / (rG * rG)) / th(4));
  return a;
}

Eigen::Matrix<double, 2, 5> regressor(const Geometry& g, double v, double vdot, double omega,
                                      double omegadot) {
  const double r = g.wheel_radius_m, rG = g.gear_ratio, lw = g.track_width_m;
  const double mw = g.wheel_mass_kg, mb = g.body_mass_kg;
  Eigen::Matrix<double, 2, 5> Y;
  for (int i = 0; i < 2; ++i) {
    const double s = (i == 0) ? 1.0 : -1.0;  // (-1)^{i+1} of the paper
    const double udot = vdot + s * lw * omegadot / 2;
    const double u = v + s * lw * omega / 2;
    Y(i, 0) = r / rG * (mw * udot + mb * vdot / 2);
    Y(i, 1) = rG / r * udot;  // printed as r/r_G in the paper; r_G/r is consistent with (6)
    Y(i, 2) = udot / (r * rG);
    Y(i, 3) = s * r / rG * omegadot / lw;
    Y(i, 4) = rG / r * u;
  }
  return Y;
}

Eigen::Vector2d currentsFromOde(const OdeCoefficients& a, double v, double vdot, double omega,
                                double omegadot) {
  const double sum = (vdot - a.a3 * v) / a.a1;
  const double diff = (omegadot - a.a4 * omega) / a.a2;
  return {(sum + diff) / 2, (sum - diff) / 2};
}

Eigen::Vector2d odeAcceleration(const OdeCoefficients& a, double v, double omega, double iR,
                                double iL) {
  return {a.a3 * v + a.a1 * (iR + iL), a.a4 * omega + a.a2 * (iR - iL)};
}

}  // namespace wheelchair::model
