// NEES helper and the outlier rule on Pozyx-like noise.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <Eigen/Cholesky>

#include "EvalTestUtil.h"
#include "libwheelchair/evaluation/Nees.h"
#include "libwheelchair/evaluation/Outliers.h"

using namespace wheelchair::evaluation;
using namespace wheelchair::evaluation::testutil;

TEST(Nees, HandComputedConstantOffset) {
  // Constant error (0.3, 0) m with covariance diag(0.09, 0.01): NEES = 0.09 / 0.09 = 1.
  std::vector<PositionEstimateStamped> est;
  std::vector<Position2DStamped> gt;
  const Eigen::Matrix2d P = Eigen::Vector2d(0.09, 0.01).asDiagonal();
  for (int k = 0; k <= 100; ++k) {
    const double t = 0.1 * k;
    est.push_back({t, Eigen::Vector2d(t + 0.3, 1.0), P});
  }
  for (int k = 0; k < 20; ++k) gt.push_back({0.05 + 0.5 * k, 0.05 + 0.5 * k, 1.0});
  NeesOptions opt;
  NeesResult r = averageNees(est, gt, opt);
  EXPECT_EQ(r.n, 20u);
  EXPECT_NEAR(r.mean_nees, 1.0, 1e-12);
  EXPECT_DOUBLE_EQ(r.fraction_inside95, 1.0);
  // Ground-truth noise adds to the covariance: 0.09 / (0.09 + 0.01) = 0.9.
  opt.gt_cov_m2 = 0.01 * Eigen::Matrix2d::Identity();
  r = averageNees(est, gt, opt);
  EXPECT_NEAR(r.mean_nees, 0.9, 1e-12);
  // Nothing matched: NaN.
  EXPECT_TRUE(std::isnan(averageNees(est, {{50.0, 0, 0}}, opt).mean_nees));
}

TEST(Nees, ConsistentEstimatorAveragesTwo) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0.0, 1.0);
  const Eigen::Matrix2d P = (Eigen::Matrix2d() << 0.04, 0.01, 0.01, 0.09).finished();
  const Eigen::Matrix2d L = P.llt().matrixL();
  std::vector<PositionEstimateStamped> est;
  std::vector<Position2DStamped> gt;
  for (int k = 0; k < 4000; ++k) {
    const double t = 0.1 * k;
    const Eigen::Vector3d truth = wander(t);
    est.push_back({t, truth.head<2>() + L * Eigen::Vector2d(n(rng), n(rng)), P});
    gt.push_back({t, truth.x(), truth.y()});
  }
  NeesOptions opt;
  opt.outliers.enabled = false;
  const NeesResult r = averageNees(est, gt, opt);
  EXPECT_EQ(r.n, 4000u);
  EXPECT_NEAR(r.mean_nees, 2.0, 0.15);
  EXPECT_LT(r.lower95, 2.0);
  EXPECT_GT(r.upper95, 2.0);
  EXPECT_NEAR(r.fraction_inside95, 0.95, 0.02);
  // 4x too optimistic a covariance is detected.
  for (auto& e : est) e.cov_m2 /= 4.0;
  EXPECT_GT(averageNees(est, gt, opt).mean_nees, 7.0);
}


TEST(Outliers, NoFalseAlarmsOnPozyxLikeNoise) {
  // 10 cm noise, 10 Hz, a drive with a stop and a turn on the spot seen by a tag 0.2 m ahead.
  const auto f = [](double t) -> Eigen::Vector3d {
    if (t < 20) return {0.8 * t, 0.0, 0.0};
    if (t < 25) return {16.0, 0.0, 0.0};               // stop
    if (t < 25 + M_PI) return {16.0, 0.0, (t - 25)};   // rotate 180 deg at 1 rad/s
    return {16.0 - 0.8 * (t - 25 - M_PI), 0.0, M_PI};  // drive back
  };
  std::size_t false_alarms = 0;
  for (unsigned seed = 1; seed <= 10; ++seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> n(0.0, 0.1);
    std::vector<Position2DStamped> gt;
    for (int k = 0; k < 450; ++k) {
      const double t = 0.1 * k;
      const Eigen::Vector3d p = f(t);
      const Pose2DStamped pose{t, p.x(), p.y(), p.z()};
      const Eigen::Vector2d tag = bodyPointPosition(pose, {0.2, 0.0});
      gt.push_back({t, tag.x() + n(rng), tag.y() + n(rng)});
    }
    auto dirty = gt;
    dirty[200].y_m += 2.0;  // during the stop
    const OutlierReport r = detectGtOutliers(dirty, OutlierOptions{});
    EXPECT_TRUE(r.is_outlier[200]) << seed;
    false_alarms += r.indices.size() - (r.is_outlier[200] ? 1 : 0);
    EXPECT_NEAR(r.sigma_m, 0.1 * std::sqrt(1.2), 0.04) << seed;
  }
  EXPECT_LE(false_alarms, 1u);  // of 4500 samples
}
