// Command-driven EKF on landmark sightings (libwheelchair/estimation/CommandDrivenEkf.h):
// the range-bearing Jacobian against central differences, and the filter on the bundled MRCLAM
// slice (datasets/mrclam, robots 3 and 4) evaluated against Vicon, which it never sees.
#include "libwheelchair/estimation/CommandDrivenEkf.h"
#include "libwheelchair/io/MrclamImport.h"

#include <gtest/gtest.h>
#include <mrpt/config/CConfigFileMemory.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>

namespace wheelchair::estimation {
namespace {

const std::string kSlice = std::string(WHEELCHAIR_SOURCE_DIR) + "/datasets/mrclam";

TEST(CommandDrivenEkf, RangeBearingJacobian) {
  model::CommandState x;
  x << 0.3, -1.2, 2.5, 0.1, 0.2;
  const Eigen::Vector2d L(2.0, 1.0);
  Eigen::Matrix<double, 2, 5> H;
  rangeBearing(x, L, &H);
  for (int k = 0; k < 5; ++k) {
    model::CommandState a = x, b = x;
    a(k) += 1e-6;
    b(k) -= 1e-6;
    const Eigen::Vector2d d = (rangeBearing(a, L) - rangeBearing(b, L)) / 2e-6;
    EXPECT_NEAR(d(0), H(0, k), 1e-7);
    EXPECT_NEAR(d(1), H(1, k), 1e-7);
  }
}

// Position RMSE and heading RMS error (deg) of the estimate at the ground-truth times.
std::pair<double, double> errorsAgainstVicon(const CommandDrivenEkfResult& r,
                                             const io::Recording& rec) {
  double se = 0, sh = 0;
  std::size_t n = 0, k = 0;
  for (const auto& g : rec.ground_truth) {
    while (k + 1 < r.trajectory.size() && r.trajectory[k + 1].t_s <= g.t_s) ++k;
    if (g.t_s < r.trajectory.front().t_s || k + 1 >= r.trajectory.size()) continue;
    const auto& e = r.trajectory[k];
    se += std::pow(e.x_m - g.x_m, 2) + std::pow(e.y_m - g.y_m, 2);
    sh += std::pow(std::remainder(e.phi_rad - g.phi_rad, 2 * M_PI) * 180 / M_PI, 2);
    ++n;
  }
  return {std::sqrt(se / n), std::sqrt(sh / n)};
}

TEST(CommandDrivenEkf, TracksTheBundledMrclamSliceWithoutGroundTruth) {
  const auto opt =
      loadCommandDrivenEkfOptions(std::string(WHEELCHAIR_SOURCE_DIR) + "/config/mrclam.ini");
  // Robot 4's slice sees only one mapped landmark: no initialisation, honestly reported.
  {
    const auto rec = io::importMrclam(kSlice, 4);
    EXPECT_FALSE(runCommandDrivenEkf(rec, io::landmarkMap(rec), opt).initialised);
  }
  for (int robot : {3}) {
    const auto rec = io::importMrclam(kSlice, robot);
    const auto r = runCommandDrivenEkf(rec, io::landmarkMap(rec), opt);
    ASSERT_TRUE(r.initialised) << robot;
    const auto [pos, head] = errorsAgainstVicon(r, rec);
    std::cout << "robot " << robot << ": start " << r.t_start_s - rec.ground_truth.front().t_s
              << " s, accepted " << r.landmarks().used << ", rejected " << r.landmarks().rejected
              << ", unmapped " << r.unmapped << ", mean NIS " << r.landmarks().meanNis()
              << ", position RMSE " << pos << " m, heading RMS " << head << " deg\n";
    EXPECT_GT(r.landmarks().used, 10);
    EXPECT_LT(pos, 0.5);
    EXPECT_LT(head, 20.0);
  }
}

// Full data: WHEELCHAIR_MRCLAM_REPORT=1 ./test_estimation --gtest_filter='*FullDataset*'
TEST(CommandDrivenEkf, FullDatasetReport) {
  const std::string dir = "/work/shared/datasets/mrclam/MRCLAM_Dataset6";
  if (!std::getenv("WHEELCHAIR_MRCLAM_REPORT") || !std::filesystem::is_directory(dir))
    GTEST_SKIP() << "set WHEELCHAIR_MRCLAM_REPORT=1 with the full dataset at " << dir;
  const auto extended =
      loadCommandDrivenEkfOptions(std::string(WHEELCHAIR_SOURCE_DIR) + "/config/mrclam.ini");
  CommandDrivenEkfOptions nominal = extended;
  nominal.response = model::CommandResponseParams{};
  nominal.ignore_zero_runs = false;
  for (int robot = 1; robot <= 5; ++robot) {
    const auto rec = io::importMrclam(dir, robot);
    const CommandDrivenEkfOptions* both[2] = {&nominal, &extended};
    for (const auto* o : both) {
      const auto r = runCommandDrivenEkf(rec, io::landmarkMap(rec), *o);
      ASSERT_TRUE(r.initialised);
      const auto [pos, head] = errorsAgainstVicon(r, rec);
      std::cout << "| " << robot << " | " << (o == &nominal ? "nominal" : "extended") << " | "
                << pos << " | " << head << " | " << r.landmarks().used << " | "
                << r.landmarks().rejected << " | " << r.landmarks().meanNis() << " |\n";
    }
  }
}

TEST(CommandDrivenEkf, NeedsAMap) {
  io::Recording rec;
  EXPECT_THROW(runCommandDrivenEkf(rec, {}, {}), std::invalid_argument);
}

// The unmodeled terms written by `wheelchair diagnose` ([mrclam_response] unmodeled_v/_omega)
// are read, written back, and move the dead reckoning exactly as their closed form says.
TEST(CommandDrivenEkf, UnmodeledTermsRoundTripAndClosedForm) {
  const std::string ini_text =
      "[mrclam_response]\n"
      "unmodeled_v = {\"v_cmd\": 0.2, \"1\": 0.01}\n"
      "unmodeled_omega = {\"|omega_cmd|\": -0.1}\n";
  mrpt::config::CConfigFileMemory ini(ini_text);
  const CommandDrivenEkfOptions o = loadCommandDrivenEkfOptions(ini);
  ASSERT_TRUE(o.hasUnmodeled());
  EXPECT_DOUBLE_EQ(o.unmodeled[0][1], 0.2);
  EXPECT_DOUBLE_EQ(o.unmodeled[0][0], 0.01);
  EXPECT_DOUBLE_EQ(o.unmodeled[1][3], -0.1);
  const Eigen::Vector2d d = o.unmodeledVelocity(Eigen::Vector2d(0.5, -0.4));
  EXPECT_NEAR(d(0), 0.01 + 0.2 * 0.5, 1e-15);
  EXPECT_NEAR(d(1), -0.1 * 0.4, 1e-15);
  mrpt::config::CConfigFileMemory back(toIni(o));
  const CommandDrivenEkfOptions o2 = loadCommandDrivenEkfOptions(back);
  EXPECT_EQ(o2.unmodeled, o.unmodeled);

  // A straight command v = 0.5 m/s for 4 s (nominal response: velocities = commands):
  // v_e = 0.5 + 0.01 + 0.2 * 0.5 = 0.61 m/s, omega_e = 0 -> x = 2.44 m.
  io::Recording rec;
  for (int k = 0; k <= 400; ++k) rec.joystick.push_back({0.01 * k, 0.5, 0.0});
  const auto dr =
      deadReckoningCommands(rec, o, 0.0, Eigen::Vector3d::Zero(), Eigen::Vector2d(0.5, 0.0));
  ASSERT_FALSE(dr.empty());
  EXPECT_NEAR(dr.back().t_s, 4.0, 1e-9);
  EXPECT_NEAR(dr.back().x_m, 0.61 * 4.0, 1e-9);
  EXPECT_NEAR(dr.back().y_m, 0.0, 1e-12);
  EXPECT_NEAR(dr.back().v_m_s, 0.61, 1e-12);

  // Unknown feature names are an error that names the key.
  mrpt::config::CConfigFileMemory bad("[mrclam_response]\nunmodeled_v = {\"v^3\": 1}\n");
  try {
    loadCommandDrivenEkfOptions(bad);
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("unmodeled_v"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace wheelchair::estimation
