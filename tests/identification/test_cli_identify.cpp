// `wheelchair identify` end to end, on recordings of the project's truth simulator
// (`wheelchair simulate`: power module, asynchronous jittered sensors, V_RC with the Zener
// knee): rawlog in, JSON and configuration out, exit codes. Needs the `wheelchair` program
// (target wheelchair_cli); skipped when it has not been built.
#include "../common/TestUtil.h"

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/identification/Identification.h"
#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/model/VehicleParams.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>

using namespace wheelchair;

namespace {

std::string cli() {
  return WHEELCHAIR_CLI;
}

#define REQUIRE_CLI()                  \
  if (!std::filesystem::exists(cli())) \
  GTEST_SKIP() << cli() << " not built (cmake --build <dir> --target wheelchair_cli)"

// Truth vehicle: differs from the nominal configuration the identification is given.
std::string writeTruthConfig(const test::TempDir& dir) {
  config::WheelchairConfig c;
  c.vehicle.yaw_inertia_kg_m2 = 9.5;
  c.vehicle.motor_viscous_Nm_s_rad = 2.8e-3;
  c.vehicle.gearbox_efficiency = 0.8;
  c.syncToIni();
  c.save(dir / "truth.ini");
  return dir / "truth.ini";
}

nlohmann::json readJson(const std::string& p) {
  std::ifstream f(p);
  return nlohmann::json::parse(f);
}

}  // namespace

TEST(CliIdentify, TruthSimulatorExciteRecoversParameters) {
  REQUIRE_CLI();
  test::TempDir dir;
  const std::string truth_ini = writeTruthConfig(dir);
  const auto truth = config::WheelchairConfig::load(truth_ini);
  const auto th = model::lumpedTheta(truth.vehicle);
  const auto a = model::odeCoefficients(truth.vehicle.geom, th);
  const std::string log = dir / "excite.rawlog";
  const auto sim =
      test::run(cli() + " simulate --scenario excite --seed 4 --duration 120 --config " +
                truth_ini + " -o " + log);
  ASSERT_EQ(sim.exit_code, 0) << sim.out;
  const std::string ini = std::string(WHEELCHAIR_SOURCE_DIR) + "/config/wheelchair.ini";
  const auto r =
      test::run(cli() + " identify " + log + " --config " + ini + " --cutoff-hz 2.5 --json " +
                (dir / "out.json") + " --write-config " + (dir / "out.ini"));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  std::printf("%s", r.out.c_str());
  const auto j = readJson(dir / "out.json");
  EXPECT_EQ(j["config"], ini);
  EXPECT_EQ(j["options"]["cutoff_hz"], 2.5);
  for (const char* t : {"theta_1", "theta_2", "theta_3", "theta_4"})
    EXPECT_TRUE(j["theta"][t]["value"].is_null()) << t;
  EXPECT_NEAR(j["theta"]["theta_5"]["value"].get<double>(), th(4), 0.03 * th(4));
  const double ta[4] = {a.a1, a.a2, a.a3, a.a4};
  const char* an[4] = {"a1", "a2", "a3", "a4"};
  for (int k = 0; k < 4; ++k) {
    const auto& e = j["ode"]["from_theta"][an[k]];
    ASSERT_FALSE(e["value"].is_null()) << an[k];
    EXPECT_NEAR(e["value"].get<double>(), ta[k], 0.03 * std::abs(ta[k])) << an[k];
    EXPECT_TRUE(e["se"].is_number());
    const auto& d = j["ode"]["direct"][an[k]];
    ASSERT_FALSE(d["value"].is_null()) << an[k];
    EXPECT_NEAR(d["value"].get<double>(), ta[k], 0.03 * std::abs(ta[k])) << an[k] << " direct";
  }
  EXPECT_TRUE(j["theta_regression"]["condition_number_identifiable_subspace"].is_number());
  EXPECT_EQ(j["theta_regression"]["not_identifiable_directions"].size(), 2u);
  EXPECT_TRUE(j.contains("quasi_steady_segments"));
  const auto out = config::WheelchairConfig::load(dir / "out.ini");
  EXPECT_NEAR(out.vehicle.yaw_inertia_kg_m2, 9.5, 0.05 * 9.5);
  EXPECT_NEAR(out.ini().read_double("identified", "a2", 0),
              j["ode"]["from_theta"]["a2"]["value"].get<double>(), 1e-6);
  EXPECT_EQ(out.ini().read_double("identification", "cutoff_hz", 0), 2.0);  // input kept
}

TEST(CliIdentify, TruthSimulatorMotorAsymmetry) {
  REQUIRE_CLI();
  test::TempDir dir;
  const std::string truth_ini = writeTruthConfig(dir);
  const std::string log = dir / "3t.rawlog";
  const auto sim =
      test::run(cli() + " simulate --scenario three_task --seed 2 --config " + truth_ini +
                " --effect motor_asymmetry:side=right,km_ratio=1.1 -o " + log);
  ASSERT_EQ(sim.exit_code, 0) << sim.out;
  const auto r = test::run(cli() + " identify " + log + " --json " + (dir / "o.json"));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto j = readJson(dir / "o.json");
  const auto& pm = j["per_motor"];
  ASSERT_FALSE(pm["right"]["back_emf_constant_Nm_A"]["value"].is_null()) << r.out;
  ASSERT_FALSE(pm["left"]["back_emf_constant_Nm_A"]["value"].is_null()) << r.out;
  const double kr = pm["right"]["back_emf_constant_Nm_A"]["value"];
  const double kl = pm["left"]["back_emf_constant_Nm_A"]["value"];
  std::printf(
      "truth simulator three_task, right k_m x1.1: back-EMF k right %.5f left %.5f ratio "
      "%.4f; k/eta ratio %.4f; %zu quasi-steady segments\n",
      kr, kl, kr / kl, pm["ratio_right_over_left"]["k_over_eta"].get<double>(),
      j["quasi_steady_segments"].size());
  EXPECT_NEAR(kr, 0.099, 0.02 * 0.09);
  EXPECT_NEAR(kl, 0.090, 0.02 * 0.09);
  EXPECT_NEAR(kr / kl, 1.1, 0.02);
}

TEST(CliIdentify, ExitCodes) {
  REQUIRE_CLI();
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
  EXPECT_FALSE(std::filesystem::exists(dir / "o.json"));
}
