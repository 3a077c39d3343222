// The rawlog read as a stream (io/RawlogStream.h) by the filters and dead reckoning (issue 13:
// memory flat in the drive's length): bit-identical to the in-memory path on a file whose
// records are out of time order across streams (a little, and one record far beyond any
// fixed window), on a damaged tail with --salvage, and through `wheelchair filter`. Also the
// one estimator-selection rule of `filter` and `evaluate` (issue 14).
#include "StreamingUtil.h"
#include "SyntheticDrive.h"

#include "../common/TestUtil.h"
#include "libwheelchair/estimation/DeadReckoning.h"
#include "libwheelchair/estimation/Estimator.h"
#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/RawlogStream.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <sstream>

using namespace wheelchair;
using namespace wheelchair::estimation;

using wheelchair::estimation::test::Collect;
using wheelchair::estimation::test::nominal;

namespace {

/// Every sample of `rec` in time order, then disturbed: every 7th IMU and every 5th motor
/// sample written 0.3 s late (across streams, within a short window), one sonar reading
/// 4 s late (beyond any fixed window), equal timestamps across streams kept.
std::vector<io::AnySample> disturbedOrder(const io::Recording& rec) {
  std::vector<std::pair<double, io::AnySample>> v;  // (time written, sample)
  std::size_t imu = 0, mot = 0, son = 0;
  io::forEachInTimeOrder(rec, [&](const io::AnySample& s) {
    double at = io::timeOf(s);
    if (io::kindOf(s) == io::StreamKind::Imu && imu++ % 7 == 3) at += 0.3;
    if (io::kindOf(s) == io::StreamKind::Motors && mot++ % 5 == 1) at += 0.3;
    if (io::kindOf(s) == io::StreamKind::Sonar && son++ == 20) at += 4.0;
    v.emplace_back(at, s);
  });
  std::stable_sort(v.begin(), v.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<io::AnySample> out;
  for (auto& [t, s] : v) out.push_back(s);
  return out;
}

void writeInOrder(const std::string& path, const io::Recording& rec,
                  const std::vector<io::AnySample>& order) {
  io::RawlogWriter w(path);
  w.writeHeader(rec.meta, nominal(), rec.startTime());
  for (const auto& s : order) w.write(s, nominal());
  w.commit();
}

void expectSameEstimates(const std::vector<EstimateSample>& a,
                         const std::vector<EstimateSample>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    ASSERT_EQ(a[k].t_s, b[k].t_s) << k;
    ASSERT_EQ(a[k].x, b[k].x) << k;
    ASSERT_EQ(a[k].sd, b[k].sd) << k;
  }
}

/// Streamed vs in-memory run of every filter and output mode, and both dead reckonings.
void expectStreamedEqualsInMemory(const std::string& path, const io::Recording& rec,
                                  const io::RecordingSummary& sum) {
  for (const EkfOptions& opt : estimation::test::streamingOptionSets()) {
    Collect mem, str;
    const auto a = runEstimator(rec, nominal(), opt, mem);
    const auto b = runEstimator(path, sum, nominal(), opt, str);
    ASSERT_GT(mem.v.size(), 50u);
    expectSameEstimates(mem.v, str.v);
    for (int s = 0; s < kNumSensors; ++s) {
      EXPECT_EQ(a.sensors[s].used, b.sensors[s].used) << s;
      EXPECT_EQ(a.sensors[s].rejected, b.sensors[s].rejected) << s;
      EXPECT_EQ(a.sensors[s].dropouts, b.sensors[s].dropouts) << s;
      EXPECT_EQ(a.sensors[s].nis_sum, b.sensors[s].nis_sum) << s;
    }
    EXPECT_EQ(a.warnings, b.warnings);
    // Read once (no scan): the same run on a time-ordered file, nothing on another.
    Collect one;
    io::RecordingSummary scanned;
    const auto c = runEstimatorOnePass(path, nominal(), opt, one, scanned);
    if (sum.lateness_s > 0) {
      EXPECT_FALSE(c);
      continue;
    }
    ASSERT_TRUE(c);
    expectSameEstimates(mem.v, one.v);
    for (int s = 0; s < kNumSensors; ++s) {
      EXPECT_EQ(a.sensors[s].used, c->sensors[s].used) << s;
      EXPECT_EQ(a.sensors[s].skipped, c->sensors[s].skipped) << s;
      EXPECT_EQ(a.sensors[s].nis_sum, c->sensors[s].nis_sum) << s;
    }
    EXPECT_EQ(a.warnings, c->warnings);
    EXPECT_EQ(scanned.counts, sum.counts);
    EXPECT_EQ(scanned.start_s, sum.start_s);
    EXPECT_EQ(scanned.end_s, sum.end_s);
    EXPECT_EQ(scanned.report.records, sum.report.records);
    EXPECT_EQ(scanned.report.broken.has_value(), sum.report.broken.has_value());
    EXPECT_EQ(scanned.meta, sum.meta);
  }
  const auto& g = nominal().vehicle.geom;
  const auto& p = nominal().encoders.params;
  for (bool gyro : {false, true}) {
    const auto mem = gyro ? deadReckoningEncoderGyro(rec.encoders, rec.imu, p, g)
                          : deadReckoningEncoders(rec.encoders, p, g);
    std::vector<DeadReckoningSample> str;
    const auto run = deadReckonRawlog(path, sum, gyro, p, g,
                                      [&](const DeadReckoningSample& s) { str.push_back(s); });
    ASSERT_EQ(mem.size(), str.size());
    EXPECT_EQ(run.samples, str.size());
    EXPECT_EQ(run.path_m, pathLength(mem));
    for (std::size_t k = 0; k < mem.size(); ++k) {
      ASSERT_EQ(mem[k].t_s, str[k].t_s) << k;
      ASSERT_EQ(mem[k].x_m, str[k].x_m) << k;
      ASSERT_EQ(mem[k].phi_rad, str[k].phi_rad) << k;
    }
  }
}

estimation::test::SynthRun drive() {
  estimation::test::SynthOptions so;
  so.duration_s = 12.0;
  so.currents = estimation::test::curvyCurrents(0.3, 1.6, 0.4);
  so.obstacle_world = Eigen::Vector2d(2.5, 0.2);
  so.sonar_cone = true;
  so.pozyx = true;
  return estimation::test::synthesize(nominal(), so, 5);
}

}  // namespace

TEST(RawlogStreaming, OutOfOrderRecordsAcrossStreamsGiveTheInMemoryResultBitForBit) {
  wheelchair::test::TempDir dir;
  const auto sr = drive();
  const std::string path = dir / "disturbed.rawlog";
  writeInOrder(path, sr.rec, disturbedOrder(sr.rec));

  const io::RecordingSummary sum = io::scanRawlog(path);
  const io::Recording rec = io::readRawlog(path);
  EXPECT_EQ(sum.size(), rec.size());
  EXPECT_EQ(sum.count(io::StreamKind::Imu), rec.imu.size());
  EXPECT_EQ(sum.start_s, rec.startTime());
  EXPECT_EQ(sum.end_s, rec.endTime());
  // The sonar reading written 4 s late sets the window.
  EXPECT_GT(sum.lateness_s, 3.9);
  EXPECT_LT(sum.lateness_s, 4.1);
  EXPECT_FALSE(sum.report.broken);
  expectStreamedEqualsInMemory(path, rec, sum);

  // The same drive written in time order: no window at all.
  const std::string ordered = dir / "ordered.rawlog";
  io::writeRawlog(sr.rec, ordered, nominal());
  const auto sum2 = io::scanRawlog(ordered);
  EXPECT_EQ(sum2.lateness_s, 0.0);
  expectStreamedEqualsInMemory(ordered, io::readRawlog(ordered), sum2);
}

TEST(RawlogStreaming, DamagedTailIsRefusedOrSalvagedLikeTheInMemoryReader) {
  wheelchair::test::TempDir dir;
  const auto sr = drive();
  const std::string path = dir / "cut.rawlog";
  writeInOrder(path, sr.rec, disturbedOrder(sr.rec));
  std::filesystem::resize_file(path, std::filesystem::file_size(path) * 2 / 3);

  // Without --salvage: the same one-line refusal as the in-memory reader.
  std::string mem_error, str_error;
  try {
    io::readRawlogSalvaging(path, false, nullptr);
  } catch (const std::exception& e) {
    mem_error = e.what();
  }
  try {
    io::scanRawlogSalvaging(path, false, nullptr);
  } catch (const std::exception& e) {
    str_error = e.what();
  }
  EXPECT_NE(mem_error.find("--salvage"), std::string::npos) << mem_error;
  EXPECT_EQ(mem_error, str_error);

  // With it: the same warning and the complete records before the break, bit for bit.
  std::string w_mem, w_str;
  const io::Recording rec = io::readRawlogSalvaging(path, true, &w_mem);
  const io::RecordingSummary sum = io::scanRawlogSalvaging(path, true, &w_str);
  EXPECT_FALSE(w_mem.empty());
  EXPECT_EQ(w_mem, w_str);
  EXPECT_EQ(sum.size(), rec.size());
  ASSERT_LT(rec.size(), sr.rec.size());
  expectStreamedEqualsInMemory(path, rec, sum);

  // Through the CLI: refused (exit 1) without --salvage; with it the warning names the break
  // and the estimates are the in-memory run's.
  const auto refused =
      wheelchair::test::cli("filter " + path + " --no-progress --estimates " + (dir / "r.csv"));
  EXPECT_EQ(refused.exit_code, 1) << refused.out;
  EXPECT_FALSE(std::filesystem::exists(dir / "r.csv"));
  const auto ok =
      wheelchair::test::cli("filter " + path + " --no-progress --salvage --estimates " +
                            (dir / "e.csv") + " --trajectory " + (dir / "t.tum") + " --variants");
  ASSERT_EQ(ok.exit_code, 0) << ok.out;
  EXPECT_NE(ok.out.find("salvaged the"), std::string::npos) << ok.out;
  Collect mem;
  runEstimator(rec, nominal(), EkfOptions{}, mem);
  std::istringstream csv(wheelchair::test::readFile(dir / "e.csv"));
  std::size_t rows = 0;
  for (std::string line; std::getline(csv, line);) rows += line.empty() ? 0 : 1;
  EXPECT_EQ(rows, mem.v.size() + 1);  // + header
}

TEST(RawlogStreaming, OnePassOnATimeOrderedCutFileAndWithoutMotorCurrents) {
  wheelchair::test::TempDir dir;
  auto sr = drive();
  // A time-ordered file cut short: one pass with the scan's summary and result, the salvage
  // rule applied by `filter` after the run (refused without --salvage, nothing written).
  const std::string path = dir / "cut.rawlog";
  io::writeRawlog(sr.rec, path, nominal());
  std::filesystem::resize_file(path, std::filesystem::file_size(path) * 2 / 3);
  const io::RecordingSummary sum = io::scanRawlog(path);
  ASSERT_TRUE(sum.report.broken);
  EXPECT_EQ(sum.lateness_s, 0.0);
  expectStreamedEqualsInMemory(path, io::readRawlogSalvaging(path, true, nullptr), sum);
  const auto refused =
      wheelchair::test::cli("filter " + path + " --no-progress --estimates " + (dir / "r.csv"));
  EXPECT_EQ(refused.exit_code, 1) << refused.out;
  EXPECT_NE(refused.out.find("--salvage"), std::string::npos) << refused.out;
  EXPECT_FALSE(std::filesystem::exists(dir / "r.csv"));
  const auto ok = wheelchair::test::cli("filter " + path + " --no-progress --salvage");
  EXPECT_EQ(ok.exit_code, 0) << ok.out;
  EXPECT_NE(ok.out.find("salvaged the"), std::string::npos) << ok.out;

  // No motor currents: the merge would hold the drive waiting for them; the two-pass run
  // warns before its first measurement. One pass declines; `filter` then scans and warns.
  sr.rec.motors.clear();
  const std::string no_motors = dir / "no_motors.rawlog";
  io::writeRawlog(sr.rec, no_motors, nominal());
  Collect sink;
  io::RecordingSummary scanned;
  EXPECT_FALSE(runEstimatorOnePass(no_motors, nominal(), EkfOptions{}, sink, scanned));
  const auto run = wheelchair::test::cli("filter " + no_motors + " --no-progress");
  EXPECT_EQ(run.exit_code, 0) << run.out;
  EXPECT_NE(run.out.find("warning: no motor currents"), std::string::npos) << run.out;
}

TEST(EstimatorSelection, OneRuleForFilterAndEvaluate) {
  io::Recording rec;
  rec.joystick.push_back({1.0, 0.2, 0.0});
  rec.landmarks.push_back({1.0, 7, 2.0, 0.1});
  EXPECT_EQ(selectEstimator(rec), EstimatorFamily::CommandDriven);
  EXPECT_EQ(selectEstimator(rec, "physics"), EstimatorFamily::Wheelchair);
  // A wheelchair drive that also saw landmarks is a wheelchair drive, for both commands.
  rec.encoders.push_back({1.0, 0, 0});
  EXPECT_EQ(selectEstimator(rec), EstimatorFamily::Wheelchair);
  EXPECT_EQ(selectEstimator(rec, "command"), EstimatorFamily::CommandDriven);
  // A landmark map in the header alone makes a recording command-driven.
  io::Recording mapped;
  mapped.meta["landmark.6"] = "1.5 2.5 0.01 0.01";
  mapped.joystick.push_back({1.0, 0.2, 0.0});
  EXPECT_EQ(selectEstimator(io::summarize(mapped)), EstimatorFamily::CommandDriven);
  mapped.imu.push_back({1.0, 0.0});
  EXPECT_EQ(selectEstimator(io::summarize(mapped)), EstimatorFamily::Wheelchair);

  // Through the CLI: a drive with encoders, gyro and landmark sightings goes to the physics
  // filter in `filter` and gets the wheelchair variants in `evaluate`.
  wheelchair::test::TempDir dir;
  auto sr = drive();
  for (const auto& e : sr.rec.encoders) sr.rec.landmarks.push_back({e.t_s, 7, 2.0, 0.1});
  io::writeRawlog(sr.rec, dir / "both.rawlog", nominal());
  const auto f = wheelchair::test::cli("filter " + (dir / "both.rawlog") + " --no-progress");
  EXPECT_EQ(f.exit_code, 0) << f.out;
  EXPECT_NE(f.out.find("physics filter"), std::string::npos) << f.out;
  const auto ev = wheelchair::test::cli("evaluate -j1 -q " + (dir / "both.rawlog") + " --csv -");
  EXPECT_EQ(ev.exit_code, 0) << ev.out;
  EXPECT_NE(ev.out.find("encoders_gyro"), std::string::npos) << ev.out;
  EXPECT_EQ(ev.out.find(",commands,"), std::string::npos) << ev.out;
}
