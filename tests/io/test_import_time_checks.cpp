// `wheelchair import` refuses timestamps that would turn into nonsense downstream: negative
// ones (MRPT's clock would wrap them to ~1.8e12 s), non-finite ones, and forward jumps of the
// timeline over [import] max_gap_s (a clock step or a stalled logger: the filter would coast
// through it). And the rawlog keeps UNIX-time stamps to MRPT's 100 ns resolution.
#include "../common/TestUtil.h"
#include "SyntheticRecording.h"

#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/TextFormat.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

using namespace wheelchair;
using test::cli;
using test::TempDir;

namespace {

/// A synthetic recording (starts at 1600000000.25 s, 2 s long) whose imu.csv row `row`
/// (1-based data row, file line row + 1) gets time `t` (as text).
std::string withImuTime(const TempDir& tmp, int row, const std::string& t) {
  const std::string dir = tmp / "src";
  io::writeTextRecording(test::syntheticRecording(2.0), dir);
  std::string imu = test::readFile(dir + "/imu.csv");
  std::size_t p = 0;
  for (int line = 0; line < row; ++line) p = imu.find('\n', p) + 1;
  imu.replace(p, imu.find(',', p) - p, t);
  test::writeFile(dir + "/imu.csv", imu);
  return dir;
}

/// The synthetic recording with every stream's rows after t0 + 1 s moved forward by jump_s.
std::string withJump(const TempDir& tmp, double jump_s) {
  auto rec = test::syntheticRecording(2.0);
  const double t_jump = rec.encoders.front().t_s + 1.0;
  auto shift = [&](auto& v) {
    for (auto& s : v)
      if (s.t_s >= t_jump) s.t_s += jump_s;
  };
  shift(rec.encoders), shift(rec.imu), shift(rec.motors), shift(rec.sonar), shift(rec.pozyx),
      shift(rec.joystick);
  const std::string dir = tmp / "jump";
  io::writeTextRecording(rec, dir);
  return dir;
}

}  // namespace

TEST(ImportTimeChecks, NegativeTimestampIsRefusedWithFileLineColumnAndValue) {
  TempDir tmp;
  const std::string dir = withImuTime(tmp, 5, "-0.25");
  const auto r = cli("import " + dir + " -o " + (tmp / "r.rawlog"));
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("imu.csv:6: column 't': negative timestamp -0.25"), std::string::npos)
      << r.out;
  EXPECT_FALSE(std::filesystem::exists(tmp / "r.rawlog"));
}

TEST(ImportTimeChecks, NonFiniteTimestampIsRefused) {
  for (const std::string bad : {"nan", "inf", "-inf"}) {
    TempDir tmp;
    const std::string dir = withImuTime(tmp, 3, bad);
    const auto r = cli("import " + dir + " -o " + (tmp / "r.rawlog"));
    EXPECT_EQ(r.exit_code, 1) << r.out;
    EXPECT_NE(r.out.find("imu.csv:4: column 't': value " + bad + " is not finite"),
              std::string::npos)
        << r.out;
    EXPECT_FALSE(std::filesystem::exists(tmp / "r.rawlog"));
  }
}

TEST(ImportTimeChecks, ForwardJumpOverTheLimitIsRefusedNamingFileLineAndSize) {
  TempDir tmp;
  const std::string dir = withJump(tmp, 7.0);  // default limit 5 s
  const std::string out = tmp / "r.rawlog";
  auto r = cli("import " + dir + " -o " + out);
  EXPECT_EQ(r.exit_code, 1) << r.out;
  // The first row after the jump is the encoders' (t0 + 1.00 s, row 51: line 52).
  EXPECT_NE(r.out.find("encoders.csv:52: timestamp 1600000008.25 s jumps 7.005 s"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("max_gap_s = 5 s"), std::string::npos) << r.out;
  EXPECT_FALSE(std::filesystem::exists(out));

  // Raised on the command line or in the configuration's [import] section: imported whole.
  r = cli("import " + dir + " -o " + out + " --max-gap 10");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto rec = io::readRawlog(out);
  EXPECT_EQ(rec.encoders.size(), test::syntheticRecording(2.0).encoders.size());
  EXPECT_NEAR(rec.endTime() - rec.startTime(), 9.0, 0.1);
  std::filesystem::remove(out);
  // The template's [import] max_gap_s with another value (a key given twice is an error).
  const std::string ini = test::readFile(test::sourcePath("config/wheelchair.ini"));
  const auto withGap = [&](const std::string& v) {
    const std::string key = "\nmax_gap_s = 5\n";
    const auto at = ini.find(key);
    EXPECT_NE(at, std::string::npos) << "config/wheelchair.ini has no max_gap_s = 5";
    return at == std::string::npos ? ini
                                   : ini.substr(0, at) + "\nmax_gap_s = " + v + "\n" +
                                         ini.substr(at + key.size());
  };
  test::writeFile(tmp / "cfg.ini", withGap("8"));
  r = cli("import " + dir + " -o " + out + " --config " + (tmp / "cfg.ini"));
  EXPECT_EQ(r.exit_code, 0) << r.out;
  test::writeFile(tmp / "cfg.ini", withGap("6"));
  r = cli("import " + dir + " -o " + (tmp / "s.rawlog") + " --config " + (tmp / "cfg.ini"));
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("max_gap_s = 6 s"), std::string::npos) << r.out;
  // 0 switches the check off; a jump under the limit is not reported at all.
  EXPECT_EQ(cli("import " + dir + " -o " + (tmp / "t.rawlog") + " --max-gap 0").exit_code, 0);
  const auto small = cli("import " + withJump(tmp, 4.0) + " -o " + (tmp / "u.rawlog"));
  EXPECT_EQ(small.exit_code, 0) << small.out;
  EXPECT_EQ(small.out.find("jumps"), std::string::npos) << small.out;
  EXPECT_EQ(cli("import " + dir + " -o " + (tmp / "v.rawlog") + " --max-gap -1").exit_code, 2);
}

TEST(ImportTimeChecks, RawlogKeepsUnixTimeToTheMrptTickAndRefusesNegativeTimes) {
  const config::WheelchairConfig cfg;
  for (const double t : {1700000000.123456, 1799999999.999999, 0.0, 12.5e-6}) {
    const auto obs = io::toObservation(io::ImuSample{t, 0.25, false, {}}, cfg);
    const auto back = io::fromObservation(*obs);
    ASSERT_TRUE(back.has_value());
    // MRPT ticks are 100 ns; a double holds 1.7e9 s to 2.4e-7 s.
    EXPECT_NEAR(io::timeOf(*back), t, 2.5e-7) << fmt::format("{:.7f}", t);
  }
  for (const double t : {-1e-3, -1700000000.0, std::nan(""), HUGE_VAL}) {
    EXPECT_THROW(io::toObservation(io::ImuSample{t, 0.25, false, {}}, cfg), std::invalid_argument)
        << t;
  }
}
