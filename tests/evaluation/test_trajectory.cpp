// Path length, TUM I/O, interpolation association, lever arm.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "../common/TestUtil.h"
#include "EvalTestUtil.h"
#include "libwheelchair/evaluation/Association.h"
#include "libwheelchair/evaluation/Metrics.h"
#include "libwheelchair/evaluation/Trajectory.h"

using namespace wheelchair::evaluation;
using namespace wheelchair::evaluation::testutil;

namespace {

Trajectory square(double side, int per_side) {
  Trajectory t;
  const Eigen::Vector2d corners[5] = {{0, 0}, {side, 0}, {side, side}, {0, side}, {0, 0}};
  double time = 0.0;
  for (int c = 0; c < 4; ++c) {
    for (int k = 0; k < per_side; ++k) {
      const Eigen::Vector2d p = corners[c] + (corners[c + 1] - corners[c]) * k / per_side;
      t.push_back({time, p.x(), p.y(), c * M_PI / 2});
      time += 0.1;
    }
  }
  t.push_back({time, 0.0, 0.0, 2 * M_PI});
  return t;
}

std::string writeFile(const std::string& name, const std::string& text) {
  const std::string p = tempPath(name);
  std::ofstream(p) << text;
  return p;
}

using wheelchair::test::errorOf;

}  // namespace

TEST(PathLength, SquareOfKnownSide) {
  const Trajectory sq = square(2.5, 10);
  EXPECT_NEAR(pathLength(sq), 10.0, 1e-12);
  EXPECT_DOUBLE_EQ(pathLength({}), 0.0);
  EXPECT_DOUBLE_EQ(pathLength({{0, 1, 2, 0}}), 0.0);

  // The same square as ground truth: d_path_m = 4 side, closed loop, zero errors. (Outlier
  // flagging off: instantaneous 90 deg corners at 0.25 m spacing are not constant-velocity.)
  MetricOptions opt;
  opt.outliers.enabled = false;
  const Metrics m = computeMetrics(sq, toGroundTruth(sq, false), opt);
  EXPECT_NEAR(m.d_path_m, 10.0, 1e-12);
  EXPECT_NEAR(m.d_path_gt_m, 10.0, 1e-12);
  EXPECT_NEAR(m.loop_error_m, 0.0, 1e-12);
  EXPECT_NEAR(m.ate_rmse_m, 0.0, 1e-9);
  EXPECT_EQ(m.n_matched, sq.size());
  EXPECT_EQ(m.n_outliers, 0u);
}

TEST(Association, HandComputedInterpolationAndAnglesAcrossPi) {
  const double d2r = M_PI / 180.0;
  const Trajectory est = {{0.0, 0.0, 0.0, 170 * d2r},
                          {1.0, 2.0, 4.0, -170 * d2r},      // +20 deg across +-pi
                          {3.0, 6.0, 8.0, 0.0}};            // 2 s gap > max_gap = 1.5 s
  const std::vector<Position2DStamped> gt = {{-0.5, 0, 0},  // before the estimate: not matched
                                             {0.25, 9, 9},  // 1/4: (0.5, 1), 175 deg
                                             {0.75, 9, 9},  // 3/4: (1.5, 3), 185 deg = -175 deg
                                             {2.0, 9, 9},   // inside the gap: not matched
                                             {3.0, 9, 9},   // exactly on a sample: matched
                                             {3.5, 9, 9}};  // after: not matched
  const Association a = associate(est, gt, 1.5);
  EXPECT_EQ(a.n_gt_total, 6u);
  ASSERT_EQ(a.n_matched, 3u);
  EXPECT_EQ(a.gt_index, (std::vector<std::size_t>{1, 2, 4}));
  EXPECT_NEAR(a.est[0].x(), 0.5, 1e-12);
  EXPECT_NEAR(a.est[0].y(), 1.0, 1e-12);
  EXPECT_NEAR(a.est_phi[0], 175 * d2r, 1e-12);
  EXPECT_NEAR(a.est[1].x(), 1.5, 1e-12);
  EXPECT_NEAR(a.est[1].y(), 3.0, 1e-12);
  EXPECT_NEAR(a.est_phi[1], -175 * d2r, 1e-12);  // wrapped, not 5 deg the long way round
  EXPECT_NEAR(a.est[2].x(), 6.0, 1e-12);
  EXPECT_DOUBLE_EQ(a.t[2], 3.0);
  EXPECT_TRUE(std::isnan(a.gt_phi[0]));
  // The default max_gap of 0.5 s rejects the 1 s interval too: only the exact sample is left.
  EXPECT_EQ(associate(est, gt).n_matched, 1u);

  // A larger max_gap lets the sample in the gap through: (4, 6) halfway.
  const Association b = associate(est, gt, 2.5);
  ASSERT_EQ(b.n_matched, 4u);
  EXPECT_NEAR(b.est[2].x(), 4.0, 1e-12);
  EXPECT_NEAR(b.est[2].y(), 6.0, 1e-12);
}

TEST(Association, LeverArmMovesEstimateToTag) {
  // Heading 90 deg, tag 0.2 m ahead and 0.1 m left of the axle centre: tag = p + (-0.1, 0.2).
  const Trajectory est = {{0.0, 1.0, 1.0, M_PI / 2}, {1.0, 1.0, 2.0, M_PI / 2}};
  const std::vector<Position2DStamped> gt = {{0.5, 0.9, 1.7}};
  const Association a = associate(est, gt, 1.0, Eigen::Vector2d(0.2, 0.1));
  ASSERT_EQ(a.n_matched, 1u);
  EXPECT_NEAR(a.est[0].x(), 0.9, 1e-12);
  EXPECT_NEAR(a.est[0].y(), 1.7, 1e-12);
  const Trajectory tag = applyLeverArm(est, {0.2, 0.1});
  EXPECT_NEAR(tag[1].x_m, 0.9, 1e-12);
  EXPECT_NEAR(tag[1].y_m, 2.2, 1e-12);
}

TEST(Association, RejectsUnorderedInput) {
  const Trajectory est = {{1.0, 0, 0, 0}, {0.5, 0, 0, 0}};
  EXPECT_THROW(associate(est, {}, 0.5), std::invalid_argument);
}

TEST(Tum, WriteReadRoundTrip) {
  const Trajectory traj = {{1700000000.123456, 1.5, -2.25, 0.0},
                           {1700000000.173456, 1.0 / 3.0, 1e-7, M_PI - 1e-12},
                           {1700000000.223456, -4.0, 5.0, -M_PI + 1e-12},
                           {1700000000.273456, 0.1, 0.2, 1.0},
                           {1700000000.323456, 0.1, 0.2, -2.5}};
  const std::string p = tempPath("roundtrip.tum");
  writeTum(p, traj);
  EXPECT_FALSE(std::filesystem::exists(p + ".tmp"));
  const Trajectory back = readTum(p);
  ASSERT_EQ(back.size(), traj.size());
  for (std::size_t k = 0; k < traj.size(); ++k) {
    EXPECT_EQ(back[k].t_s, traj[k].t_s);  // shortest round-trip representation: exact
    EXPECT_EQ(back[k].x_m, traj[k].x_m);
    EXPECT_EQ(back[k].y_m, traj[k].y_m);
    EXPECT_NEAR(angleDiff(back[k].phi_rad, traj[k].phi_rad), 0.0, 1e-12) << k;
  }
  const auto gt = readTumGroundTruth(p, false);
  ASSERT_EQ(gt.size(), traj.size());
  EXPECT_FALSE(gt[0].hasHeading());
  EXPECT_TRUE(readTumGroundTruth(p, true)[0].hasHeading());
}

TEST(Tum, ReadsGeneralQuaternionsAndComments) {
  // 90 deg yaw as an unnormalised quaternion, CRLF, blank and comment lines.
  const std::string p =
      writeFile("general.tum", "# t x y z qx qy qz qw\r\n\n0.5 1 2 0.3 0 0 2 2\r\n  # c\n");
  const Trajectory t = readTum(p);
  ASSERT_EQ(t.size(), 1u);
  EXPECT_NEAR(t[0].phi_rad, M_PI / 2, 1e-12);
  EXPECT_EQ(t[0].x_m, 1.0);
}

TEST(Tum, MalformedLinesNameFileAndLine) {
  const std::string bad_num =
      writeFile("bad_num.tum", "# header\n1.0 0 0 0 0 0 0 1\n2.0 0 abc 0 0 0 0 1\n");
  std::string msg = errorOf([&] { readTum(bad_num); });
  EXPECT_NE(msg.find(bad_num + ":3:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("'abc'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("(y)"), std::string::npos) << msg;

  const std::string bad_count =
      writeFile("bad_count.tum", "1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 0 1\n\n3.0 1 2 3\n");
  msg = errorOf([&] { readTum(bad_count); });
  EXPECT_NE(msg.find(bad_count + ":4:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("expected 8"), std::string::npos) << msg;

  const std::string bad_time = writeFile("bad_time.tum", "2.0 0 0 0 0 0 0 1\n1.0 0 0 0 0 0 0 1\n");
  msg = errorOf([&] { readTum(bad_time); });
  EXPECT_NE(msg.find(bad_time + ":2:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("time-ordered"), std::string::npos) << msg;

  const std::string zero_q = writeFile("zero_q.tum", "1.0 0 0 0 0 0 0 0\n");
  msg = errorOf([&] { readTum(zero_q); });
  EXPECT_NE(msg.find(zero_q + ":1:"), std::string::npos) << msg;

  const std::string missing = tempPath("does_not_exist.tum");
  msg = errorOf([&] { readTum(missing); });
  EXPECT_NE(msg.find(missing), std::string::npos) << msg;
}
