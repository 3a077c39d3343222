// Pozyx fused by the filters ([estimator] use_pozyx = 1) on the bundled faulty drive, through
// the CLI: `filter` says the Pozyx is no longer an independent truth (console and TUM header),
// `evaluate` marks the filters' rows "pozyx_fused" and warns, and with the simulator's truth
// (`evaluate --truth`) scores against it instead, where fusing lowers the EKF's ATE.
#include "../common/TestUtil.h"

#include "libwheelchair/config/WheelchairConfig.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <sstream>
#include <string>

using namespace wheelchair;
using namespace wheelchair::test;

namespace {

// The ate_rmse_m column of `variant`'s row in an evaluate CSV (NaN when absent).
double ateOf(const std::string& csv_path, const std::string& variant, std::string* truth) {
  std::istringstream in(readFile(csv_path));
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ls(line);
    for (std::string c; std::getline(ls, c, ',');) f.push_back(c);
    if (f.size() > 7 && f[1] == variant) {
      if (truth) *truth = f[2];
      return std::stod(f[7]);
    }
  }
  return std::nan("");
}

}  // namespace

TEST(PozyxFusedEvaluate, SaysSoAndScoresAgainstTheSimulatorTruth) {
  TempDir dir;
  const std::string rawlog = dir / "faulty.rawlog";
  const std::string truth = sourcePath("datasets/three_task_faulty.truth.json");
  ASSERT_EQ(cli("import " + sourcePath("datasets/three_task_faulty") + " -o " + rawlog +
                " --config " + sourcePath("config/wheelchair.ini"))
                .exit_code,
            0);
  // The shipped configuration with the Pozyx fused in the drive's anchor frame (from the
  // simulator's truth: p_anchor = R(yaw) p_start + (x, y)).
  std::ifstream tin(truth);
  const auto anchor = nlohmann::json::parse(tin).at("pozyx_anchor");
  auto cfg = config::WheelchairConfig::load(sourcePath("config/wheelchair.ini"));
  cfg.set("estimator", "use_pozyx", "1");
  cfg.set("estimator", "pozyx_anchor_x_m", std::to_string(anchor.at("x_m").get<double>()));
  cfg.set("estimator", "pozyx_anchor_y_m", std::to_string(anchor.at("y_m").get<double>()));
  cfg.set("estimator", "pozyx_anchor_yaw_deg",
          std::to_string(anchor.at("yaw_rad").get<double>() * 180 / M_PI));
  const std::string fused_ini = dir / "fused.ini";
  cfg.save(fused_ini);

  const auto f = cli("filter " + rawlog + " --no-progress --config " + fused_ini +
                     " --trajectory " + (dir / "ekf.tum"));
  ASSERT_EQ(f.exit_code, 0) << f.out;
  EXPECT_NE(f.out.find("note: Pozyx fused (use_pozyx = 1): not an independent ground truth"),
            std::string::npos)
      << f.out;
  EXPECT_NE(readFile(dir / "ekf.tum").find("# Pozyx fused (use_pozyx = 1)"), std::string::npos);

  // Against the Pozyx itself: the filters' rows say so, and a warning names the file.
  const auto e = cli("evaluate " + rawlog + " -q --no-baseline --config " + fused_ini + " --csv " +
                     (dir / "pozyx.csv"));
  ASSERT_EQ(e.exit_code, 0) << e.out;
  EXPECT_NE(e.out.find("not an independent evaluation"), std::string::npos) << e.out;
  std::string gt;
  ateOf(dir / "pozyx.csv", "ekf", &gt);
  EXPECT_EQ(gt, "pozyx_fused");
  ateOf(dir / "pozyx.csv", "encoders", &gt);
  EXPECT_EQ(gt, "pozyx");  // dead reckoning does not use the Pozyx

  // Against the simulator's truth: fused vs the shipped (Pozyx not fused) configuration.
  const auto fused = cli("evaluate " + rawlog + " -q --no-baseline --config " + fused_ini +
                         " --truth " + truth + " --csv " + (dir / "fused.csv"));
  ASSERT_EQ(fused.exit_code, 0) << fused.out;
  EXPECT_EQ(fused.out.find("not an independent"), std::string::npos) << fused.out;
  const auto nominal = cli("evaluate " + rawlog + " -q --no-baseline --config " +
                           sourcePath("config/wheelchair.ini") + " --truth " + truth + " --csv " +
                           (dir / "nominal.csv"));
  ASSERT_EQ(nominal.exit_code, 0) << nominal.out;
  const double ate_fused = ateOf(dir / "fused.csv", "ekf", &gt);
  EXPECT_EQ(gt, "simulator");
  const double ate_nominal = ateOf(dir / "nominal.csv", "ekf", nullptr);
  std::printf(
      "three_task_faulty, ekf ATE against the simulator's truth: %.3f m without the "
      "Pozyx, %.3f m with it fused\n",
      ate_nominal, ate_fused);
  // The shipped filter already corrects the faulty encoder online (its side from the motor
  // currents: 0.013 m, 0.05 m before); fused, the Pozyx (0.1 m noise) must keep it there.
  EXPECT_LT(ate_fused, 0.03);
  EXPECT_LT(ate_fused, ate_nominal + 0.005);

  // One truth file per recording.
  EXPECT_EQ(cli("evaluate " + rawlog + " -q --truth " + truth + " " + truth).exit_code, 2);
}
