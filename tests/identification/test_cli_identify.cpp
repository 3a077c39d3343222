// `wheelchair identify` end to end: rawlog in, JSON and configuration out, exit codes.
#include "../common/TestUtil.h"

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/simulation/Simulator.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>

using namespace wheelchair;

namespace {
std::string cli() {
  return WHEELCHAIR_CLI;
}
}  // namespace

TEST(CliIdentify, WritesJsonAndConfig) {
  test::TempDir dir;
  config::WheelchairConfig truth;
  truth.vehicle.yaw_inertia_kg_m2 = 9.5;
  truth.syncToIni();
  simulation::SimulationOptions so;
  const auto s = simulation::simulate(truth, "excite", 4, 90, {}, so);
  const std::string log = dir / "excite.rawlog";
  io::writeRawlog(s.recording, log, truth);
  const std::string ini = std::string(WHEELCHAIR_SOURCE_DIR) + "/config/wheelchair.ini";

  const auto r =
      test::run(cli() + " identify " + log + " --config " + ini + " --cutoff-hz 2.5 --json " +
                (dir / "out.json") + " --write-config " + (dir / "out.ini"));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  std::ifstream f(dir / "out.json");
  const auto j = nlohmann::json::parse(f);
  EXPECT_EQ(j["config"], ini);
  EXPECT_EQ(j["options"]["cutoff_hz"], 2.5);
  EXPECT_TRUE(j["theta"]["theta_1"]["value"].is_null());
  EXPECT_FALSE(j["theta"]["theta_5"]["value"].is_null());
  EXPECT_FALSE(j["ode"]["from_theta"]["a2"]["value"].is_null());
  EXPECT_TRUE(j["ode"]["from_theta"]["a2"]["se"].is_number());
  EXPECT_TRUE(j["theta_regression"]["condition_number_identifiable_subspace"].is_number());
  EXPECT_EQ(j["theta_regression"]["not_identifiable_directions"].size(), 2u);
  EXPECT_TRUE(j.contains("quasi_steady_segments"));
  const auto out = config::WheelchairConfig::load(dir / "out.ini");
  EXPECT_NEAR(out.vehicle.yaw_inertia_kg_m2, 9.5, 0.5);
  EXPECT_NEAR(out.ini().read_double("identified", "a2", 0), j["ode"]["from_theta"]["a2"]["value"],
              1e-6);
  EXPECT_EQ(out.ini().read_double("identification", "cutoff_hz", 0), 2.0);  // input kept
}

TEST(CliIdentify, ExitCodes) {
  test::TempDir dir;
  EXPECT_EQ(test::run(cli() + " identify").exit_code, 2);
  EXPECT_EQ(test::run(cli() + " identify x.rawlog").exit_code, 2);  // --json missing
  EXPECT_EQ(
      test::run(cli() + " identify " + (dir / "missing.rawlog") + " --json " + (dir / "o.json"))
          .exit_code,
      1);
  {
    std::ofstream bad(dir / "bad.rawlog");
    bad << "not a rawlog";
  }
  EXPECT_EQ(test::run(cli() + " identify " + (dir / "bad.rawlog") + " --json " + (dir / "o.json"))
                .exit_code,
            1);
  EXPECT_EQ(test::run(cli() + " identify x.rawlog --json o.json --omega-source compass").exit_code,
            2);
}
