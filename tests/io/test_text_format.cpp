// Plain-text recording format: parsing, validation errors, streaming merge, round trips.
#include "../common/TestUtil.h"
#include "SyntheticRecording.h"

#include "libwheelchair/io/TextFormat.h"

#include <gtest/gtest.h>

using namespace wheelchair;
using wheelchair::test::TempDir;

namespace {

std::string writeDir(const TempDir& tmp, const io::Recording& rec, const std::string& name = "rec") {
  const std::string dir = tmp / name;
  io::writeTextRecording(rec, dir);
  return dir;
}

void expectThrowsWith(const std::function<void()>& f, const std::string& needle) {
  try {
    f();
    FAIL() << "expected an error containing '" << needle << "'";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

}  // namespace

TEST(TextFormat, WriteThenReadReproducesEveryValue) {
  TempDir tmp;
  const io::Recording rec = test::syntheticRecording(3.0, true, true);
  const std::string dir = writeDir(tmp, rec);
  std::vector<std::string> warnings;
  const io::Recording back = io::readTextRecording(dir, &warnings);
  ASSERT_EQ(back.encoders.size(), rec.encoders.size());
  ASSERT_EQ(back.imu.size(), rec.imu.size());
  ASSERT_EQ(back.motors.size(), rec.motors.size());
  ASSERT_EQ(back.sonar.size(), rec.sonar.size());
  ASSERT_EQ(back.pozyx.size(), rec.pozyx.size());
  ASSERT_EQ(back.joystick.size(), rec.joystick.size());
  for (size_t i = 0; i < rec.encoders.size(); ++i) {
    EXPECT_EQ(back.encoders[i].right_ticks, rec.encoders[i].right_ticks);
    EXPECT_EQ(back.encoders[i].left_ticks, rec.encoders[i].left_ticks);
    EXPECT_NEAR(back.encoders[i].t_s, rec.encoders[i].t_s, 1e-6);
  }
  for (size_t i = 0; i < rec.imu.size(); ++i) {
    EXPECT_EQ(back.imu[i].gyro_z_rad_s, rec.imu[i].gyro_z_rad_s);  // shortest repr round-trips
    EXPECT_TRUE(back.imu[i].has_extra);
    EXPECT_EQ(back.imu[i].extra, rec.imu[i].extra);
  }
  for (size_t i = 0; i < rec.pozyx.size(); ++i) {
    EXPECT_TRUE(back.pozyx[i].has_z);
    EXPECT_EQ(back.pozyx[i].z_m, rec.pozyx[i].z_m);
  }
  EXPECT_EQ(back.meta, rec.meta);
  EXPECT_TRUE(warnings.empty());
}

TEST(TextFormat, StreamingMergeIsTimeOrderedAndKeepsFileOrder) {
  TempDir tmp;
  const std::string dir = writeDir(tmp, test::syntheticRecording(2.0));
  io::TextRecordingReader in(dir);
  io::AnySample s;
  double last = -1;
  size_t n = 0;
  while (in.next(s)) {
    EXPECT_GE(io::timeOf(s), last);
    last = io::timeOf(s);
    ++n;
  }
  EXPECT_EQ(n, io::readTextRecording(dir).size());
}

TEST(TextFormat, MalformedRowNamesFileAndLine) {
  TempDir tmp;
  const std::string dir = writeDir(tmp, test::syntheticRecording(1.0));
  std::string imu = test::readFile(dir + "/imu.csv");
  // Corrupt the 5th data row (line 6 of the file).
  size_t pos = 0;
  for (int i = 0; i < 5; ++i) pos = imu.find('\n', pos) + 1;
  imu.insert(pos, "1600000000.5,abc,1,2,3,4,5\n");
  test::writeFile(dir + "/imu.csv", imu);
  expectThrowsWith([&] { io::readTextRecording(dir); }, "imu.csv:6: column 'gyro_z': 'abc'");
}

TEST(TextFormat, NanAndInfAreRejected) {
  for (const std::string bad : {"nan", "inf", "-inf", "NaN"}) {
    TempDir tmp;
    const std::string dir = writeDir(tmp, test::syntheticRecording(1.0, false));
    test::writeFile(dir + "/sonar.csv", "t,range\n1.0,2.5\n1.1," + bad + "\n");
    expectThrowsWith([&] { io::readTextRecording(dir); }, "sonar.csv:3");
  }
}

TEST(TextFormat, WrongFieldCountAndHeader) {
  TempDir tmp;
  const std::string dir = writeDir(tmp, test::syntheticRecording(1.0, false));
  test::writeFile(dir + "/joystick.csv", "t,v_cmd,w_cmd\n1.0,0.5\n");
  expectThrowsWith([&] { io::readTextRecording(dir); }, "joystick.csv:2: 2 fields, expected 3");
  test::writeFile(dir + "/joystick.csv", "t,v,w\n1.0,0.5,0\n");
  expectThrowsWith([&] { io::readTextRecording(dir); }, "joystick.csv:1: header 't,v,w'");
}

TEST(TextFormat, EncoderTicksMustBeInt32) {
  TempDir tmp;
  const std::string dir = writeDir(tmp, test::syntheticRecording(1.0, false));
  test::writeFile(dir + "/encoders.csv", "t,right_ticks,left_ticks\n1.0,1.5,2\n");
  expectThrowsWith([&] { io::readTextRecording(dir); }, "not a 32-bit integer");
  test::writeFile(dir + "/encoders.csv", "t,right_ticks,left_ticks\n1.0,2147483648,2\n");
  expectThrowsWith([&] { io::readTextRecording(dir); }, "encoders.csv:2");
}

TEST(TextFormat, MissingRequiredFileIsAnErrorMissingOptionalIsAWarning) {
  TempDir tmp;
  const std::string dir = writeDir(tmp, test::syntheticRecording(1.0, false));
  std::filesystem::remove(dir + "/pozyx.csv");
  std::vector<std::string> w;
  const auto rec = io::readTextRecording(dir, &w);
  EXPECT_TRUE(rec.pozyx.empty());
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].find("pozyx.csv"), std::string::npos);
  std::filesystem::remove(dir + "/motors.csv");
  expectThrowsWith([&] { io::readTextRecording(dir); }, "motors.csv: required file is missing");
}

TEST(TextFormat, EmptyFileIsAnError) {
  TempDir tmp;
  const std::string dir = writeDir(tmp, test::syntheticRecording(1.0, false));
  test::writeFile(dir + "/encoders.csv", "");
  expectThrowsWith([&] { io::readTextRecording(dir); }, "encoders.csv: empty file");
}

TEST(TextFormat, NonMonotonicAndDuplicateTimestampsAreKeptAndReported) {
  TempDir tmp;
  const std::string dir = writeDir(tmp, test::syntheticRecording(1.0, false));
  test::writeFile(dir + "/sonar.csv", "t,range\n1.0,2.5\n1.2,2.4\n1.1,2.3\n1.1,2.2\n");
  std::vector<std::string> w;
  const auto rec = io::readTextRecording(dir, &w);
  ASSERT_EQ(rec.sonar.size(), 4u);  // nothing dropped, file order kept
  EXPECT_EQ(rec.sonar[2].range_m, 2.3);
  EXPECT_EQ(rec.sonar[3].range_m, 2.2);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].find("1 out-of-order and 1 duplicated"), std::string::npos) << w[0];
  EXPECT_NE(w[0].find("line 4"), std::string::npos) << w[0];
}

TEST(TextFormat, FailedExportLeavesNoDirectory) {
  TempDir tmp;
  const std::string dir = tmp / "out";
  {
    io::TextRecordingWriter w(dir);
    w.write(io::EncoderSample{1.0, 1, 2});
    // destroyed without commit (as when an exception unwinds)
  }
  EXPECT_FALSE(std::filesystem::exists(dir));
  EXPECT_FALSE(std::filesystem::exists(dir + ".tmp-export"));
}
