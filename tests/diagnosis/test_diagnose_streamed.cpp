// `wheelchair diagnose` reads rawlogs with motor currents as a stream into the streams the
// diagnosis needs (diagnosis/RawlogInput.h: no whole io::Recording of the IMU and motor
// samples; memory, issue 13). These tests hold the streamed read to the loaded one:
//  - the streams and the kept recording are those makeStreams(readRawlog(...)) and readRawlog
//    give, sample for sample, on a bundled drive and on a file out of time order with repeated
//    stamps and non-finite values (the sorting path);
//  - diagnose() on the streamed input gives the loaded recordings' report, and the CLI's JSON
//    is the report of the loaded path (held-out split, and --validate).
#include "libwheelchair/diagnosis/Comparisons.h"
#include "libwheelchair/diagnosis/HeldOut.h"
#include "libwheelchair/diagnosis/RawlogInput.h"
#include "libwheelchair/io/RawlogIO.h"

#include "../common/TestUtil.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <string>
#include <vector>

namespace {

using namespace wheelchair;
using test::cli;
using test::sourcePath;

/// The configuration `wheelchair diagnose` uses without --config: the one the rawlog records.
config::WheelchairConfig recordedConfig(const std::string& path) {
  io::RawlogReadReport rr;
  io::readRawlog(path, &rr);
  const std::string text = io::headerConfigText(rr.header_text);
  return text.empty() ? config::WheelchairConfig() : config::WheelchairConfig::fromText(text, path);
}

std::string imported(const test::TempDir& tmp, const std::string& dataset) {
  const std::string out = tmp / (dataset + ".rawlog");
  const auto r = cli("import " + sourcePath("datasets/" + dataset) + " -o " + out);
  EXPECT_EQ(r.exit_code, 0) << r.out;
  return out;
}

void expectSameStreams(const diagnosis::Streams& a, const diagnosis::Streams& b) {
  EXPECT_EQ(a.te, b.te);
  EXPECT_EQ(a.sR, b.sR);
  EXPECT_EQ(a.sL, b.sL);
  EXPECT_EQ(a.tg, b.tg);
  EXPECT_EQ(a.gz, b.gz);
  EXPECT_EQ(a.tm, b.tm);
  EXPECT_EQ(a.iR, b.iR);
  EXPECT_EQ(a.iL, b.iL);
  ASSERT_EQ(a.pozyx.size(), b.pozyx.size());
  for (std::size_t k = 0; k < a.pozyx.size(); ++k)
    EXPECT_TRUE(a.pozyx[k].t_s == b.pozyx[k].t_s && a.pozyx[k].x_m == b.pozyx[k].x_m &&
                a.pozyx[k].y_m == b.pozyx[k].y_m)
        << k;
  ASSERT_EQ(a.gt.size(), b.gt.size());
  for (std::size_t k = 0; k < a.gt.size(); ++k)
    EXPECT_TRUE(a.gt[k].t_s == b.gt[k].t_s && a.gt[k].x_m == b.gt[k].x_m &&
                a.gt[k].phi_rad == b.gt[k].phi_rad)
        << k;
  EXPECT_EQ(a.t_begin, b.t_begin);
  EXPECT_EQ(a.t_end, b.t_end);
}

/// The streamed read of `path` against the loaded recording: the same streams, and the kept
/// recording holds the loaded one's streams but the IMU, motor and joystick samples.
diagnosis::DiagnosisInput expectStreamedReadEqualsLoaded(const std::string& path,
                                                         const config::WheelchairConfig& cfg) {
  const io::Recording loaded = io::readRawlog(path);
  diagnosis::DiagnosisInput in;
  diagnosis::readForDiagnosis(path, io::scanRawlog(path), cfg, in);
  EXPECT_EQ(in.recs.size(), 1u);
  EXPECT_EQ(in.streams.size(), 1u);
  if (in.recs.size() != 1 || in.streams.size() != 1) return in;
  expectSameStreams(in.streams[0], diagnosis::makeStreams(loaded, cfg));
  const io::Recording& kept = in.recs[0];
  EXPECT_TRUE(kept.imu.empty() && kept.motors.empty() && kept.joystick.empty());
  EXPECT_EQ(kept.encoders.size(), loaded.encoders.size());
  for (std::size_t k = 0; k < std::min(kept.encoders.size(), loaded.encoders.size()); ++k)
    EXPECT_TRUE(kept.encoders[k].t_s == loaded.encoders[k].t_s &&
                kept.encoders[k].right_ticks == loaded.encoders[k].right_ticks &&
                kept.encoders[k].left_ticks == loaded.encoders[k].left_ticks)
        << k;
  EXPECT_EQ(kept.sonar.size(), loaded.sonar.size());
  EXPECT_EQ(kept.pozyx.size(), loaded.pozyx.size());
  EXPECT_EQ(kept.ground_truth.size(), loaded.ground_truth.size());
  EXPECT_EQ(kept.meta, loaded.meta);
  return in;
}

nlohmann::json withoutRuntime(nlohmann::json j) {
  j["info"].erase("runtime_s");
  for (const char* k : {"inputs", "validate", "config"}) j.erase(k);
  return j;
}

TEST(DiagnoseStreamed, StreamsEqualTheLoadedRecordingsOnABundledDrive) {
  test::TempDir tmp;
  const std::string path = imported(tmp, "excite");
  const auto cfg = recordedConfig(path);
  auto in = expectStreamedReadEqualsLoaded(path, cfg);
  ASSERT_GT(in.streams.at(0).tm.size(), 1000u);  // a drive with motor currents and a gyro
  ASSERT_GT(in.streams.at(0).tg.size(), 1000u);
}

// A file whose IMU and motor samples are out of time order, with repeated stamps and
// non-finite values: the columns go through the sorting path and give the loaded streams; the
// diagnosis of both is the same, bit for bit.
TEST(DiagnoseStreamed, OutOfOrderRepeatedAndNonFiniteSamplesAndTheReport) {
  test::TempDir tmp;
  const std::string src = imported(tmp, "excite");
  const auto cfg = recordedConfig(src);
  io::Recording rec = io::readRawlog(src);
  ASSERT_GT(rec.imu.size(), 400u);
  ASSERT_GT(rec.motors.size(), 400u);
  std::swap(rec.imu[100], rec.imu[300]);  // out of order
  std::swap(rec.motors[120], rec.motors[350]);
  rec.imu[200].t_s = rec.imu[199].t_s;  // a repeated stamp: the first sample is kept
  rec.motors[210].t_s = rec.motors[209].t_s;
  rec.imu[50].gyro_z_rad_s = NAN;  // dropped
  rec.motors[60].current_left_A = INFINITY;
  const std::string path = tmp / "disordered.rawlog";
  io::writeRawlog(rec, path, cfg);
  ASSERT_GT(io::scanRawlog(path).lateness_s, 0.0);  // the file is out of time order
  auto in = expectStreamedReadEqualsLoaded(path, cfg);
  ASSERT_EQ(in.streams.size(), 1u);
  const auto& s = in.streams[0];
  EXPECT_TRUE(std::is_sorted(s.tg.begin(), s.tg.end()));
  EXPECT_EQ(std::adjacent_find(s.tm.begin(), s.tm.end()), s.tm.end());  // no repeated stamp
  EXPECT_LT(s.tg.size(), rec.imu.size());
  EXPECT_LT(s.tm.size(), rec.motors.size());

  diagnosis::DiagnosisOptions opt;
  opt.loadFromConfig(cfg.ini());
  std::vector<io::Recording> loaded{io::readRawlog(path)};
  const auto a = diagnosis::diagnose(std::move(loaded), {}, cfg, opt).toJson();
  const auto b = diagnosis::diagnose(std::move(in), {}, cfg, opt).toJson();
  EXPECT_EQ(withoutRuntime(a).dump(), withoutRuntime(b).dump());
}

// What `diagnose` computed before it read rawlogs as streams: the loaded recordings, the
// wheelchair stages, the held-out rule and the comparisons (cmd_diagnose.cpp's analyse()).
nlohmann::json loadedReport(const std::vector<std::string>& fit_paths,
                            const std::vector<std::string>& val_paths) {
  std::vector<io::Recording> fit, val;
  for (const auto& p : fit_paths) fit.push_back(io::readRawlog(p));
  for (const auto& p : val_paths) val.push_back(io::readRawlog(p));
  const auto cfg = recordedConfig(fit_paths.front());
  diagnosis::DiagnosisOptions opt;
  opt.loadFromConfig(cfg.ini());
  const auto streams = diagnosis::sensorStreams(fit);
  auto rep = diagnosis::diagnose(std::move(fit), std::move(val), cfg, opt);
  diagnosis::enforceHeldOutRule(rep);
  diagnosis::addComparisons(streams, rep);
  return rep.toJson();
}

TEST(DiagnoseStreamed, CliReportEqualsTheLoadedRecordingsReport) {
  test::TempDir tmp;
  // The held-out last part of one recording (the crops consume the streams) ...
  const std::string excite = imported(tmp, "excite");
  auto r = cli("diagnose " + excite + " --no-progress --json " + (tmp / "e.json"));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_EQ(withoutRuntime(nlohmann::json::parse(test::readFile(tmp / "e.json"))).dump(),
            withoutRuntime(loadedReport({excite}, {})).dump());
  // ... and a --validate recording.
  const std::string faulty = imported(tmp, "three_task_faulty");
  const std::string faulty_b = imported(tmp, "three_task_faulty_b");
  r = cli("diagnose " + faulty + " --validate " + faulty_b + " --no-progress --json " +
          (tmp / "f.json"));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_EQ(withoutRuntime(nlohmann::json::parse(test::readFile(tmp / "f.json"))).dump(),
            withoutRuntime(loadedReport({faulty}, {faulty_b})).dump());
}

}  // namespace
