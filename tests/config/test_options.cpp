// The one options mechanism (config/Options.h): strict numbers, ranges, file/line in errors,
// save/load round trip, unknown keys with a suggestion, and a recording's embedded
// configuration loading back strictly.
#include "libwheelchair/config/Options.h"
#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/io/RawlogIO.h"

#include "../common/TestUtil.h"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

using namespace wheelchair;

namespace {

using wheelchair::test::errorOf;

struct Demo {
  double rate_hz = 100, gate = 0.5;
  int count = 3;
  bool on = true;
  std::string source = "encoders";
  config::Options options(const std::string& section = "demo") {
    return config::Options(section)
        .real("rate_hz", rate_hz, "rate (Hz)", config::Range::above(0))
        .real("gate", gate, "probability (-)", config::Range::between(0, 1))
        .integer("count", count, "count", config::Range::atLeast(0))
        .flag("on", on, "switch")
        .oneOf("source", source, {"encoders", "gyro"}, "source");
  }
};

}  // namespace

TEST(Options, NumbersAreParsedWhole) {
  EXPECT_EQ(config::parseStrictNumber("2.5", "k"), 2.5);
  EXPECT_EQ(config::parseStrictNumber(" 1e-3 ", "k"), 1e-3);
  EXPECT_EQ(config::parseStrictNumber("+3", "k"), 3.0);
  EXPECT_EQ(config::parseStrictNumber("-0.25", "k"), -0.25);
  // atof would read 2, 1.5, 0, NaN, inf, 0: each of these is an error.
  for (const char* bad : {"2,5", "1.5 m", "0x10", "nan", "inf", "", "1e999", "--1"})
    EXPECT_THROW(config::parseStrictNumber(bad, "k"), std::runtime_error) << bad;
}

TEST(Options, ValuesAreCheckedAndErrorsNameFileLineAndKey) {
  Demo d;
  const config::IniFile ok(
      "# c\n[demo]\nrate_hz = 50\ngate = 1\ncount = 7\non = false\n"
      "source = gyro\n",
      "ok.ini");
  d.options().load(ok);
  EXPECT_EQ(d.rate_hz, 50);
  EXPECT_EQ(d.gate, 1);
  EXPECT_EQ(d.count, 7);
  EXPECT_FALSE(d.on);
  EXPECT_EQ(d.source, "gyro");

  auto load = [](const std::string& text) {
    Demo x;
    x.options().load(config::IniFile(text, "f.ini"));
  };
  EXPECT_EQ(errorOf([&] { load("[demo]\n\ngate = 5\n"); }),
            "f.ini:3: [demo] gate: 5 is out of range [0, 1]");
  EXPECT_EQ(errorOf([&] { load("[demo]\nrate_hz = 2,5\n"); }),
            "f.ini:2: [demo] rate_hz: '2,5' is not a number");
  EXPECT_EQ(errorOf([&] { load("[demo]\nrate_hz = 0\n"); }),
            "f.ini:2: [demo] rate_hz: 0 is out of range > 0");
  EXPECT_EQ(errorOf([&] { load("[demo]\ncount = 2.5\n"); }),
            "f.ini:2: [demo] count: '2.5' is not an integer");
  EXPECT_EQ(errorOf([&] { load("[demo]\non = 2\n"); }),
            "f.ini:2: [demo] on: expected 0 or 1, got '2'");
  EXPECT_EQ(errorOf([&] { load("[demo]\nsource = imu\n"); }),
            "f.ini:2: [demo] source: expected encoders | gyro, got 'imu'");
}

TEST(Options, SaveThenLoadGivesTheSameValues) {
  Demo a;
  a.rate_hz = 12.345678901234567;
  a.gate = 0.1;
  a.count = 42;
  a.on = false;
  a.source = "gyro";
  config::IniFile ini;
  a.options().save(ini);
  Demo b;
  b.options().load(ini);
  EXPECT_EQ(b.rate_hz, a.rate_hz);  // shortest exact text: bit-identical
  EXPECT_EQ(b.gate, a.gate);
  EXPECT_EQ(b.count, a.count);
  EXPECT_EQ(b.on, a.on);
  EXPECT_EQ(b.source, a.source);
  // The dump documents every key with its range.
  const std::string dump = a.options().dump();
  EXPECT_NE(dump.find("# probability (-); [0, 1]\ngate = 0.1\n"), std::string::npos) << dump;
}

TEST(Options, UnknownKeyOfAKnownSectionIsAnErrorWithASuggestion) {
  const std::string text = "[vehicle]\nwheel_radius_m = 0.2\nwheel_radus_m = 0.3\n";
  EXPECT_EQ(errorOf([&] { config::WheelchairConfig::fromText(text, "t.ini"); }),
            "t.ini:3: [vehicle] wheel_radus_m: unknown key (did you mean wheel_radius_m?)");
  config::setLenient(true);
  const auto cfg = config::WheelchairConfig::fromText(text, "t.ini");
  config::setLenient(false);
  EXPECT_EQ(cfg.vehicle.geom.wheel_radius_m, 0.2);
  EXPECT_EQ(
      errorOf([] { config::WheelchairConfig::fromText("[imu]\nrate_hz = 100\nrate_hz = 200\n", "d.ini"); }),
      "d.ini:3: [imu] rate_hz: duplicate key (first at line 2)");
  // Values of shared keys are checked at load, with their line.
  EXPECT_EQ(errorOf([] { config::WheelchairConfig::fromText("[imu]\n\nrate_hz = -1\n", "i.ini"); }),
            "i.ini:3: [imu] rate_hz: -1 is out of range > 0");
}

TEST(Options, ConfigurationRoundTripsThroughTextAndARecordingHeader) {
  auto cfg = config::WheelchairConfig::load(test::sourcePath("config/wheelchair.ini"));
  cfg.set("vehicle", "wheel_radius_m", "0.1712345678901");
  cfg.set("encoders", "counts_per_rev", "4096");
  const auto back = config::WheelchairConfig::fromText(cfg.text(), "round trip");
  EXPECT_EQ(back.vehicle.geom.wheel_radius_m, 0.1712345678901);
  EXPECT_EQ(back.encoders.params.counts_per_rev, 4096);
  EXPECT_EQ(back.text(), cfg.text());

  // The configuration embedded in a rawlog header (with its [recording] keys) loads strictly.
  test::TempDir tmp;
  io::Recording rec;
  rec.meta["operator"] = "test";
  io::writeRawlog(rec, tmp / "r.rawlog", cfg);
  io::RawlogReadReport rep;
  io::readRawlog(tmp / "r.rawlog", &rep);
  ASSERT_NE(rep.header_text.find("[vehicle]"), std::string::npos);
  const auto embedded = config::WheelchairConfig::fromText(rep.header_text, "r.rawlog header");
  EXPECT_EQ(embedded.vehicle.geom.wheel_radius_m, 0.1712345678901);
  EXPECT_EQ(embedded.encoders.params.counts_per_rev, 4096);
}

TEST(Options, LoadingAnEmptyFileIsAnError) {
  test::TempDir tmp;
  test::writeFile(tmp / "empty.ini", "# only a comment\n\n");
  EXPECT_EQ(errorOf([&] { config::WheelchairConfig::load(tmp / "empty.ini"); }),
            tmp / "empty.ini" + ": empty configuration (no section, no key)");
}
