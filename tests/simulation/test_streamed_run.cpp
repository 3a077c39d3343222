// `wheelchair simulate` writing as the run produces (issue 13: memory flat in the drive's
// length): simulateToFiles gives the same bytes as simulate() + writeRawlog + writeTruth, with
// the truth kept in memory or spilled to the scratch file; io::TimeOrderedRawlogWriter gives
// writeRawlog's bytes for samples fed stream by stream, and refuses (writing nothing) when the
// header time it had to choose early turns out wrong.
#include "../common/TestUtil.h"
#include "../io/SyntheticRecording.h"
#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/RawlogStream.h"
#include "libwheelchair/simulation/StreamedRun.h"

#include <gtest/gtest.h>

#include <filesystem>

using namespace wheelchair;

namespace {

std::string bytes(const std::string& path) {
  return wheelchair::test::readFile(path);
}

/// Every sample of `rec`, stream by stream in stream order, interleaved in blocks of `block`
/// samples per stream (so the writer sees streams running ahead of each other).
std::vector<io::AnySample> interleaved(const io::Recording& rec, std::size_t block) {
  std::vector<std::vector<io::AnySample>> per(io::kNumStreams);
  io::forEachInTimeOrder(rec, [&](const io::AnySample& s) { per[s.index()].push_back(s); });
  std::vector<io::AnySample> out;
  std::vector<std::size_t> at(io::kNumStreams, 0);
  for (bool more = true; more;) {
    more = false;
    for (int k = 0; k < io::kNumStreams; ++k)
      for (std::size_t i = 0; i < block && at[k] < per[k].size(); ++i, more = true)
        out.push_back(per[k][at[k]++]);
  }
  return out;
}

}  // namespace

TEST(StreamedRun, TimeOrderedWriterGivesWriteRawlogsBytes) {
  wheelchair::test::TempDir dir;
  const config::WheelchairConfig cfg;
  const io::Recording rec = wheelchair::test::syntheticRecording(6.0);
  io::writeRawlog(rec, dir / "ref.rawlog", cfg);
  const std::vector<io::StreamKind> streams = {io::StreamKind::Encoders, io::StreamKind::Imu,
                                               io::StreamKind::Motors,   io::StreamKind::Sonar,
                                               io::StreamKind::Pozyx,    io::StreamKind::Joystick};
  for (std::size_t block : {1u, 7u, 500u}) {
    const std::string path = dir / ("s" + std::to_string(block) + ".rawlog");
    io::TimeOrderedRawlogWriter w(path, cfg, streams);
    w.setMeta(rec.meta);
    for (const auto& s : interleaved(rec, block)) w.add(s);
    w.commit();
    EXPECT_TRUE(bytes(path) == bytes(dir / "ref.rawlog")) << "block " << block;
    EXPECT_EQ(w.counts()[int(io::StreamKind::Imu)], rec.imu.size());
  }
  // A stream whose second sample is earlier than every first one: the header time chosen
  // early is wrong, so nothing is written.
  io::Recording bad;
  bad.encoders = {{2.0, 1, 1}, {0.5, 2, 2}};
  bad.imu = {{1.0, 0.1}};
  const std::string path = dir / "bad.rawlog";
  {
    io::TimeOrderedRawlogWriter w(path, cfg, {io::StreamKind::Encoders, io::StreamKind::Imu});
    w.add(bad.encoders[0]);
    w.add(bad.imu[0]);
    w.add(bad.encoders[1]);
    EXPECT_THROW(w.commit(), io::TimeOrderedRawlogWriter::HeaderTimeMismatch);
  }
  EXPECT_FALSE(std::filesystem::exists(path));
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()),
                          std::filesystem::directory_iterator()),
            4);  // ref + three streamed files, no temporary
}

TEST(StreamedRun, SimulateToFilesGivesTheInMemoryBytes) {
  wheelchair::test::TempDir dir;
  const config::WheelchairConfig cfg;
  simulation::SimulationOptions opt;
  opt.loadFromConfig(cfg.ini(), "simulation");
  opt.record_ground_truth = true;
  const std::vector<effects::EffectSpec> effects = {
      effects::parseEffect("sonar_dropout:probability=0.15,burst_length=3")};
  const auto ref = simulation::simulate(cfg, "three_task", 4, 12, effects, opt);
  io::writeRawlog(ref.recording, dir / "ref.rawlog", cfg);
  ref.writeTruth(dir / "ref.truth.json");
  ref.writeTruth(dir / "ref.truth.csv");
  // Truth kept in memory (default), and spilled to the scratch file after 100 samples.
  for (std::size_t in_memory : {std::size_t(200000), std::size_t(100)}) {
    for (const std::string truth : {"t.truth.json", "t.truth.csv"}) {
      const auto run = simulation::simulateToFiles(cfg, "three_task", 4, 12, effects, opt,
                                                   dir / "s.rawlog", dir / truth, in_memory);
      EXPECT_TRUE(bytes(dir / "s.rawlog") == bytes(dir / "ref.rawlog")) << in_memory;
      EXPECT_TRUE(bytes(dir / truth) == bytes(dir / ("ref" + truth.substr(1)))) << truth;
      EXPECT_TRUE(run.result.recording.encoders.empty());
      ASSERT_EQ(run.result.truth.samples.size(), 1u);
      EXPECT_EQ(run.result.truth.samples.back().x_m, ref.truth.samples.back().x_m);
      EXPECT_EQ(run.counts[int(io::StreamKind::Sonar)], ref.recording.sonar.size());
      EXPECT_EQ(run.counts[int(io::StreamKind::GroundTruth)], ref.recording.ground_truth.size());
    }
  }
}
