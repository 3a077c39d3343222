// The streaming TUM writer (evaluation::TumWriter, writeTum) and the pose-only estimate sink
// that `wheelchair evaluate` uses instead of whole estimation results (issue 13).
#include <gtest/gtest.h>

#include "../common/TestUtil.h"
#include "libwheelchair/estimation/Estimator.h"
#include "libwheelchair/evaluation/Batch.h"
#include "libwheelchair/evaluation/Trajectory.h"
#include "libwheelchair/io/RawlogIO.h"

#include <cmath>
#include <filesystem>
#include <stdexcept>

using namespace wheelchair;
using namespace wheelchair::evaluation;

TEST(TumWriter, StreamedPosesReadBackExactlyWithCommentsAndLastOfEqualTimes) {
  wheelchair::test::TempDir dir;
  const std::string path = dir / "t.tum";
  {
    TumWriter w(path, {"frame: start", "made by a test"});
    w.add({0.1, 1.0 / 3, -2.0 / 7, 0.5});
    w.add({0.2, 1e-9, 123456.789, -3.0});
    w.add({0.2, 5.0, 6.0, 1.0});  // same time: replaces the previous pose
    w.add({0.35, -0.0, 2.5, M_PI - 1e-12});
    EXPECT_EQ(w.poses(), 3u);
    EXPECT_FALSE(std::filesystem::exists(path));
    w.commit();
  }
  const std::string text = wheelchair::test::readFile(path);
  EXPECT_EQ(text.rfind("# frame: start\n# made by a test\n# timestamp x y z qx qy qz qw", 0), 0u)
      << text;
  const Trajectory t = readTum(path);
  ASSERT_EQ(t.size(), 3u);
  EXPECT_EQ(t[0].x_m, 1.0 / 3);
  EXPECT_EQ(t[0].y_m, -2.0 / 7);
  EXPECT_NEAR(t[0].phi_rad, 0.5, 1e-15);
  EXPECT_EQ(t[1].t_s, 0.2);
  EXPECT_EQ(t[1].x_m, 5.0);
  EXPECT_NEAR(t[1].phi_rad, 1.0, 1e-15);
  EXPECT_EQ(t[2].y_m, 2.5);
  // writeTum is the same writer.
  writeTum(dir / "u.tum", t, {"frame: start", "made by a test"});
  const Trajectory u = readTum(dir / "u.tum");
  ASSERT_EQ(u.size(), t.size());
  for (std::size_t k = 0; k < t.size(); ++k) EXPECT_EQ(u[k].x_m, t[k].x_m);
}

TEST(TumWriter, AnEarlierPoseThrowsNamingTheFileAndNothingIsLeft) {
  wheelchair::test::TempDir dir;
  const std::string path = dir / "t.tum";
  try {
    TumWriter w(path);
    w.add({1.0, 0, 0, 0});
    w.add({0.5, 0, 0, 0});
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
  EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
}

TEST(TrajectorySink, KeepsThePosesOfTheStoredEstimates) {
  // A short simulated drive through the real reader.
  wheelchair::test::TempDir dir;
  const auto r = wheelchair::test::cli("simulate --scenario three_task --duration 15 -o " +
                                       (dir / "d.rawlog") + " --truth " + (dir / "t.json"));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const io::Recording rec = io::readRawlog(dir / "d.rawlog");
  const config::WheelchairConfig cfg;
  estimation::EkfOptions opt;
  const auto stored = estimation::runEstimator(rec, cfg, opt);
  TrajectorySink poses;
  const auto streamed = estimation::runEstimator(rec, cfg, opt, poses);
  const Trajectory a = toTrajectory(stored), b = poses.take();
  ASSERT_GT(a.size(), 500u);
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(streamed.n_estimates, stored.estimates.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    ASSERT_EQ(a[k].t_s, b[k].t_s);
    ASSERT_EQ(a[k].x_m, b[k].x_m);
    ASSERT_EQ(a[k].y_m, b[k].y_m);
    ASSERT_EQ(a[k].phi_rad, b[k].phi_rad);
  }
  EXPECT_TRUE(poses.take().empty());
}
