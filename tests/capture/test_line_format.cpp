// The shared line parser (LineFormat) and the line splitting of the serial sources.
#include "CaptureTestUtil.h"

#include "libwheelchair/capture/LineSensor.h"

using namespace wheelchair;
using capture::LineFormat;
using capture::ParsedLine;
using io::StreamKind;

namespace {

LineFormat fromIni(const std::string& text, const std::string& section, StreamKind k) {
  mrpt::config::CConfigFileMemory ini(text);
  return LineFormat::fromConfig(ini, section, k);
}

}  // namespace

TEST(LineFormat, DefaultFormatsReadBackWhatTheyWrite) {
  const auto rec = test::captureRecording(0.5);
  for (auto k : test::kCapturedStreams) {
    mrpt::config::CConfigFileMemory ini(test::readFile(test::captureTemplate()));
    const char* sec[] = {"encoders", "imu", "motors", "sonar", "pozyx", "joystick"};
    const auto f = LineFormat::fromConfig(ini, sec[static_cast<int>(k)], k);
    for (const auto& s : test::samplesOf(rec, k)) {
      std::size_t inexact = 0;
      const std::string line = f.format(s, &inexact);
      EXPECT_EQ(inexact, 0u) << line;
      ParsedLine p;
      ASSERT_TRUE(f.parse(line, p)) << line;
      ASSERT_TRUE(p.device_time_s.has_value());
      EXPECT_EQ(*p.device_time_s, io::timeOf(s));
      std::visit([&](auto& x) { x.t_s = *p.device_time_s; }, p.sample);
      EXPECT_TRUE(test::sameSample(s, p.sample)) << line;
    }
  }
}

TEST(LineFormat, ArduinoSendsIntegerAdcCountsConvertedByTheCalibration) {
  mrpt::config::CConfigFileMemory ini(test::readFile(test::captureTemplate()));
  const auto f = LineFormat::fromConfig(ini, "motors", StreamKind::Motors);
  ParsedLine p;
  ASSERT_TRUE(f.parse("12.5,512,1023,0,1024", p));
  const auto& m = std::get<io::MotorSample>(p.sample);
  EXPECT_DOUBLE_EQ(m.current_right_A, 0.0);  // 2.5 V = 0 A
  EXPECT_DOUBLE_EQ(m.current_left_A, -62.5 + 1023 * 5.0 / 1024 / 0.040);
  EXPECT_DOUBLE_EQ(m.vrc_right_V, 0.0);
  EXPECT_DOUBLE_EQ(m.vrc_left_V, 5.0);
  // And the replay writes integer counts for values on the ADC grid.
  EXPECT_EQ(f.format(io::MotorSample{12.5, 0.0, -62.5, 2.5, 5.0}), "12.5,512,0,512,1024");
}

TEST(LineFormat, StockRazorFirmwareFormatWithUnitGains) {
  const std::string ini =
      "[imu]\nline_format = {t}, {acc_x}, {acc_y}, {acc_z}, {gyro_x}, {gyro_y}, {gyro_z}, {_}, "
      "{_}, {_}\n"
      "t_gain = 0.001\nacc_x_gain = 9.80665\nacc_y_gain = 9.80665\nacc_z_gain = 9.80665\n"
      "gyro_x_gain = 0.017453292519943295\ngyro_y_gain = 0.017453292519943295\n"
      "gyro_z_gain = 0.017453292519943295\n";
  const auto f = fromIni(ini, "imu", StreamKind::Imu);
  ParsedLine p;
  ASSERT_TRUE(f.parse("123456, 0.01, -0.02, 1.00, 1.5, -2.0, 90.0, 10.5, -3.2, 40.1", p));
  const auto& s = std::get<io::ImuSample>(p.sample);
  EXPECT_DOUBLE_EQ(*p.device_time_s, 123.456);
  EXPECT_DOUBLE_EQ(s.gyro_z_rad_s, M_PI / 2);
  ASSERT_TRUE(s.has_extra);
  EXPECT_DOUBLE_EQ(s.extra[4], 9.80665);
  // Blanks are flexible where the template has a space.
  EXPECT_TRUE(f.parse("123456,0.01,-0.02,1.00,1.5,-2.0,90.0,10.5,-3.2,40.1", p));
  EXPECT_TRUE(f.parse("123456,  0.01,\t-0.02, 1.00, 1.5, -2.0, 90.0, 10.5, -3.2, 40.1\r", p));
  // The replay inverts the gains; the values come back to within an ulp (exactly when a
  // decimal exists that does it).
  io::ImuSample in{100.25, 0.3, true, {0.1, -0.2, 0.5, -0.05, 9.81}};
  std::size_t inexact = 0;
  ASSERT_TRUE(f.parse(f.format(in, &inexact), p));
  const auto& back = std::get<io::ImuSample>(p.sample);
  EXPECT_NEAR(back.gyro_z_rad_s, in.gyro_z_rad_s, 1e-15);
  for (int i = 0; i < 5; ++i) EXPECT_NEAR(back.extra[i], in.extra[i], 1e-14);
  EXPECT_LE(inexact, 2u);
}

TEST(LineFormat, MalformedLinesAreRejected) {
  mrpt::config::CConfigFileMemory ini(test::readFile(test::captureTemplate()));
  const auto enc = LineFormat::fromConfig(ini, "encoders", StreamKind::Encoders);
  const auto imu = LineFormat::fromConfig(ini, "imu", StreamKind::Imu);
  const auto sonar = LineFormat::fromConfig(ini, "sonar", StreamKind::Sonar);
  const auto pozyx = LineFormat::fromConfig(ini, "pozyx", StreamKind::Pozyx);
  ParsedLine p;
  for (const char* bad : {"", "1.0", "1.0,5", "1.0,5,6,7", "1.0,5.5,6", "1.0,5e3,6", "1.0,,6",
                          "1.0,5,6,", "x1.0,5,6", "1.0;5;6", "1.0,4294967296,6",
                          "1.0,-2147483649,6", "nan,5,6", "1.0,0x10,6", "\x80\x81\x82"})
    EXPECT_FALSE(enc.parse(bad, p)) << "'" << bad << "'";
  for (const char* bad :
       {"1.0,0.1,0.2", "1.0,0.1,0.2,0.3,0.4,0.5", "1.0,inf", "1.0,0.1,", "1.0,err"})
    EXPECT_FALSE(imu.parse(bad, p)) << bad;
  EXPECT_FALSE(sonar.parse("1.0,-0.5", p));           // a negative range
  EXPECT_FALSE(pozyx.parse("1.0,1,2,", p));           // a dangling optional group
  EXPECT_FALSE(enc.parse(std::string(600, '1'), p));  // longer than max_line_length
}

TEST(LineFormat, AcceptsWhatRealDevicesSend) {
  mrpt::config::CConfigFileMemory ini(test::readFile(test::captureTemplate()));
  const auto enc = LineFormat::fromConfig(ini, "encoders", StreamKind::Encoders);
  const auto pozyx = LineFormat::fromConfig(ini, "pozyx", StreamKind::Pozyx);
  ParsedLine p;
  ASSERT_TRUE(enc.parse("1.0,4294967295,+2147483648\r", p));  // unsigned counters: wrap
  EXPECT_EQ(std::get<io::EncoderSample>(p.sample).right_ticks, -1);
  EXPECT_EQ(std::get<io::EncoderSample>(p.sample).left_ticks, std::numeric_limits<int32_t>::min());
  ASSERT_TRUE(enc.parse("  7,-5,12  ", p));
  EXPECT_EQ(std::get<io::EncoderSample>(p.sample).right_ticks, -5);
  ASSERT_TRUE(pozyx.parse("2.5,1.25,-3", p));
  EXPECT_FALSE(std::get<io::PozyxSample>(p.sample).has_z);
  ASSERT_TRUE(pozyx.parse("2.5,1.25,-3,0.75", p));
  EXPECT_TRUE(std::get<io::PozyxSample>(p.sample).has_z);
  EXPECT_EQ(std::get<io::PozyxSample>(p.sample).z_m, 0.75);
}

TEST(LineFormat, PrefixesAndRegexFormats) {
  const auto f = fromIni("[s]\nline_format = $RNG {t} ; {range} cm\nrange_gain = 0.01\n", "s",
                         StreamKind::Sonar);
  ParsedLine p;
  ASSERT_TRUE(f.parse("$RNG 10.5 ; 123 cm", p));
  EXPECT_DOUBLE_EQ(std::get<io::SonarSample>(p.sample).range_m, 1.23);
  EXPECT_FALSE(f.parse("RNG 10.5 ; 123 cm", p));  // a line cut at its start
  EXPECT_FALSE(f.parse("$RNG 10.5 ; 123", p));
  EXPECT_EQ(f.format(io::SonarSample{10.5, 1.25}), "$RNG 10.5 ; 125 cm");

  const auto r = fromIni(
      "[p]\nline_regex = ^POS,0x[0-9a-f]+,x\\(mm\\): (-?\\d+) y\\(mm\\): (-?\\d+)( z\\(mm\\): "
      "(-?\\d+))?$\n"
      "line_fields = x,y,_,z\nx_gain = 0.001\ny_gain = 0.001\nz_gain = 0.001\n",
      "p", StreamKind::Pozyx);
  ASSERT_TRUE(r.parse("POS,0x6951,x(mm): 1234 y(mm): -50", p));
  const auto& s = std::get<io::PozyxSample>(p.sample);
  EXPECT_DOUBLE_EQ(s.x_m, 1.234);
  EXPECT_DOUBLE_EQ(s.y_m, -0.05);
  EXPECT_FALSE(s.has_z);
  EXPECT_FALSE(p.device_time_s.has_value());
  EXPECT_FALSE(r.parse("POS,0x6951,x(mm): 12a4 y(mm): -50", p));
  EXPECT_FALSE(r.canFormat());
}

TEST(LineFormat, ConfigurationErrorsNameTheProblem) {
  auto err = [](const std::string& ini, StreamKind k) -> std::string {
    try {
      fromIni(ini, "s", k);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_NE(err("[s]\nline_format = {t},{speed}\n", StreamKind::Sonar).find("unknown field"),
            std::string::npos);
  EXPECT_NE(err("[s]\nline_format = {t}\n", StreamKind::Sonar).find("required field {range}"),
            std::string::npos);
  EXPECT_NE(err("[s]\nline_format = {t}.{range}\n", StreamKind::Sonar).find("ambiguous"),
            std::string::npos);
  EXPECT_NE(err("[s]\nline_format = {t},{range},{range}\n", StreamKind::Sonar).find("twice"),
            std::string::npos);
  EXPECT_NE(err("[s]\nright_ticks_gain = 2\n", StreamKind::Encoders).find("tick counts"),
            std::string::npos);
  EXPECT_NE(err("[s]\nline_format = {t},{gyro_z},{gyro_x}\n", StreamKind::Imu).find("go together"),
            std::string::npos);
  EXPECT_NE(err("[s]\nrange_gain = abc\n", StreamKind::Sonar).find("range_gain"),
            std::string::npos);
}

namespace {
// A LineSensor fed by hand (no device).
struct FedSensor {
  capture::SonarSensor s;
  FedSensor() {
    mrpt::config::CConfigFileMemory ini(
        "[sonar]\ndriver = SonarSensor\nserial_port = /nonexistent\n"
        "time_source = device\nmax_line_length = 64\n");
    s.loadConfig(ini, "sonar");
  }
  std::vector<double> ranges() {
    std::vector<double> v;
    for (auto& [t, o] : s.getObservations())
      v.push_back(std::get<io::SonarSample>(
                      *io::fromObservation(*std::dynamic_pointer_cast<mrpt::obs::CObservation>(o)))
                      .range_m);
    return v;
  }
};
}  // namespace

TEST(LineSensor, LinesSplitAcrossReadsAndOverlongLines) {
  FedSensor f;
  auto feed = [&](const std::string& s) { f.s.feed(s.data(), s.size(), 100.0); };
  feed("1.0,0.5\n2.0,0.");
  feed("75\n\n\r\n3.0,");
  feed("1.25\n");
  EXPECT_EQ(f.ranges(), (std::vector<double>{0.5, 0.75, 1.25}));
  feed(std::string(50, '9'));
  feed(std::string(50, '9'));  // > 64 without an end of line: garbage, skipped to its end
  feed(std::string(500, '9') + "\n4.0,2.5\n");
  EXPECT_EQ(f.ranges(), (std::vector<double>{2.5}));
  EXPECT_EQ(f.s.status().garbage, 1u);
  feed("5.0,abc\n\x01\x02\n6.0,3\n");
  EXPECT_EQ(f.ranges(), (std::vector<double>{3.0}));
  EXPECT_EQ(f.s.status().garbage, 3u);
  EXPECT_EQ(f.s.status().records, 5u);
}

TEST(LineSensor, MrptFactoryCreatesTheDrivers) {
  for (const char* d : {"ArduinoMotorsSensor", "RazorImuSensor", "PozyxSensor", "SonarSensor",
                        "JoystickSensor", "QuadratureCounterSensor"}) {
    auto s = capture::createCaptureSource(d);
    ASSERT_TRUE(s) << d;
    EXPECT_STREQ(s->GetRuntimeClass()->className, d);
    // Also through MRPT's own factory, as rawlog-grabber would.
    std::unique_ptr<mrpt::hwdrivers::CGenericSensor> g(
        mrpt::hwdrivers::CGenericSensor::createSensor(d));
    EXPECT_TRUE(g) << d;
  }
  EXPECT_FALSE(capture::createCaptureSource("CGPSInterface"));  // an MRPT driver, not ours
  // A wrong sensorLabel would make the stream unreadable: refused.
  capture::SonarSensor s;
  mrpt::config::CConfigFileMemory ini("[x]\nsensorLabel = RANGE\nserial_port = /dev/null\n");
  EXPECT_THROW(s.loadConfig(ini, "x"), std::exception);
}
