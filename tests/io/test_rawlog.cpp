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

namespace {
/// A sample's stream and every field as numbers (to compare two decodings exactly).
std::vector<double> fieldsOf(const std::optional<io::AnySample>& s) {
  if (!s) return {-1};
  std::vector<double> v{static_cast<double>(s->index())};
  std::visit(
      [&](const auto& x) {
        using T = std::decay_t<decltype(x)>;
        v.push_back(x.t_s);
        if constexpr (std::is_same_v<T, io::EncoderSample>) {
          v.insert(v.end(), {double(x.right_ticks), double(x.left_ticks)});
        } else if constexpr (std::is_same_v<T, io::ImuSample>) {
          v.insert(v.end(), {x.gyro_z_rad_s, double(x.has_extra)});
          v.insert(v.end(), x.extra.begin(), x.extra.end());
        } else if constexpr (std::is_same_v<T, io::MotorSample>) {
          v.insert(v.end(), {x.current_right_A, x.current_left_A, x.vrc_right_V, x.vrc_left_V});
        } else if constexpr (std::is_same_v<T, io::JoystickSample>) {
          v.insert(v.end(), {x.v_cmd_m_s, x.omega_cmd_rad_s});
        }  // sonar, Pozyx, ...: always decoded through MRPT (time compared)
      },
      *s);
  return v;
}

std::optional<io::AnySample> viaMrpt(const mrpt::serialization::CSerializable::Ptr& obj) {
  auto o = std::dynamic_pointer_cast<mrpt::obs::CObservation>(obj);
  return o ? io::fromObservation(*o) : std::nullopt;
}

/// Reads `path` record by record as MRPT decodes it (next + fromObservation) and as
/// nextSample does, expecting the same samples and the same end or break; returns how many
/// records nextSample decoded in place.
std::size_t expectSameDecoding(const std::string& path) {
  io::RawlogReader mrpt_in(path), fast_in(path);
  mrpt::serialization::CSerializable::Ptr mrpt_obj, fast_obj;
  io::AnySample s;
  std::size_t in_place = 0;
  for (std::size_t record = 0;; ++record) {
    const bool more = mrpt_in.next(mrpt_obj);
    const auto got = fast_in.nextSample(s, fast_obj);
    EXPECT_EQ(more, got != io::RawlogReader::Got::End) << "record " << record;
    if (!more || got == io::RawlogReader::Got::End) break;
    in_place += got == io::RawlogReader::Got::Sample;
    const auto fast =
        got == io::RawlogReader::Got::Sample ? std::optional<io::AnySample>(s) : viaMrpt(fast_obj);
    EXPECT_EQ(fieldsOf(fast), fieldsOf(viaMrpt(mrpt_obj))) << "record " << record;
  }
  EXPECT_EQ(mrpt_in.recordsRead(), fast_in.recordsRead());
  EXPECT_EQ(mrpt_in.error().has_value(), fast_in.error().has_value());
  if (mrpt_in.error() && fast_in.error()) {
    EXPECT_EQ(mrpt_in.error()->record_index, fast_in.error()->record_index);
    EXPECT_EQ(mrpt_in.error()->byte_offset, fast_in.error()->byte_offset);
    EXPECT_EQ(mrpt_in.error()->what, fast_in.error()->what);
  }
  return in_place;
}
}  // namespace

// RawlogReader::nextSample decodes encoder, IMU, motor and joystick records straight from the
// bytes: the samples must be MRPT's, bit for bit, for every layout (IMU with and without the
// extra channels, wrapping encoder counters), records that only look alike (other labels,
// odometry with velocities, a DAQ of another width) must still go through MRPT, and damage
// must be reported as next() reports it.
TEST(Rawlog, InPlaceDecodingGivesMrptsSamples) {
  TempDir tmp;
  const config::WheelchairConfig cfg;
  for (const bool extra : {true, false}) {
    const auto rec = test::syntheticRecording(3.0, extra);
    const std::string path = tmp / "r.rawlog";
    {
      io::RawlogWriter w(path);
      w.writeHeader(rec.meta, cfg, rec.startTime());
      io::forEachInTimeOrder(rec, [&](const io::AnySample& s) { w.write(s, cfg); });
      auto odo = mrpt::obs::CObservationOdometry::Create();  // with velocities: via MRPT
      odo->sensorLabel = "ENCODERS";
      odo->hasEncodersInfo = true;
      odo->encoderLeftTicks = 5;
      odo->encoderRightTicks = -7;
      odo->hasVelocities = true;
      w.write(*odo);
      auto imu = mrpt::obs::CObservationIMU::Create();  // not our label: ignored
      imu->sensorLabel = "IMU2";
      imu->set(mrpt::obs::IMU_WZ, 0.5);
      w.write(*imu);
      auto daq = mrpt::obs::CObservationRawDAQ::Create();  // 3 channels: ignored
      daq->sensorLabel = "MOTORS";
      daq->AIN_double = {1, 2, 3};
      w.write(*daq);
      w.write(io::EncoderSample{rec.endTime() + 1, -3, 9}, cfg);
      w.commit();
    }
    const std::size_t bulk =
        rec.encoders.size() + rec.imu.size() + rec.motors.size() + rec.joystick.size() + 1;
    EXPECT_EQ(expectSameDecoding(path), bulk);
    // Cut inside the compressed data: the same records, then the same break.
    const std::string bytes = test::readFile(path);
    const std::string cut = tmp / "cut.rawlog";
    test::writeFile(cut, bytes.substr(0, bytes.size() / 2));
    EXPECT_GT(expectSameDecoding(cut), bulk / 4);
  }
}
