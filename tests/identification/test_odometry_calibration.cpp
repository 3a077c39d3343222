// Odometry calibration anchors (identification/OdometryCalibration.h) on synthetic runs of a
// differential drive whose true geometry differs from the nominal one: the robot follows a
// square by its (nominal) odometry, the truth integrates the true geometry. UMBmark, the
// two-step least squares and the trajectory fit must recover the true geometry.
#include "libwheelchair/identification/OdometryCalibration.h"

#include <gtest/gtest.h>

#include <cmath>

namespace wheelchair::identification {
namespace {

const OdometryGeometry kNominal{1e-4, 1e-4, 0.2};
const OdometryGeometry kTrue{1.004e-4, 0.998e-4, 0.206};   // E_d = 1.00601, E_b = 1.03
const OdometryGeometry kSmall{1.001e-4, 0.999e-4, 0.201};  // E_d = 1.002, E_b = 1.005

/// A square of side L driven by odometry (nominal geometry), cw (dir -1) or ccw (+1), with
/// 20 Hz ticks; truth from the true geometry. Straight legs add a small wobble so that the
/// least-squares problem is well posed.
OdometryRun square(double L, int dir, const OdometryGeometry& truth, double t0 = 0,
                   double lever_x = 0, double lever_y = 0) {
  OdometryRun r;
  double nR = 0, nL = 0, t = t0;
  double x = 0, y = 0, phi = 0;     // truth
  double xo = 0, yo = 0, phio = 0;  // odometry (nominal)
  auto push = [&] {
    r.t_s.push_back(t), r.ticks_right.push_back(nR), r.ticks_left.push_back(nL);
    r.x_m.push_back(x + std::cos(phi) * lever_x - std::sin(phi) * lever_y);  // tracked point
    r.y_m.push_back(y + std::sin(phi) * lever_x + std::cos(phi) * lever_y);
    r.phi_rad.push_back(phi);
  };
  auto step = [&](double dR, double dL) {  // ticks this cycle
    nR += dR, nL += dL, t += 0.05;
    auto integ = [](const OdometryGeometry& g, double a, double b, double& X, double& Y,
                    double& P) {
      const double ds = 0.5 * (g.m_per_tick_right * a + g.m_per_tick_left * b);
      const double dp = (g.m_per_tick_right * a - g.m_per_tick_left * b) / g.track_m;
      X += ds * std::cos(P + 0.5 * dp), Y += ds * std::sin(P + 0.5 * dp), P += dp;
    };
    integ(truth, dR, dL, x, y, phi);
    integ(kNominal, dR, dL, xo, yo, phio);
    push();
  };
  push();
  for (int leg = 0; leg < 4; ++leg) {
    const double target_phi = leg * dir * M_PI / 2;
    double s = 0;
    while (s < L) {  // drive straight by odometry, steering on the odometric heading
      const double e = target_phi - phio;
      const double c = std::clamp(200 * e, -6.0, 6.0);
      step(30 + c, 30 - c);
      s += 30 * kNominal.m_per_tick_right;
    }
    const double goal = target_phi + dir * M_PI / 2;
    while (dir * (goal - phio) > 1e-4) {
      const double need =
          std::abs(goal - phio) * kNominal.track_m / (2 * kNominal.m_per_tick_right);
      const double n = std::min(20.0, need);
      step(dir * n, -dir * n);
    }
  }
  return r;
}

TEST(OdometryCalibration, UmbmarkRecoversDiameterRatioAndTrack) {
  std::vector<OdometryRun> runs{square(2.0, -1, kSmall), square(2.0, +1, kSmall)};
  const UmbmarkResult u = umbmark(runs, 2.0, kNominal);
  EXPECT_EQ(u.n_cw, 1);
  EXPECT_EQ(u.n_ccw, 1);
  const double Ed = kSmall.m_per_tick_right / kSmall.m_per_tick_left;
  EXPECT_NEAR(u.E_d, Ed, 0.15 * (Ed - 1));  // first-order formulas
  EXPECT_NEAR(u.E_b, kSmall.track_m / 0.2, 0.15 * 0.005);
  // corrected odometry predicts the squares far better than the nominal one
  EXPECT_LT(meanOdometryError(runs, u.corrected).end_position_m,
            0.3 * meanOdometryError(runs, kNominal).end_position_m);
  EXPECT_THROW(umbmark({runs[0]}, 2.0, kNominal), std::invalid_argument);
}

TEST(OdometryCalibration, LeastSquaresAndTrajectoryFitRecoverTheGeometry) {
  std::vector<OdometryRun> runs{square(2.0, -1, kTrue), square(2.0, +1, kTrue, 100)};
  const OdometryGeometry ls = leastSquaresCalibration(runs, 1.0);
  EXPECT_NEAR(ls.m_per_tick_right / kTrue.m_per_tick_right, 1, 1e-3);
  EXPECT_NEAR(ls.m_per_tick_left / kTrue.m_per_tick_left, 1, 1e-3);
  EXPECT_NEAR(ls.track_m / kTrue.track_m, 1, 2e-3);
  double rms = 0;
  const OdometryGeometry tf = trajectoryCalibration(runs, kNominal, TrajectoryFit{}, &rms);
  EXPECT_NEAR(tf.m_per_tick_right / kTrue.m_per_tick_right, 1, 1e-4);
  EXPECT_NEAR(tf.m_per_tick_left / kTrue.m_per_tick_left, 1, 1e-4);
  EXPECT_NEAR(tf.track_m / kTrue.track_m, 1, 1e-4);
  EXPECT_LT(rms, 1e-5);
  // only the track free: the wheels stay nominal
  TrajectoryFit only_b;
  only_b.free = {false, false, true};
  const OdometryGeometry tb = trajectoryCalibration(runs, kNominal, only_b);
  EXPECT_DOUBLE_EQ(tb.m_per_tick_right, kNominal.m_per_tick_right);
  EXPECT_NE(tb.track_m, kNominal.track_m);
}

TEST(OdometryCalibration, LeverArmOfTheTrackedPointIsFittedWithTheGeometry) {
  // the motion-capture point 3 cm ahead and 1 cm left of the axle midpoint
  std::vector<OdometryRun> runs{square(2.0, -1, kTrue, 0, 0.03, 0.01),
                                square(2.0, +1, kTrue, 100, 0.03, 0.01)};
  TrajectoryFit fit;
  fit.lever_arm = true;
  double rms = 0;
  const OdometryGeometry g = trajectoryCalibration(runs, kNominal, fit, &rms);
  EXPECT_NEAR(g.lever_x_m, 0.03, 1e-4);
  EXPECT_NEAR(g.lever_y_m, 0.01, 1e-4);
  EXPECT_NEAR(g.track_m / kTrue.track_m, 1, 1e-4);
  EXPECT_LT(rms, 1e-5);
  // without the lever arm the same data give a worse fit
  double rms0 = 0;
  trajectoryCalibration(runs, kNominal, TrajectoryFit{}, &rms0);
  EXPECT_GT(rms0, 10 * rms);
}

}  // namespace
}  // namespace wheelchair::identification
