// The regressor of the drive model (identification/Identification.h) and what it determines.
#include "libwheelchair/identification/Identification.h"
#include "libwheelchair/model/VehicleParams.h"

#include <gtest/gtest.h>

#include <random>

using namespace wheelchair;

// The algebra behind the identifiability analysis: Y theta = D1 vdot + s D2 omegadot +
// theta_5 (r_G/r) u_i, and a1..a4 of Appendix VI are 1/(2 D1), 1/(2 D2), ...
TEST(LeastSquares, RegressorCollapsesToThreeCombinations) {
  model::VehicleParams p;
  const auto th = model::lumpedTheta(p);
  const auto& g = p.geom;
  const double rho = g.wheel_radius_m / g.gear_ratio, lw = g.track_width_m;
  const double D1 = identification::d1Weights(g).dot(th);
  const double D2 = identification::d2Weights(g).dot(th);
  const auto a = model::odeCoefficients(g, th);
  EXPECT_NEAR(a.a1, 0.5 / D1, 1e-12);
  EXPECT_NEAR(a.a2, 0.5 / D2, 1e-12);
  EXPECT_NEAR(a.a3, -th(4) / (rho * D1), 1e-12);
  EXPECT_NEAR(a.a4, -th(4) * lw / (2 * rho * D2), 1e-12);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(-1, 1);
  for (int k = 0; k < 20; ++k) {
    const double v = U(rng), vd = U(rng), w = U(rng), wd = U(rng);
    const Eigen::Vector2d i = model::regressor(g, v, vd, w, wd) * th;
    for (int s = 0; s < 2; ++s) {
      const double sg = s == 0 ? 1 : -1;
      EXPECT_NEAR(i(s), D1 * vd + sg * D2 * wd + th(4) / rho * (v + sg * lw * w / 2), 1e-9);
    }
  }
}
