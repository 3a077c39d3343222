// `wheelchair simulate`: outputs, truth file, summary, exit codes.
#include "../common/TestUtil.h"

#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/TextFormat.h"
#include "libwheelchair/simulation/Simulator.h"

#include <gtest/gtest.h>

#include <filesystem>

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

TEST(CliSimulate, UsageErrors) {
  wt::TempDir tmp;
  EXPECT_EQ(wt::cli("simulate --scenario moonwalk -o " + (tmp / "x")).exit_code, 2);
  EXPECT_EQ(wt::cli("simulate --scenario excite --effect warp:x=1 -o " + (tmp / "x")).exit_code, 2);
  EXPECT_EQ(wt::cli("simulate --scenario excite --format xml -o " + (tmp / "x")).exit_code, 2);
  const auto l = wt::cli("simulate --list");
  EXPECT_EQ(l.exit_code, 0);
  EXPECT_NE(l.out.find("motor_asymmetry"), std::string::npos);
}
