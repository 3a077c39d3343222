// SE(2) alignment: recovery of a known transform, origin vs SE(2) vs first-seconds alignment.
#include <gtest/gtest.h>

#include <cmath>

#include "EvalTestUtil.h"
#include "libwheelchair/evaluation/Alignment.h"
#include "libwheelchair/evaluation/Metrics.h"

using namespace wheelchair::evaluation;
using namespace wheelchair::evaluation::testutil;

TEST(AlignSE2, RecoversKnownTransformAndZeroAte) {
  // Ground truth = T(estimate) with a known T; the estimate is sampled 5x faster.
  const SE2 T{3.0, -1.5, 0.7};
  const Trajectory truth = sample(wander, 0.0, 0.02, 3001);  // 60 s
  const Trajectory est = transformed(truth, T.inverse());
  std::vector<Position2DStamped> gt;
  for (std::size_t k = 0; k < truth.size(); k += 5)
    gt.push_back({truth[k].t_s, truth[k].x_m, truth[k].y_m});

  std::vector<Eigen::Vector2d> e, g;
  for (const auto& p : est) e.emplace_back(p.x_m, p.y_m);
  for (const auto& p : truth) g.emplace_back(p.x_m, p.y_m);
  const SE2 R = alignSE2(e, g);
  EXPECT_NEAR(R.x, T.x, 1e-9);
  EXPECT_NEAR(R.y, T.y, 1e-9);
  EXPECT_NEAR(R.theta, T.theta, 1e-12);

  MetricOptions opt;
  opt.alignment = Alignment::SE2;
  const Metrics m = computeMetrics(est, gt, opt);
  EXPECT_EQ(m.n_matched, gt.size());
  EXPECT_EQ(m.n_outliers, 0u);
  EXPECT_NEAR(m.ate_rmse_m, 0.0, 1e-9);
  EXPECT_NEAR(m.ate_max_m, 0.0, 1e-9);
  EXPECT_NEAR(m.alignment.x, T.x, 1e-9);
  EXPECT_NEAR(m.alignment.y, T.y, 1e-9);
  EXPECT_NEAR(m.alignment.theta, T.theta, 1e-12);
  EXPECT_NEAR(m.rpe_1m_m, 0.0, 1e-9);
  EXPECT_NEAR(m.heading_drift_deg, 0.0, 1e-9);
  EXPECT_EQ(m.heading_drift_method, HeadingDriftMethod::DirectionOfTravel);
  // Without alignment the offset shows up in full.
  opt.alignment = Alignment::None;
  EXPECT_GT(computeMetrics(est, gt, opt).ate_rmse_m, 1.0);
}

TEST(AlignSE2, ComposeAndInverse) {
  const SE2 A{1.0, 2.0, 0.3}, B{-0.5, 0.25, -1.1};
  const Eigen::Vector2d p(0.7, -3.0);
  EXPECT_LT(((A * B).apply(p) - A.apply(B.apply(p))).norm(), 1e-12);
  EXPECT_LT((A.inverse().apply(A.apply(p)) - p).norm(), 1e-12);
  EXPECT_THROW(alignSE2({}, {}), std::invalid_argument);
  EXPECT_THROW(alignSE2({p}, {p, p}), std::invalid_argument);
}

TEST(Alignment, OriginVersusSE2) {
  // Straight 10 m drive along x; the estimate is the same line rotated by 3 deg about its start
  // and shifted: a constant heading error from the start.
  const double th = 3.0 * M_PI / 180.0;
  const SE2 Tinv{1.0, -2.0, th};
  const Trajectory truth =
      sample([](double t) { return Eigen::Vector3d(0.5 * t, 0.0, 0.0); }, 0.0, 0.1, 201);
  const Trajectory est = transformed(truth, Tinv);
  const auto gt_pos = toGroundTruth(truth, false);

  MetricOptions opt;
  opt.alignment = Alignment::SE2;
  const Metrics se2 = computeMetrics(est, gt_pos, opt);
  EXPECT_NEAR(se2.ate_rmse_m, 0.0, 1e-9);

  // Origin alignment with position-only ground truth: translation only, so the error grows
  // linearly with distance from the start, 2 sin(th/2) s.
  opt.alignment = Alignment::Origin;
  const Metrics org = computeMetrics(est, gt_pos, opt);
  const double k = 2.0 * std::sin(th / 2.0);
  double sq = 0.0;
  for (const auto& p : truth) sq += (k * p.x_m) * (k * p.x_m);
  EXPECT_NEAR(org.ate_rmse_m, std::sqrt(sq / truth.size()), 1e-9);
  EXPECT_NEAR(org.terminal_error_m, k * 10.0, 1e-9);
  EXPECT_NEAR(org.ate_max_m, k * 10.0, 1e-9);
  EXPECT_NEAR(org.alignment.theta, 0.0, 0.0);
  EXPECT_GT(org.ate_rmse_m, se2.ate_rmse_m);
  // Heading drift is alignment-independent: the heading error is constant.
  EXPECT_NEAR(org.heading_drift_deg, 0.0, 1e-9);

  // With a ground-truth heading, origin alignment matches the full first pose (evo
  // --align_origin) and the rigidly transformed estimate aligns exactly.
  const Metrics org_h = computeMetrics(est, toGroundTruth(truth, true), opt);
  EXPECT_NEAR(org_h.ate_rmse_m, 0.0, 1e-9);
  EXPECT_NEAR(org_h.alignment.theta, -th, 1e-12);
}

TEST(Alignment, SE2FirstSecondsUsesOnlyTheWindow) {
  // Identical for the first 10 s, then the estimate veers left (growing heading error).
  const auto truth_f = [](double t) { return Eigen::Vector3d(0.5 * t, 0.0, 0.0); };
  const auto est_f = [](double t) {
    const double y = t <= 10.0 ? 0.0 : 0.02 * (t - 10.0) * (t - 10.0);
    return Eigen::Vector3d(0.5 * t, y, 0.0);
  };
  const Trajectory est = sample(est_f, 0.0, 0.1, 401);
  const auto gt = toGroundTruth(sample(truth_f, 0.0, 0.1, 401), false);

  MetricOptions opt;
  opt.alignment = Alignment::SE2FirstSeconds;
  opt.align_first_s = 8.05;  // 81 samples, t = 0 .. 8 s
  const Metrics first = computeMetrics(est, gt, opt);
  EXPECT_NEAR(first.alignment.x, 0.0, 1e-12);
  EXPECT_NEAR(first.alignment.y, 0.0, 1e-12);
  EXPECT_NEAR(first.alignment.theta, 0.0, 1e-12);
  EXPECT_NEAR(first.alignment_spread_m, std::sqrt((81.0 * 81.0 - 1.0) / 12.0) * 0.05, 1e-9);
  EXPECT_NEAR(first.terminal_error_m, 0.02 * 30.0 * 30.0, 1e-9);

  opt.alignment = Alignment::SE2;
  const Metrics all = computeMetrics(est, gt, opt);
  EXPECT_LT(all.ate_rmse_m, first.ate_rmse_m);  // least squares over everything
  EXPECT_LT(all.terminal_error_m, first.terminal_error_m);
  EXPECT_GT(std::abs(all.alignment.theta), 1e-3);  // rotated to spread the error
}
