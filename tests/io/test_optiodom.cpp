// OptiOdom import (libwheelchair/io/OptiodomImport.h) on the REAL files: the shipped excerpt
// (datasets/optiodom/230620202042, runs 1 and 4) always; the full circular and square folders
// at ../shared/datasets/optiodom beside the source tree when present (else skipped).
#include "libwheelchair/io/OptiodomImport.h"
#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/TextFormat.h"

#include "../common/TestUtil.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace wheelchair::io {
namespace {

namespace fs = std::filesystem;
const std::string kExcerpt = std::string(WHEELCHAIR_SOURCE_DIR) + "/datasets/optiodom/230620202042";
const std::string kFull = std::string(WHEELCHAIR_SOURCE_DIR) + "/../shared/datasets/optiodom";

TEST(OptiodomImport, ExcerptTicksTruthCommandsAndGeometry) {
  OptiodomImportReport rep;
  const Recording rec = importOptiodom(kExcerpt, 1, &rep);
  // run-01.csv: 1814 rows, t from 0 every 50 ms; ends back near the start after one cw square
  ASSERT_EQ(rec.encoders.size(), 1814u);
  ASSERT_EQ(rec.ground_truth.size(), 1814u);
  EXPECT_DOUBLE_EQ(rec.encoders.front().t_s, 0.0);
  EXPECT_NEAR(rec.encoders.back().t_s, 90.65, 1e-9);
  EXPECT_NEAR(rec.ground_truth.back().phi_rad, -6.28220535716447, 1e-12);
  EXPECT_EQ(rep.direction, "cw");
  EXPECT_EQ(rep.path_kind, "square");
  EXPECT_DOUBLE_EQ(rep.square_side_m, 0.75);
  // ticks accumulate: row 1500 of the file is t = 74.95 s with odoR 29, odoL 30 per cycle
  const auto& a = rec.encoders[1498];
  const auto& b = rec.encoders[1499];
  EXPECT_NEAR(b.t_s, 74.95, 1e-9);
  EXPECT_EQ(b.right_ticks - a.right_ticks, 29);
  EXPECT_EQ(b.left_ticks - a.left_ticks, 30);
  // a cw square of 4 x 0.75 m with four right turns in place: the right (inner) wheel rolls
  // 3 m - 4 (pi/2) (b/2) = 2.37 m, the left one 3.63 m (ticks of pi 0.084 / 2796.8 m)
  EXPECT_NEAR(rec.encoders.back().right_ticks * M_PI * 0.084 / 2796.8, 3.0 - M_PI * 0.2, 0.05);
  EXPECT_NEAR(rec.encoders.back().left_ticks * M_PI * 0.084 / 2796.8, 3.0 + M_PI * 0.2, 0.05);
  // geometry of the metadata / log header
  EXPECT_DOUBLE_EQ(rep.geometry.wheel_diameter_right_m, 0.084);
  EXPECT_DOUBLE_EQ(rep.geometry.wheel_diameter_left_m, 0.084);
  EXPECT_DOUBLE_EQ(rep.geometry.track_m, 0.2);
  EXPECT_NEAR(rep.geometry.ticksPerWheelRev(), 2796.8, 1e-9);
  config::WheelchairConfig cfg;
  applyOptiodomGeometry(rep.geometry, cfg);
  EXPECT_NEAR(cfg.encoders.params.ticksPerWheelRev(), 2796.8, 1e-9);
  EXPECT_DOUBLE_EQ(cfg.vehicle.geom.wheel_radius_m, 0.042);
  EXPECT_DOUBLE_EQ(cfg.vehicle.geom.odometryRadius(0), 0.042);
  EXPECT_DOUBLE_EQ(cfg.vehicle.geom.track_width_m, 0.2);
  // commands of run 1 in physical units: 30 ticks/cycle = 30 pi 0.084 / 2796.8 / 0.05 m/s
  ASSERT_GT(rep.commands, 1000u);
  EXPECT_NEAR(rec.joystick[1].v_cmd_m_s, 30 * M_PI * 0.084 / 2796.8 / 0.05, 1e-12);
  EXPECT_NEAR(rec.joystick[3].omega_cmd_rad_s, -0.08 / 0.05, 1e-12);
  EXPECT_NEAR(rec.joystick.front().t_s, 0.0, 1e-9);
  const Recording ccw = importOptiodom(kExcerpt, 4, &rep);
  EXPECT_EQ(rep.direction, "ccw");
  EXPECT_EQ(ccw.meta.at("run"), "4");
}

TEST(OptiodomImport, CliWritesRawlogWithTheRecordingsGeometry) {
  const test::TempDir tmp;
  const std::string out = tmp / "cli.rawlog";
  const auto r = test::cli("import --format optiodom " + kExcerpt + " --run 4 -o " + out);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  RawlogReadReport rep;
  const Recording rec = readRawlog(out, &rep);
  EXPECT_EQ(rec.encoders.size(), 1814u);
  EXPECT_EQ(rec.ground_truth.size(), 1814u);
  EXPECT_FALSE(rec.joystick.empty());
  EXPECT_EQ(rec.meta.at("direction"), "ccw");
  EXPECT_NE(rep.header_text.find("track_width_m = 0.2"), std::string::npos);
  EXPECT_NE(rep.header_text.find("wheel_radius_right_m = 0.042"), std::string::npos);
  // a run the excerpt does not ship: exit 1 naming the file on stderr, no output written
  const std::string bad = tmp / "bad.rawlog";
  const auto r2 = test::run("{ " + std::string(WHEELCHAIR_CLI) + " import --format optiodom " +
                            kExcerpt + " --run 2 -o " + bad + " > /dev/null; }");  // stderr only
  EXPECT_EQ(r2.exit_code, 1) << r2.out;
  EXPECT_FALSE(fs::exists(bad));
  EXPECT_NE(r2.out.find("230620202042_run-02.csv"), std::string::npos) << r2.out;
}

TEST(OptiodomImport, BadRowsNameFileAndLine) {
  const test::TempDir tmp;
  const fs::path d = tmp.path() / "230620202042";
  fs::create_directories(d);
  for (const char* f : {"230620202042_metadata.csv", "230620202042.csv"})
    fs::copy_file(kExcerpt + "/" + f, d / f, fs::copy_options::overwrite_existing);
  std::ofstream(d / "230620202042_run-01.csv") << "0,0,0,0,0,0\n0.05,0,0,0,x,1\n";
  try {
    importOptiodom(d.string(), 1);
    FAIL() << "no error";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("230620202042_run-01.csv:2"), std::string::npos)
        << e.what();
  }
  std::ofstream(d / "230620202042_run-01.csv") << "0,0,0,0,0,0\n0.05,0,0,0,1.5,1\n";
  EXPECT_THROW(importOptiodom(d.string(), 1), FormatError);  // fractional ticks
  std::ofstream(d / "230620202042_run-01.csv") << "0,0,0,0,0,0\n0,0,0,0,1,1\n";
  EXPECT_THROW(importOptiodom(d.string(), 1), FormatError);            // time does not increase
  EXPECT_THROW(importOptiodom(d.string(), 7), std::invalid_argument);  // N = 6
}

TEST(OptiodomImport, FullDatasetEveryRunImports) {
  if (!fs::is_directory(kFull + "/square"))
    GTEST_SKIP() << kFull << " not present (the full OptiOdom folders live beside the repository)";
  std::size_t runs = 0, cw = 0, ccw = 0;
  for (const char* kind : {"square", "circular"})
    for (const auto& [rec, rep] : importOptiodomFolder(kFull + "/" + kind)) {
      EXPECT_GT(rec.encoders.size(), 500u) << rep.experiment << " run " << rep.run;
      EXPECT_FALSE(rec.joystick.empty()) << rep.experiment << " run " << rep.run;
      ++runs;
      if (std::string(kind) == "square") (rep.direction == "cw" ? cw : ccw)++;
    }
  EXPECT_EQ(runs, 98u);  // README: 54 circular + 44 square runs
  EXPECT_EQ(cw + ccw, 44u);
  EXPECT_EQ(cw, ccw);
}

}  // namespace
}  // namespace wheelchair::io
