// Rawlog I/O: standard MRPT classes, round trip through the rawlog, truncated/corrupt files.
#include "../common/TestUtil.h"
#include "SyntheticRecording.h"

#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/TextFormat.h"

#include <gtest/gtest.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CObservationRange.h>
#include <mrpt/obs/CObservationRawDAQ.h>
#include <mrpt/obs/CObservationRobotPose.h>

using namespace wheelchair;
using wheelchair::test::TempDir;

TEST(Rawlog, StreamsUseStandardMrptClassesWithLabels) {
  TempDir tmp;
  const config::WheelchairConfig cfg;
  const auto rec = test::syntheticRecording(1.0);
  const std::string path = tmp / "r.rawlog";
  io::writeRawlog(rec, path, cfg);
  io::RawlogReader in(path);
  mrpt::serialization::CSerializable::Ptr obj;
  std::map<std::string, std::string> classOf;
  while (in.next(obj)) {
    auto o = std::dynamic_pointer_cast<mrpt::obs::CObservation>(obj);
    ASSERT_TRUE(o);
    classOf[io::headerText(*o) ? "META" : o->sensorLabel] = o->GetRuntimeClass()->className;
    if (auto r = std::dynamic_pointer_cast<mrpt::obs::CObservationRange>(o)) {
      EXPECT_NEAR(r->sensedData.at(0).sensorPose.x, cfg.sonar.x_m, 1e-9);
      EXPECT_NEAR(r->maxSensorDistance, cfg.sonar.max_range_m, 1e-6);
      EXPECT_NEAR(r->sensorConeApperture, 2 * cfg.sonar.cone_half_angle_deg * M_PI / 180, 1e-6);
    }
    if (auto d = std::dynamic_pointer_cast<mrpt::obs::CObservationOdometry>(o)) {
      EXPECT_TRUE(d->hasEncodersInfo);
    }
  }
  EXPECT_FALSE(in.error());
  EXPECT_EQ(classOf["ENCODERS"], "mrpt::obs::CObservationOdometry");
  EXPECT_EQ(classOf["IMU"], "mrpt::obs::CObservationIMU");
  EXPECT_EQ(classOf["MOTORS"], "mrpt::obs::CObservationRawDAQ");
  EXPECT_EQ(classOf["SONAR"], "mrpt::obs::CObservationRange");
  EXPECT_EQ(classOf["POZYX"], "mrpt::obs::CObservationRobotPose");
  EXPECT_EQ(classOf["JOYSTICK"], "mrpt::obs::CObservationRawDAQ");
  EXPECT_EQ(classOf["META"], "mrpt::obs::CObservationComment");
}

TEST(Rawlog, RoundTripKeepsEverySampleAndZeroSonar) {
  TempDir tmp;
  const auto rec = test::syntheticRecording(2.0, true, false);
  const std::string path = tmp / "r.rawlog";
  io::writeRawlog(rec, path, config::WheelchairConfig());
  const auto back = io::readRawlog(path);
  ASSERT_EQ(back.size(), rec.size());
  size_t zeros = 0;
  for (size_t i = 0; i < rec.sonar.size(); ++i) {
    EXPECT_FLOAT_EQ(back.sonar[i].range_m, rec.sonar[i].range_m);
    zeros += back.sonar[i].range_m == 0.0;
  }
  EXPECT_GT(zeros, 0u);
  for (size_t i = 0; i < rec.encoders.size(); ++i) {
    EXPECT_EQ(back.encoders[i].right_ticks, rec.encoders[i].right_ticks);
    EXPECT_NEAR(back.encoders[i].t_s, rec.encoders[i].t_s, 2e-7);  // MRPT clock: 100 ns ticks
  }
  for (size_t i = 0; i < rec.motors.size(); ++i)
    EXPECT_EQ(back.motors[i].vrc_right_V, rec.motors[i].vrc_right_V);
  EXPECT_FALSE(back.pozyx.at(0).has_z);
  EXPECT_EQ(back.meta, rec.meta);
}

TEST(Rawlog, TruncatedFileYieldsCompleteRecordsThenReportsTheBreak) {
  TempDir tmp;
  const auto rec = test::syntheticRecording(2.0);
  const std::string full = tmp / "full.rawlog";
  // Uncompressed so that cutting bytes cuts records, not the gzip trailer only.
  {
    io::RawlogWriter w(full, 0);
    const config::WheelchairConfig cfg;
    io::forEachInTimeOrder(rec, [&](const io::AnySample& s) { w.write(s, cfg); });
    w.commit();
  }
  std::string bytes = test::readFile(full);
  const std::string cut = tmp / "cut.rawlog";
  test::writeFile(cut, bytes.substr(0, bytes.size() * 2 / 3 + 7));
  io::RawlogReadReport rep;
  const auto part = io::readRawlog(cut, &rep, true);
  ASSERT_TRUE(rep.broken);
  EXPECT_GT(part.size(), rec.size() / 2);
  EXPECT_LT(part.size(), rec.size());
  EXPECT_EQ(rep.broken->record_index, part.size());
  EXPECT_THROW(io::readRawlog(cut), std::runtime_error);

}

TEST(Rawlog, UncommittedWriterLeavesNoFile) {
  TempDir tmp;
  const std::string path = tmp / "x.rawlog";
  {
    io::RawlogWriter w(path);
    w.write(io::AnySample(io::EncoderSample{1, 2, 3}), config::WheelchairConfig());
  }
  EXPECT_FALSE(std::filesystem::exists(path));
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
}
