// RPE (evo definition), heading drift, ground-truth outliers, CSV and evo export.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <sstream>

#include "EvalTestUtil.h"
#include "libwheelchair/evaluation/Metrics.h"
#include "libwheelchair/evaluation/Outliers.h"

using namespace wheelchair::evaluation;
using namespace wheelchair::evaluation::testutil;

namespace {
constexpr double kD2R = M_PI / 180.0;

// 20 m straight drive along x at 1 m/s, one sample per 0.125 m (exact in binary, so the path
// accumulates to exactly 1 m every 8 samples).
Trajectory straight20m() {
  return sample([](double t) { return Eigen::Vector3d(t, 0.0, 0.0); }, 0.0, 0.125, 161);
}
}  // namespace

TEST(Rpe, PairsFollowEvoFilterPairsByPath) {
  std::vector<Eigen::Vector2d> p;
  for (int k = 0; k <= 40; ++k) p.emplace_back(0.125 * k, 0.0);
  // evo starts at the first index whose accumulated path reaches delta (not at 0).
  const auto pairs = pairsByPath(p, 1.0);
  ASSERT_EQ(pairs.size(), 4u);
  EXPECT_EQ(pairs[0], std::make_pair(std::size_t{8}, std::size_t{16}));
  EXPECT_EQ(pairs[3], std::make_pair(std::size_t{32}, std::size_t{40}));
  // The overshoot is dropped when the accumulation restarts.
  const auto p3 = pairsByPath(p, 0.3);  // reaches 0.375 every 3 samples
  ASSERT_FALSE(p3.empty());
  EXPECT_EQ(p3[0], std::make_pair(std::size_t{3}, std::size_t{6}));
}

TEST(Rpe, ConstantHeadingErrorWithGroundTruthHeading) {
  // Positions exact, heading off by a constant 10 deg: evo's RPE translation part is
  // |R_Pi^T dP - R_Qi^T dQ| = |dQ| 2 sin(10 deg / 2) for every pair.
  const double th = 10.0 * kD2R;
  const Trajectory truth = straight20m();
  Trajectory est = truth;
  for (auto& p : est) p.phi_rad += th;
  MetricOptions opt;
  opt.alignment = Alignment::None;
  const Metrics m = computeMetrics(est, toGroundTruth(truth, true), opt);
  EXPECT_NEAR(m.ate_rmse_m, 0.0, 1e-12);
  EXPECT_EQ(m.n_rpe_1m, 19u);  // ids at 1, 2, ..., 20 m
  EXPECT_EQ(m.n_rpe_5m, 3u);   // ids at 5, 10, 15, 20 m
  EXPECT_NEAR(m.rpe_1m_m, 2.0 * std::sin(th / 2.0), 1e-12);
  EXPECT_NEAR(m.rpe_5m_m, 10.0 * std::sin(th / 2.0), 1e-12);
  EXPECT_NEAR(m.heading_drift_deg, 0.0, 1e-9);  // constant error: no drift
  EXPECT_EQ(m.heading_drift_method, HeadingDriftMethod::GroundTruthHeading);

  // A rigidly rotated estimate (positions and heading) has zero RPE whatever the alignment.
  const Trajectory rot = transformed(truth, SE2{0.5, 0.2, th});
  EXPECT_NEAR(computeMetrics(rot, toGroundTruth(truth, true), opt).rpe_1m_m, 0.0, 1e-12);
}

TEST(Rpe, ConstantHeadingErrorPositionOnlyGroundTruth) {
  // The estimate drives the same line but 10 deg off (rotated about the start). Without a
  // ground-truth heading the error is |dP - dQ| in the aligned world frame.
  const double th = 10.0 * kD2R;
  const Trajectory truth = straight20m();
  const Trajectory est = transformed(truth, SE2{0.0, 0.0, th});
  const auto gt = toGroundTruth(truth, false);
  MetricOptions opt;
  opt.alignment = Alignment::None;
  Metrics m = computeMetrics(est, gt, opt);
  EXPECT_NEAR(m.rpe_1m_m, 2.0 * std::sin(th / 2.0), 1e-12);
  EXPECT_NEAR(m.rpe_5m_m, 10.0 * std::sin(th / 2.0), 1e-12);
  EXPECT_NEAR(m.terminal_error_m, 20.0 * 2.0 * std::sin(th / 2.0), 1e-9);
  // The SE(2) alignment removes the constant heading error.
  opt.alignment = Alignment::SE2;
  m = computeMetrics(est, gt, opt);
  EXPECT_NEAR(m.rpe_1m_m, 0.0, 1e-9);
  EXPECT_NEAR(m.ate_rmse_m, 0.0, 1e-9);
  // Pairs chosen along the estimate (evo's default). The rotated steps are no longer exact
  // binary fractions, so evo's accumulation may need a 9th step now and then.
  opt.rpe_pairs_from = RpePairsFrom::Estimate;
  m = computeMetrics(est, gt, opt);
  EXPECT_GE(m.n_rpe_1m, 17u);
  EXPECT_LE(m.n_rpe_1m, 19u);
  EXPECT_NEAR(m.rpe_1m_m, 0.0, 1e-9);
}

TEST(HeadingDrift, FromGroundTruthHeading) {
  // Gyro-bias-like heading error growing linearly to 5 deg at the end; positions exact.
  const Trajectory truth = straight20m();
  Trajectory est = truth;
  for (auto& p : est) p.phi_rad += 5.0 * kD2R * p.t_s / 20.0;
  MetricOptions opt;
  const Metrics m = computeMetrics(est, toGroundTruth(truth, true), opt);
  EXPECT_EQ(m.heading_drift_method, HeadingDriftMethod::GroundTruthHeading);
  EXPECT_NEAR(m.heading_drift_deg, 5.0, 1e-9);
}

TEST(HeadingDrift, FromDirectionOfTravelWithoutHeading) {
  // L-shaped drive: 10 m along x, then 10 m along y. The estimate's second leg is turned 5 deg
  // further left about the corner.
  const auto truth_f = [](double t) {
    return t <= 10.0 ? Eigen::Vector3d(t, 0.0, 0.0) : Eigen::Vector3d(10.0, t - 10.0, M_PI / 2);
  };
  const Trajectory truth = sample(truth_f, 0.0, 0.125, 161);
  Trajectory est = truth;
  const SE2 turn = SE2{10.0, 0.0, 5.0 * kD2R} * SE2{-10.0, 0.0, 0.0};  // about (10, 0)
  for (auto& p : est) {
    if (p.t_s <= 10.0) continue;
    const Eigen::Vector2d q = turn.apply({p.x_m, p.y_m});
    p.x_m = q.x();
    p.y_m = q.y();
  }
  const auto gt = toGroundTruth(truth, false);
  MetricOptions opt;
  opt.outliers.enabled = false;  // the instantaneous corner is not constant-velocity
  for (Alignment al : {Alignment::None, Alignment::Origin, Alignment::SE2}) {
    opt.alignment = al;
    const Metrics m = computeMetrics(est, gt, opt);
    EXPECT_EQ(m.heading_drift_method, HeadingDriftMethod::DirectionOfTravel);
    EXPECT_NEAR(m.heading_drift_deg, 5.0, 1e-9) << toString(al);
  }
  // Too short a drive for the segment spread: unavailable rather than noise.
  opt.heading_min_spread_m = 100.0;
  const Metrics m = computeMetrics(est, gt, opt);
  EXPECT_TRUE(std::isnan(m.heading_drift_deg));
  EXPECT_EQ(m.heading_drift_method, HeadingDriftMethod::Unavailable);
}

namespace {
struct NoisyDrive {
  Trajectory est;
  std::vector<Position2DStamped> gt;  // tag positions with 5 cm noise at 10 Hz
};

NoisyDrive noisyDrive() {
  NoisyDrive d;
  // Estimate at 50 Hz with a slowly growing heading error; ground truth = true tag position.
  const Eigen::Vector2d lever(0.2, 0.0);
  const Trajectory truth = sample(wander, 0.0, 0.02, 6001);  // 120 s
  d.est = truth;
  for (auto& p : d.est) {
    p.x_m += 0.002 * p.t_s;
    p.phi_rad += 0.0005 * p.t_s;
  }
  std::mt19937 rng(42);
  std::normal_distribution<double> n(0.0, 0.05);
  for (std::size_t k = 0; k < truth.size(); k += 5) {
    const Eigen::Vector2d tag = bodyPointPosition(truth[k], lever);
    d.gt.push_back({truth[k].t_s, tag.x() + n(rng), tag.y() + n(rng)});
  }
  return d;
}
}  // namespace

TEST(Outliers, InjectedJumpsAreFlaggedAndExcluded) {
  const NoisyDrive d = noisyDrive();
  const std::set<std::size_t> injected = {50, 120, 121, 300, 1000};
  std::vector<Position2DStamped> dirty = d.gt;
  for (auto i : injected) {
    dirty[i].x_m += 1.5;
    dirty[i].y_m -= 1.0;
  }
  const OutlierReport rep = detectGtOutliers(dirty, OutlierOptions{});
  EXPECT_EQ(std::set<std::size_t>(rep.indices.begin(), rep.indices.end()), injected);
  EXPECT_NEAR(rep.sigma_m, 0.05 * std::sqrt(1.2), 0.03);  // residual includes neighbour noise
  EXPECT_TRUE(detectGtOutliers(d.gt, OutlierOptions{}).indices.empty());

  MetricOptions opt;
  opt.lever_arm_m = {0.2, 0.0};
  const Metrics with = computeMetrics(d.est, dirty, opt);
  EXPECT_EQ(with.n_outliers, injected.size());
  EXPECT_EQ(with.n_gt, dirty.size());
  EXPECT_EQ(with.n_matched, dirty.size() - injected.size());

  // Same numbers as if the outliers had never been recorded.
  std::vector<Position2DStamped> removed;
  for (std::size_t k = 0; k < d.gt.size(); ++k)
    if (!injected.count(k)) removed.push_back(d.gt[k]);
  const Metrics ref = computeMetrics(d.est, removed, opt);
  EXPECT_EQ(ref.n_outliers, 0u);
  EXPECT_DOUBLE_EQ(with.ate_rmse_m, ref.ate_rmse_m);
  EXPECT_DOUBLE_EQ(with.ate_max_m, ref.ate_max_m);
  EXPECT_DOUBLE_EQ(with.rpe_1m_m, ref.rpe_1m_m);
  EXPECT_DOUBLE_EQ(with.heading_drift_deg, ref.heading_drift_deg);

  // Averaged in, they would have inflated the ATE.
  opt.outliers.enabled = false;
  EXPECT_GT(computeMetrics(d.est, dirty, opt).ate_max_m, 1.0);
  EXPECT_LT(ref.ate_max_m, 0.6);
}

TEST(Metrics, LeverArmMatters) {
  const NoisyDrive d = noisyDrive();
  MetricOptions opt;
  opt.alignment = Alignment::SE2FirstSeconds;
  opt.lever_arm_m = {0.2, 0.0};
  const Metrics right = computeMetrics(d.est, d.gt, opt);
  opt.lever_arm_m.setZero();
  const Metrics wrong = computeMetrics(d.est, d.gt, opt);
  EXPECT_LT(right.ate_rmse_m, wrong.ate_rmse_m);
}

TEST(Metrics, CsvColumns) {
  const NoisyDrive d = noisyDrive();
  const Metrics m = computeMetrics(d.est, d.gt, MetricOptions{});
  const std::string p = tempPath("metrics.csv");
  writeMetricsCsv(p, {{"ekf", m}, {"odom", m}}, Alignment::SE2);
  std::ifstream f(p);
  std::string header, row;
  std::getline(f, header);
  std::getline(f, row);
  for (const char* col : {"d_path_m", "terminal_error_m", "loop_error_m", "ate_rmse_m", "ate_max_m",
                          "rpe_1m_m", "heading_drift_deg", "n_outliers"}) {
    EXPECT_NE(header.find(col), std::string::npos) << col;
  }
  EXPECT_EQ(std::count(header.begin(), header.end(), ','), std::count(row.begin(), row.end(), ','));
  EXPECT_EQ(row.rfind("ekf,", 0), 0u);
  EXPECT_NE(row.find(",se2"), std::string::npos);
}

TEST(Metrics, EvoFilesReproduceTheNumbers) {
  // The exported, already associated files give the same ATE / RPE when evaluated again without
  // alignment (what evo_ape / evo_rpe compute on them).
  const NoisyDrive d = noisyDrive();
  MetricOptions opt;
  opt.lever_arm_m = {0.2, 0.0};
  const Metrics m = computeMetrics(d.est, d.gt, opt);
  const std::string prefix = tempPath("evo_");
  writeEvoFiles(prefix, d.est, d.gt, opt);
  const Trajectory gt = readTum(prefix + "gt.tum");
  const Trajectory est_al = readTum(prefix + "est_aligned.tum");
  const Trajectory est_raw = readTum(prefix + "est.tum");
  ASSERT_EQ(gt.size(), m.n_matched);
  ASSERT_EQ(est_al.size(), m.n_matched);

  MetricOptions plain;
  plain.alignment = Alignment::None;
  plain.outliers.enabled = false;
  const Metrics again = computeMetrics(est_al, toGroundTruth(gt, true), plain);
  EXPECT_NEAR(again.ate_rmse_m, m.ate_rmse_m, 1e-9);
  EXPECT_NEAR(again.rpe_1m_m, m.rpe_1m_m, 1e-9);
  EXPECT_NEAR(again.rpe_5m_m, m.rpe_5m_m, 1e-9);
  // evo -a on the raw export: our SE(2) alignment again.
  plain.alignment = Alignment::SE2;
  const Metrics raw = computeMetrics(est_raw, toGroundTruth(gt, true), plain);
  EXPECT_NEAR(raw.ate_rmse_m, m.ate_rmse_m, 1e-9);
  EXPECT_NEAR(raw.rpe_1m_m, m.rpe_1m_m, 1e-9);  // RPE with full poses is alignment-invariant
}
