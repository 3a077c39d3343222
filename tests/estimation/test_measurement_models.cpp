// The one measurement shape and update path (libwheelchair/estimation/Measurement.h): every
// filter's measurement model H against central differences of its h (physics CD-EKF in both
// obstacle forms, with and without the sensor-error states; the kinematic baseline), the
// angular-row wrap of the innovation, correct() = josephUpdate with its guard, and the NIS
// bookkeeping every filter shares.
#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/estimation/BaselineEkf.h"
#include "libwheelchair/estimation/CommandDrivenEkf.h"
#include "libwheelchair/estimation/Measurement.h"
#include "libwheelchair/estimation/WheelchairEkf.h"
#include "libwheelchair/model/Kinematics.h"
#include "libwheelchair/stats/Distributions.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <string>

using namespace wheelchair;
using namespace wheelchair::estimation;

namespace {

using ModelAt = std::function<Measurement&(const Eigen::VectorXd& x)>;

// H of model(x) against central differences of h (the innovation rows flagged angular are
// differenced through the wrap, as the update uses them).
void expectJacobianMatches(const ModelAt& model, const Eigen::VectorXd& x,
                           const std::string& what) {
  const Eigen::MatrixXd H = model(x).H;
  const unsigned angular = model(x).angular_rows;
  ASSERT_EQ(H.cols(), x.size()) << what;
  for (int j = 0; j < x.size(); ++j) {
    const double eps = 1e-6 * std::max(1.0, std::fabs(x(j)));
    Eigen::VectorXd a = x, b = x;
    a(j) += eps;
    b(j) -= eps;
    const Eigen::VectorXd ha = model(a).h, hb = model(b).h;
    for (int i = 0; i < H.rows(); ++i) {
      double d = ha(i) - hb(i);
      if (angular & (1u << i)) d = std::remainder(d, 2 * M_PI);
      const double num = d / (2 * eps);
      EXPECT_NEAR(H(i, j), num, 1e-6 * std::max(1.0, std::fabs(num)))
          << what << ": row " << i << ", state " << j;
    }
  }
}

// A state of n components in the filter's layout, away from singular points: every component
// drawn in [-1, 1] (positions scaled up) with the obstacle in front of the sonar.
Eigen::VectorXd randomState(int n, std::mt19937_64& rng, int obstacle_index, bool polar) {
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  Eigen::VectorXd x(n);
  for (int i = 0; i < n; ++i) x(i) = U(rng);
  if (polar) {
    x(obstacle_index) = 2.0 + U(rng);  // d_o (m)
    x(obstacle_index + 1) = 0.3 * U(rng);
  } else {
    x(obstacle_index) = 2.0 + U(rng);
    x(obstacle_index + 1) = 0.5 * U(rng);
  }
  return x;
}

config::WheelchairConfig configWithLeverArm() {
  config::WheelchairConfig cfg;
  cfg.set("pozyx", "lever_x_m", "-0.25");
  cfg.set("pozyx", "lever_y_m", "0.12");
  return cfg;
}

}  // namespace

TEST(MeasurementModels, PhysicsFilterJacobiansMatchCentralDifferences) {
  const auto cfg = configWithLeverArm();
  std::mt19937_64 rng(7);
  for (const bool polar : {false, true})
    for (const bool errors : {false, true}) {
      EkfOptions opt;
      opt.obstacle_form = polar ? ObstacleFormOption::Polar : ObstacleFormOption::Cartesian;
      opt.estimate_encoder_scales = errors;
      opt.estimate_gyro_bias = errors;
      WheelchairEkf ekf(cfg, opt, nullptr);
      const int n = ekf.filter().x().size();
      ASSERT_EQ(n, errors ? kPhysicsStateDim + kNumSensorErrorStates : kPhysicsStateDim);
      const std::string what =
          std::string(polar ? "polar" : "cartesian") + (errors ? ", sensor-error states" : "");
      for (int trial = 0; trial < 5; ++trial) {
        const Eigen::VectorXd x = randomState(n, rng, model::kIdxO1, polar);
        expectJacobianMatches(
            [&](const Eigen::VectorXd& s) -> Measurement& { return ekf.gyroModel(s, 0.1, 1e-4); },
            x, "physics gyro, " + what);
        expectJacobianMatches(
            [&](const Eigen::VectorXd& s) -> Measurement& { return ekf.sonarModel(s, 2.0, 1e-4); },
            x, "physics sonar, " + what);
        expectJacobianMatches(
            [&](const Eigen::VectorXd& s) -> Measurement& {
              return ekf.pozyxModel(s, Eigen::Vector2d(1, 2), Eigen::Matrix2d::Identity());
            },
            x, "physics Pozyx, " + what);
      }
      // The gyro sees omega + b_g when the bias is a state.
      Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
      x(model::kIdxOmega) = 0.2;
      if (errors) x(kIdxGyroBias) = 0.01;
      EXPECT_DOUBLE_EQ(ekf.gyroModel(x, 0, 1).h(0), errors ? 0.21 : 0.2);
    }
}

TEST(MeasurementModels, PozyxSeesTheTagAtItsLeverArm) {
  // Body at (1, 2) heading 90 deg: the tag at body (-0.25, 0.12) is at (1 - 0.12, 2 - 0.25).
  const auto cfg = configWithLeverArm();
  EkfOptions opt;
  WheelchairEkf ekf(cfg, opt, nullptr);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(kPhysicsStateDim);
  x(model::kIdxX) = 1;
  x(model::kIdxY) = 2;
  x(model::kIdxPhi) = M_PI / 2;
  const Eigen::VectorXd h =
      ekf.pozyxModel(x, Eigen::Vector2d::Zero(), Eigen::Matrix2d::Identity()).h;
  EXPECT_NEAR(h(0), 1 - 0.12, 1e-12);
  EXPECT_NEAR(h(1), 2 - 0.25, 1e-12);
  BaselineEkf base(cfg, opt);
  Eigen::VectorXd xb = Eigen::VectorXd::Zero(kBaselineStateDim);
  xb << 1, 2, M_PI / 2, 0, 0, 3, 2;
  const Eigen::VectorXd hb =
      base.pozyxModel(xb, Eigen::Vector2d::Zero(), Eigen::Matrix2d::Identity()).h;
  EXPECT_NEAR(hb(0), 1 - 0.12, 1e-12);
  EXPECT_NEAR(hb(1), 2 - 0.25, 1e-12);
}

TEST(MeasurementModels, BaselineJacobiansMatchCentralDifferences) {
  const auto cfg = configWithLeverArm();
  EkfOptions opt;
  opt.filter = FilterKind::Baseline;
  BaselineEkf ekf(cfg, opt);
  std::mt19937_64 rng(11);
  for (int trial = 0; trial < 5; ++trial) {
    // Baseline layout [x, y, phi, v, omega, ox, oy]: obstacle in the start frame.
    const Eigen::VectorXd x = randomState(kBaselineStateDim, rng, 5, false);
    expectJacobianMatches(
        [&](const Eigen::VectorXd& s) -> Measurement& { return ekf.gyroModel(s, 0.1, 1e-4); }, x,
        "baseline gyro");
    expectJacobianMatches(
        [&](const Eigen::VectorXd& s) -> Measurement& { return ekf.sonarModel(s, 2.0, 1e-4); }, x,
        "baseline sonar");
    expectJacobianMatches(
        [&](const Eigen::VectorXd& s) -> Measurement& {
          return ekf.pozyxModel(s, Eigen::Vector2d(1, 2), Eigen::Matrix2d::Identity());
        },
        x, "baseline Pozyx");
  }
}

TEST(MeasurementModels, CommandDrivenRangeBearingThroughTheCommonShape) {
  // The command-driven EKF's sighting as a Measurement: H of rangeBearing against central
  // differences, bearing row angular; near +-pi the wrapped innovation is the short way round.
  const Eigen::Vector2d L(2.0, 1.0);
  Measurement m(Sensor::Landmarks, 2, 5);
  m.angular_rows = 0b10;
  const ModelAt model = [&](const Eigen::VectorXd& s) -> Measurement& {
    Eigen::Matrix<double, 2, 5> H;
    m.h = rangeBearing(s, L, &H);
    m.H = H;
    return m;
  };
  Eigen::VectorXd x(5);
  x << 0.3, -1.2, 2.5, 0.1, 0.2;
  expectJacobianMatches(model, x, "range-bearing");
  model(x);
  m.z << m.h(0), model::wrapAngle(m.h(1) + 2 * M_PI - 0.01);  // 0.01 rad less, across the cut
  const Eigen::VectorXd y = m.innovation();
  EXPECT_NEAR(y(0), 0.0, 1e-12);
  EXPECT_NEAR(y(1), -0.01, 1e-9);
}

TEST(MeasurementModels, CorrectIsTheJosephUpdateOnTheWrappedInnovation) {
  Eigen::VectorXd x(3);
  x << 0.1, 3.1, -0.2;
  Eigen::MatrixXd P = Eigen::Vector3d(0.04, 0.09, 0.01).asDiagonal();
  Measurement m(Sensor::Gyro, 2, 3);
  m.H << 1, 0, 0, 0, 1, 0;
  m.R = Eigen::Vector2d(0.01, 0.02).asDiagonal();
  m.angular_rows = 0b10;
  m.z << 0.15, -3.1;  // the angle row is 0.083 rad from h across the +-pi cut
  m.h << x(0), x(1);
  Eigen::VectorXd x_ref = x;
  Eigen::MatrixXd P_ref = P;
  Eigen::VectorXd y(2);
  y << m.z(0) - m.h(0), model::wrapAngle(m.z(1) - m.h(1));
  EXPECT_NEAR(y(1), 2 * M_PI - 6.2, 1e-12);  // the short way round, not -6.2
  const UpdateResult ref = josephUpdate(x_ref, P_ref, y, m.H, m.R, 0.0);
  const UpdateResult r = correct(x, P, m, 0.0);
  ASSERT_TRUE(r.accepted);
  EXPECT_DOUBLE_EQ(r.nis, ref.nis);
  EXPECT_TRUE(x == x_ref);
  EXPECT_TRUE(P == P_ref);
  // A degenerate innovation covariance is rejected by the guard, nothing changes.
  m.R.setZero();
  Eigen::MatrixXd P0 = Eigen::MatrixXd::Zero(3, 3);
  Eigen::VectorXd x0 = x;
  const UpdateResult bad = correct(x0, P0, m, 0.0);
  EXPECT_FALSE(bad.accepted);
  EXPECT_TRUE(std::isinf(bad.nis));
  EXPECT_TRUE(x0 == x);
}

TEST(MeasurementModels, BookkeepingCountsGatesAndBands) {
  EstimationResult res;
  const double gate = stats::chi2Quantile(0.999, 1);
  UpdateResult ok;
  ok.accepted = true;
  ok.dof = 1;
  ok.nis = 1.0;  // inside chi2(1)'s 95 % interval [0.00098, 5.02]
  UpdateResult low = ok;
  low.nis = 1e-4;  // accepted, below the interval
  UpdateResult gated;
  gated.dof = 1;
  gated.nis = 50;
  gated.innovation = Eigen::VectorXd::Constant(1, 7.0);
  bookUpdate(res, Sensor::Sonar, 1.0, ok, gate, true);
  bookUpdate(res, Sensor::Sonar, 2.0, low, gate, true);
  bookUpdate(res, Sensor::Sonar, 3.0, gated, gate, false);
  const SensorStats& st = res.stats(Sensor::Sonar);
  EXPECT_EQ(st.used, 2);
  EXPECT_EQ(st.rejected, 1);
  EXPECT_EQ(st.nis_count, 2);
  EXPECT_EQ(st.nis_inside95, 1);
  EXPECT_DOUBLE_EQ(st.meanNis(), (1.0 + 1e-4) / 2);
  ASSERT_EQ(res.rejected.size(), 1u);
  EXPECT_EQ(res.rejected[0].t_s, 3.0);
  EXPECT_EQ(res.rejected[0].innovation(0), 7.0);
  EXPECT_EQ(res.nis.size(), 2u);  // the third was booked without its record
  EXPECT_EQ(std::string(sensorName(Sensor::Landmarks)), "landmarks");
}
