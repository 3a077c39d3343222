// The `wheelchair import/export/info` commands end to end, and MRPT's own rawlog-edit
// reading our files.
#include "../common/TestUtil.h"
#include "SyntheticRecording.h"

#include "libwheelchair/io/TextFormat.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <random>
#include <regex>
#include <sys/resource.h>

using namespace wheelchair;
using wheelchair::test::cli;
using wheelchair::test::readFile;
using wheelchair::test::TempDir;

TEST(CliIo, ImportThenExportReproducesEveryRow) {
  TempDir tmp;
  const std::string src = tmp / "src";
  io::writeTextRecording(test::syntheticRecording(3.0, true, true), src);
  auto r = cli("import " + src + " -o " + (tmp / "r.rawlog"));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  r = cli("export " + (tmp / "r.rawlog") + " -o " + (tmp / "back"));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  for (const char* f : {"encoders.csv", "imu.csv", "motors.csv", "sonar.csv", "pozyx.csv",
                        "joystick.csv", "meta.ini"}) {
    EXPECT_EQ(readFile(src + "/" + f), readFile((tmp / "back/") + f)) << f;
  }
}

TEST(CliIo, RawlogEditReadsEveryStreamWithTheRightCount) {
  if (test::run("command -v rawlog-edit").exit_code != 0) GTEST_SKIP() << "mrpt-apps missing";
  TempDir tmp;
  const auto rec = test::syntheticRecording(2.0);
  const std::string src = tmp / "src";
  io::writeTextRecording(rec, src);
  ASSERT_EQ(cli("import " + src + " -o " + (tmp / "r.rawlog")).exit_code, 0);
  const auto info = test::run("rawlog-edit --info -i " + (tmp / "r.rawlog"));
  ASSERT_EQ(info.exit_code, 0) << info.out;
  const auto list = test::run("cd " + tmp.path().string() + " && rawlog-edit --list-timestamps -i " +
                              (tmp / "r.rawlog") + " --text-file-output " + (tmp / "ts.txt"));
  ASSERT_EQ(list.exit_code, 0) << list.out;
  // One line per observation: "timestamp label class".
  std::map<std::string, size_t> counts;
  std::istringstream ss(readFile(tmp / "ts.txt"));
  std::string line;
  while (std::getline(ss, line)) {
    std::istringstream ls(line);
    std::string ts, label, cls;
    if (ls >> ts >> label >> cls && line[0] != '%') ++counts[label];
  }
  EXPECT_EQ(counts["ENCODERS"], rec.encoders.size());
  EXPECT_EQ(counts["IMU"], rec.imu.size());
  EXPECT_EQ(counts["MOTORS"], rec.motors.size());
  EXPECT_EQ(counts["SONAR"], rec.sonar.size());
  EXPECT_EQ(counts["POZYX"], rec.pozyx.size());
  EXPECT_EQ(counts["JOYSTICK"], rec.joystick.size());
  // --info lists each sensor label too.
  for (const char* label : {"ENCODERS", "IMU", "MOTORS", "SONAR", "POZYX", "JOYSTICK"})
    EXPECT_NE(info.out.find(label), std::string::npos) << info.out;
}

TEST(CliIo, InfoReportsPerStreamStatistics) {
  TempDir tmp;
  const auto rec = test::syntheticRecording(2.0);
  io::writeTextRecording(rec, tmp / "src");
  ASSERT_EQ(cli("import " + (tmp / "src") + " -o " + (tmp / "r.rawlog")).exit_code, 0);
  const auto r = cli("info --json " + (tmp / "r.rawlog"));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto j = nlohmann::json::parse(r.out);
  std::map<std::string, nlohmann::json> by_label;
  for (const auto& s : j["streams"]) by_label[s["label"]] = s;
  EXPECT_EQ(by_label["IMU"]["count"], rec.imu.size());
  EXPECT_NEAR(by_label["IMU"]["mean_rate_hz"].get<double>(), 100.0, 0.5);
  EXPECT_NEAR(by_label["ENCODERS"]["mean_rate_hz"].get<double>(), 50.0, 0.5);
  EXPECT_NEAR(by_label["SONAR"]["largest_gap_s"].get<double>(), 0.1, 1e-3);
  EXPECT_EQ(by_label["IMU"]["class"], "mrpt::obs::CObservationIMU");
  EXPECT_NEAR(j["duration_s"].get<double>(), 2.0, 0.1);
  const auto text = cli("info " + (tmp / "r.rawlog"));
  EXPECT_EQ(text.exit_code, 0);
  EXPECT_NE(text.out.find("CObservationRange"), std::string::npos);
}

TEST(CliIo, OutOfOrderTimestampsAreCountedByInfo) {
  TempDir tmp;
  io::writeTextRecording(test::syntheticRecording(1.0), tmp / "src");
  // On the recording's clock (syntheticRecording starts at 1600000000.25 s).
  test::writeFile(tmp / "src/sonar.csv",
                  "t,range\n1600000000.5,2.5\n1600000000.7,2.4\n1600000000.6,2.3\n"
                  "1600000000.6,2.2\n");
  auto r = cli("import " + (tmp / "src") + " -o " + (tmp / "r.rawlog"));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("warning"), std::string::npos);
  r = cli("info --json " + (tmp / "r.rawlog"));
  const auto j = nlohmann::json::parse(r.out);
  for (const auto& s : j["streams"]) {
    if (s["label"] == "SONAR") {
      EXPECT_EQ(s["count"], 4);
      EXPECT_EQ(s["out_of_order"], 1);
      EXPECT_EQ(s["duplicate_timestamps"], 1);
    }
  }
  r = cli("import --strict " + (tmp / "src") + " -o " + (tmp / "s.rawlog"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_FALSE(std::filesystem::exists(tmp / "s.rawlog"));
}

TEST(CliIo, BadInputExitsOneAndLeavesNoOutput) {
  TempDir tmp;
  io::writeTextRecording(test::syntheticRecording(1.0), tmp / "src");
  test::writeFile(tmp / "src/motors.csv",
                  "t,current_right,current_left,vrc_right,vrc_left\n1,2,3,4,5\n1.01,2,3,inf,5\n");
  const std::string out = tmp / "r.rawlog";
  auto r = cli("import " + (tmp / "src") + " -o " + out);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("motors.csv:3"), std::string::npos) << r.out;
  EXPECT_FALSE(std::filesystem::exists(out));
  EXPECT_FALSE(std::filesystem::exists(out + ".tmp"));
  r = cli("import " + (tmp / "nonexistent") + " -o " + out);
  EXPECT_EQ(r.exit_code, 1);
  r = cli("info " + (tmp / "nonexistent.rawlog"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("nonexistent.rawlog"), std::string::npos);
}

TEST(CliIo, UsageErrorsExitTwo) {
  EXPECT_EQ(cli("import").exit_code, 2);
  EXPECT_EQ(cli("no-such-command").exit_code, 2);
  EXPECT_EQ(cli("info --no-such-flag x").exit_code, 2);
  const auto h = cli("import --help");
  EXPECT_EQ(h.exit_code, 0);
  EXPECT_NE(h.out.find("--output"), std::string::npos);
}

TEST(CliIo, InfoOnTruncatedRawlogReportsWhereItBroke) {
  TempDir tmp;
  io::writeTextRecording(test::syntheticRecording(2.0), tmp / "src");
  ASSERT_EQ(cli("import " + (tmp / "src") + " -o " + (tmp / "r.rawlog")).exit_code, 0);
  const std::string bytes = readFile(tmp / "r.rawlog");
  test::writeFile(tmp / "cut.rawlog", bytes.substr(0, bytes.size() / 2));
  const auto r = cli("info " + (tmp / "cut.rawlog"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("cut.rawlog: record"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("complete records"), std::string::npos) << r.out;
}

// Garbage in the middle of an (uncompressed) rawlog: the records before it are reported,
// the program neither crashes nor exhausts memory on nonsense lengths.
TEST(CliIo, CorruptRawlogIsReportedNotCrashedOn) {
  TempDir tmp;
  io::writeTextRecording(test::syntheticRecording(2.0), tmp / "src");
  ASSERT_EQ(cli("import " + (tmp / "src") + " -o " + (tmp / "r.rawlog.gz")).exit_code, 0);
  // Decompress so that the corruption hits record bytes rather than the gzip framing.
  ASSERT_EQ(test::run("gzip -dc < " + (tmp / "r.rawlog.gz") + " > " + (tmp / "plain.rawlog"))
                .exit_code,
            0);
  std::string bytes = readFile(tmp / "plain.rawlog");
  for (int trial = 0; trial < 6; ++trial) {
    std::string bad = bytes;
    std::mt19937 rng(trial);
    const size_t at = bad.size() / 4 + rng() % (bad.size() / 2);
    for (size_t i = at; i < at + 16 && i < bad.size(); ++i) bad[i] = static_cast<char>(rng());
    test::writeFile(tmp / "bad.rawlog", bad);
    const auto r = cli("info --json " + (tmp / "bad.rawlog"));
    // Either the corruption happened to be harmless (e.g. inside a double) or it is reported.
    EXPECT_TRUE(r.exit_code == 0 || r.exit_code == 1) << r.exit_code << r.out;
    if (r.exit_code == 1) EXPECT_NE(r.out.find("bad.rawlog: record"), std::string::npos) << r.out;
  }
}

// Memory stays flat with input size: import streams rows straight to the rawlog.
TEST(CliIo, ImportMemoryDoesNotGrowWithInputSize) {
  TempDir tmp;
  auto peakKbOfImport = [&](int imu_rows, const std::string& name) {
    const std::string dir = tmp / name;
    io::writeTextRecording(test::syntheticRecording(0.5, false), dir);
    {
      std::ofstream imu(dir + "/imu.csv", std::ios::trunc);
      imu << "t,gyro_z\n";
      for (int k = 0; k < imu_rows; ++k) imu << 1600000000.25 + 1e-3 * k << "," << 1e-4 * (k % 977) << "\n";
    }
    const auto r = test::run("/usr/bin/time -f 'MAXRSS %M' " + std::string(WHEELCHAIR_CLI) +
                             " import " + dir + " -o " + dir + ".rawlog");
    EXPECT_EQ(r.exit_code, 0) << r.out;
    std::smatch m;
    std::regex re("MAXRSS (\\d+)");
    EXPECT_TRUE(std::regex_search(r.out, m, re)) << r.out;
    return std::stol(m[1]);
  };
  if (test::run("test -x /usr/bin/time").exit_code != 0) GTEST_SKIP() << "/usr/bin/time missing";
  const long small_kb = peakKbOfImport(1000, "small");
  const long large_kb = peakKbOfImport(600000, "large");  // ~17 MB of CSV
  EXPECT_LT(large_kb - small_kb, 8 * 1024) << small_kb << " kB vs " << large_kb << " kB";
}
