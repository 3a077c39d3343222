// `wheelchair simulate`: outputs, truth file, summary, exit codes.
#include "../common/TestUtil.h"

#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/TextFormat.h"
#include "libwheelchair/simulation/Simulator.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

using namespace wheelchair;
namespace wt = wheelchair::test;

TEST(CliSimulate, CsvDirectoryAndTruth) {
  wt::TempDir tmp;
  const std::string out = tmp / "obst";
  const auto r = wt::cli("simulate --scenario obstacles --seed 3 --format csv -o " + out +
                         " --effect gyro_bias:bias_rad_s=0.01 sonar_dropout:probability=0.2");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("collisions:"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("gyro_bias:bias_rad_s=0.01"), std::string::npos) << r.out;
  EXPECT_TRUE(std::filesystem::exists(out + "/encoders.csv"));
  EXPECT_TRUE(std::filesystem::exists(out + "/sonar.csv"));
  const auto truth = simulation::readTruth(out + ".truth.json");
  EXPECT_EQ(truth.scenario, "obstacles");
  EXPECT_EQ(truth.effects.size(), 2u);
  EXPECT_GT(truth.collisions, 0);
  const auto rec = io::readTextRecording(out);
  EXPECT_NEAR(rec.imu.size(), 1000, 2);
}

TEST(CliSimulate, RawlogWithSupervisoryControl) {
  wt::TempDir tmp;
  const std::string out = tmp / "sim.rawlog";
  const auto r = wt::cli("simulate --scenario obstacles --seed 1 --supervisory on -o " + out +
                         " --truth " + (tmp / "t.json"));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("collisions: 0"), std::string::npos) << r.out;
  const auto rec = io::readRawlog(out);
  EXPECT_NEAR(rec.encoders.size(), 500, 2);
  EXPECT_EQ(simulation::readTruth(tmp / "t.json").collisions, 0);
}

TEST(CliSimulate, AFailedTruthFileLeavesNoRecordingBehind) {
  wt::TempDir tmp;
  for (const std::string format : {"rawlog", "csv"}) {
    const std::string out = tmp / ("sim_" + format);
    const auto r = wt::cli("simulate --scenario obstacles --seed 1 --format " + format + " -o " +
                           out + " --truth " + (tmp.path() / "missing_dir" / "t.json").string());
    EXPECT_EQ(r.exit_code, 1) << r.out;
    EXPECT_NE(r.out.find("t.json"), std::string::npos) << r.out;
    EXPECT_FALSE(std::filesystem::exists(out)) << format;
  }
  EXPECT_TRUE(std::filesystem::is_empty(tmp.path()));
}

TEST(CliSimulate, UsageErrors) {
  wt::TempDir tmp;
  EXPECT_EQ(wt::cli("simulate --scenario moonwalk -o " + (tmp / "x")).exit_code, 2);
  EXPECT_EQ(wt::cli("simulate --scenario excite --effect warp:x=1 -o " + (tmp / "x")).exit_code, 2);
  EXPECT_EQ(wt::cli("simulate --scenario excite --format xml -o " + (tmp / "x")).exit_code, 2);
  const auto l = wt::cli("simulate --list");
  EXPECT_EQ(l.exit_code, 0);
  EXPECT_NE(l.out.find("motor_asymmetry"), std::string::npos);
}

TEST(CliSimulate, MujocoEngine) {
  wt::TempDir tmp;
  const std::string out = tmp / "mj.rawlog";
  const auto r =
      wt::cli("simulate --engine mujoco --scenario three_task --seed 2 --duration 8 -o " + out +
              " --effect tyre_scrub:torsion_m=0.01 gyro_bias:bias_rad_s=0.01");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("engine mujoco"), std::string::npos) << r.out;
  const auto rec = io::readRawlog(out);
  EXPECT_NEAR(rec.encoders.size(), 400, 2);
  EXPECT_GT(rec.encoders.back().right_ticks, 1000);  // it drove
  const auto truth = simulation::readTruth(out + ".truth.json");
  EXPECT_EQ(truth.engine, "mujoco");
  EXPECT_EQ(truth.effects.size(), 2u);
  EXPECT_NE(truth.config_text.find("[vehicle]"), std::string::npos);
  // Engine-only effects are refused by the model engine; unknown engines are usage errors;
  // a bad [mujoco] value is bad input naming the key.
  const auto m =
      wt::cli("simulate --scenario excite --effect tyre_scrub:torsion_m=0.01 -o " + (tmp / "x"));
  EXPECT_EQ(m.exit_code, 2);
  EXPECT_NE(m.out.find("only with --engine mujoco"), std::string::npos) << m.out;
  EXPECT_EQ(wt::cli("simulate --engine bullet --scenario excite -o " + (tmp / "x")).exit_code, 2);
  const std::string ini = tmp / "bad.ini";
  {
    std::ofstream f(ini);
    f << "[mujoco]\ntimestep_s = fast\n";
  }
  const auto b = wt::cli("simulate --engine mujoco --config " + ini +
                         " --scenario excite --duration 1 -o " + (tmp / "y"));
  EXPECT_EQ(b.exit_code, 1) << b.out;
  EXPECT_NE(b.out.find("timestep_s"), std::string::npos) << b.out;
  EXPECT_FALSE(std::filesystem::exists(tmp / "y"));
  {
    std::ofstream f(ini);
    f << "[mujoco]\ntimestep = 0.001\n";
  }
  const auto u = wt::cli("simulate --engine mujoco --config " + ini +
                         " --scenario excite --duration 1 -o " + (tmp / "y"));
  EXPECT_EQ(u.exit_code, 1) << u.out;
  EXPECT_NE(u.out.find("[mujoco] timestep: unknown key"), std::string::npos) << u.out;
}
