// The numerics of identification/LeastSquares.h: rank detection on a structurally
// rank-deficient regressor, estimability of linear functionals, and HAC standard errors that
// cover the truth under strongly autocorrelated residuals where the iid ones do not.
#include "libwheelchair/identification/Identification.h"
#include "libwheelchair/identification/LeastSquares.h"
#include "libwheelchair/model/VehicleParams.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

using namespace wheelchair;
using identification::LsInput;
using identification::solveLeastSquares;

TEST(LeastSquares, DetectsProportionalColumnsAndEstimableFunctionals) {
  std::mt19937 rng(1);
  std::normal_distribution<double> N(0, 1);
  const int n = 400;
  LsInput in;
  in.X.resize(n, 3);
  in.y.resize(n);
  for (int i = 0; i < n; ++i) {
    const double a = N(rng), b = N(rng);
    in.X.row(i) << a, 1e4 * a, b;  // column 1 = 1e4 * column 0
    in.y(i) = 2 * a + 3 * b + 0.01 * N(rng);
    in.time_index.push_back(i);
    in.block.push_back(0);
  }
  const auto s = solveLeastSquares(in);
  EXPECT_EQ(s.rank, 2);
  EXPECT_FALSE(std::isfinite(s.condition_number) && s.condition_number < 1e8);
  EXPECT_LT(s.condition_number_identifiable, 10);
  Eigen::Vector3d e0(1, 0, 0), e2(0, 0, 1), combo(1, 1e4, 0);
  EXPECT_FALSE(s.isEstimable(e0));
  EXPECT_TRUE(s.isEstimable(e2));
  EXPECT_TRUE(s.isEstimable(combo));
  EXPECT_NEAR(s.estimate(combo), 2.0, 5e-3);
  EXPECT_NEAR(s.estimate(e2), 3.0, 5e-3);
  const Eigen::MatrixXd N0 = s.nullDirections();
  ASSERT_EQ(N0.cols(), 1);
  EXPECT_LT((in.X * N0).norm() / in.X.norm(), 1e-9);
}

// y = b x + AR(1)-filtered noise with a slowly varying regressor: the iid standard error is
// several times too small, the HAC one covers at about its nominal rate.
TEST(LeastSquares, HacStandardErrorsCoverUnderAutocorrelation) {
  std::mt19937 rng(7);
  std::normal_distribution<double> N(0, 1);
  const int n = 3000, reps = 200;
  int cover_hac = 0, cover_iid = 0;
  double ratio = 0;
  for (int r = 0; r < reps; ++r) {
    LsInput in;
    in.X.resize(n, 1);
    in.y.resize(n);
    double e = 0, x = 0;
    for (int i = 0; i < n; ++i) {
      e = 0.95 * e + N(rng);
      x = 0.95 * x + N(rng);
      in.X(i, 0) = x;
      in.y(i) = 1.5 * x + e;
      in.time_index.push_back(i);
      in.block.push_back(0);
    }
    identification::LsOptions opt;
    opt.hac_lags = 150;
    const auto s = solveLeastSquares(in, opt);
    Eigen::VectorXd w(1);
    w << 1;
    const double err = std::abs(s.estimate(w) - 1.5);
    cover_hac += err < 1.96 * s.standardError(w);
    cover_iid += err < 1.96 * s.standardErrorNaive(w);
    ratio += s.standardError(w) / s.standardErrorNaive(w) / reps;
  }
  const double f_hac = double(cover_hac) / reps, f_iid = double(cover_iid) / reps;
  std::printf("AR(1) 0.95: coverage of +-1.96 se: HAC %.3f, iid %.3f; se ratio %.2f\n", f_hac,
              f_iid, ratio);
  EXPECT_GT(f_hac, 0.88);
  EXPECT_LT(f_iid, 0.6);
  EXPECT_GT(ratio, 3.0);
}

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
