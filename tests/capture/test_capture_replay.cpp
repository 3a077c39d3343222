// The whole capture path without hardware: a formula-generated recording is replayed into
// pseudo-terminals (SerialReplayer) in the sources' line formats, captured (CaptureSession)
// and compared, value by value and timestamp by timestamp, with the original - also with
// the faults of issue 8: garbage lines, a device absent at start, an unplug/replug.
#include "CaptureTestUtil.h"

#include "libwheelchair/capture/CaptureSession.h"
#include "libwheelchair/capture/SerialReplayer.h"

#include <atomic>

using namespace wheelchair;
using wheelchair::test::TempDir;

namespace {

struct ScenarioResult {
  capture::ReplayReport replay;
  std::vector<capture::SourceStatus> status;
  std::vector<capture::CaptureEvent> events;
  io::Recording captured;
  io::RawlogReadReport read;
  io::Recording expected;
  std::size_t late = 0;
  std::string log;
};

const capture::ReplaySourceReport& replayOf(const ScenarioResult& r, const std::string& section) {
  for (const auto& s : r.replay.sources)
    if (s.section == section) return s;
  throw std::runtime_error("no source " + section);
}

const capture::SourceStatus& statusOf(const ScenarioResult& r, const std::string& section) {
  for (const auto& s : r.status)
    if (s.section == section) return s;
  throw std::runtime_error("no source " + section);
}

bool hasEvent(const ScenarioResult& r, const std::string& section, const std::string& text) {
  for (const auto& e : r.events)
    if (e.source == section && e.text.find(text) != std::string::npos) return true;
  return false;
}

// Replays `rec` (written as a text recording) into the capture and reads the result back.
ScenarioResult runScenario(const TempDir& tmp, const io::Recording& rec,
                           capture::ReplayOptions ro) {
  ScenarioResult res;
  const std::string dir = tmp / "recording";
  io::writeTextRecording(rec, dir);
  res.expected = test::importedOriginal(dir, tmp);
  ro.recording = dir;
  ro.capture_config = test::writeTestCaptureConfig(tmp);
  ro.link_dir = tmp / "dev";
  ro.derived_config = tmp / "capture-replay.ini";
  if (ro.start_delay_s == 0) ro.start_delay_s = 0.3;  // let the sources connect first
  capture::SerialReplayer replayer(ro);
  replayer.setup();

  capture::CaptureOptions co;
  co.config_path = ro.derived_config;
  co.output = tmp / "captured.rawlog";
  co.status_out = nullptr;
  capture::CaptureSession session(co);
  std::atomic<bool> stop{false};
  int rc = -1;
  std::thread th([&] { rc = session.run(&stop); });
  res.replay = replayer.run();
  test::sleepFor(0.3);  // the last lines reach the capture
  stop = true;
  th.join();
  replayer.close();
  EXPECT_EQ(rc, 0) << session.error();
  res.status = session.status();
  res.events = session.events();
  res.late = session.lateRecords();
  res.log = test::readFile(session.logPath());
  res.captured = io::readRawlog(co.output, &res.read, true);
  EXPECT_FALSE(res.read.broken.has_value());
  return res;
}

}  // namespace

TEST(CaptureReplay, EveryValueAndTimestampArrivesExactlyOnce) {
  WHEELCHAIR_REQUIRE_PTYS();
  TempDir tmp;
  capture::ReplayOptions ro;
  ro.speed = 8;
  const auto rec = test::captureRecording(4.0);
  auto r = runScenario(tmp, rec, ro);
  test::expectSameRecording(r.expected, r.captured);
  EXPECT_EQ(r.captured.meta.at("operator"), "unknown");  // [recording] of the capture INI
  EXPECT_NE(r.read.header_text.find("[vehicle]"), std::string::npos);
  EXPECT_EQ(r.late, 0u);
  for (const auto& s : r.replay.sources) {
    EXPECT_EQ(s.inexact, 0u) << s.section;
    EXPECT_EQ(s.dropped_overflow, 0u) << s.section;
  }
  for (const auto& s : r.status) {
    EXPECT_EQ(s.garbage, 0u) << s.section << " " << s.last_garbage;
    EXPECT_EQ(s.connects, 1u) << s.section;
  }
  // Written in timestamp order (what io::forEachInTimeOrder of the original gives).
  io::RawlogReader in(tmp / "captured.rawlog");
  mrpt::serialization::CSerializable::Ptr obj;
  double last = 0;
  std::size_t n = 0;
  while (in.next(obj)) {
    auto o = std::dynamic_pointer_cast<mrpt::obs::CObservation>(obj);
    ASSERT_TRUE(o);
    const double t = mrpt::Clock::toDouble(o->timestamp);
    if (n++ > 0) EXPECT_GE(t, last);
    last = t;
  }
  EXPECT_EQ(n, rec.size() + 1);  // + the META header
}

TEST(CaptureReplay, GarbageAndPartialLinesAreCountedAndSkipped) {
  WHEELCHAIR_REQUIRE_PTYS();
  TempDir tmp;
  capture::ReplayOptions ro;
  ro.speed = 8;
  ro.garbage_every = 7;  // noise, cut lines, non-numbers, overlong lines in turn
  auto r = runScenario(tmp, test::captureRecording(3.0), ro);
  test::expectSameRecording(r.expected, r.captured);
  for (const auto& s : r.replay.sources) {
    EXPECT_GE(s.garbage, 4u) << s.section;  // every kind at least once
    EXPECT_EQ(statusOf(r, s.section).garbage, s.garbage) << s.section;
  }
  EXPECT_TRUE(hasEvent(r, "imu", "skipped malformed line"));
  EXPECT_NE(r.log.find("skipped malformed line"), std::string::npos);
}

TEST(CaptureReplay, DeviceAbsentAtStartIsPickedUpWhenItAppears) {
  WHEELCHAIR_REQUIRE_PTYS();
  TempDir tmp;
  capture::ReplayOptions ro;
  ro.speed = 4;
  ro.outages = {capture::parseOutage("imu@0+1.2")};  // the IMU is plugged in 1.2 s late
  auto r = runScenario(tmp, test::captureRecording(3.0), ro);
  const auto& imu = replayOf(r, "imu");
  EXPECT_GT(imu.dropped_unplugged, 100u);
  // The other sources did not wait for it: complete and exact.
  for (auto k : {io::StreamKind::Encoders, io::StreamKind::Motors, io::StreamKind::Sonar,
                 io::StreamKind::Pozyx, io::StreamKind::Joystick})
    test::expectSameStream(r.expected, r.captured, k);
  // The IMU: everything it sent once it appeared.
  io::Recording expected_imu;
  // (The replay's times are the text's; the expected ones went through MRPT's 100 ns clock.)
  for (const auto& s : r.expected.imu)
    if (std::none_of(imu.dropped_times.begin(), imu.dropped_times.end(),
                     [&](double t) { return std::abs(t - s.t_s) < 1e-5; }))
      expected_imu.imu.push_back(s);
  io::Recording got_imu;
  got_imu.imu = r.captured.imu;
  test::expectSameStream(expected_imu, got_imu, io::StreamKind::Imu);
  EXPECT_TRUE(hasEvent(r, "imu", "No such file or directory"));
  EXPECT_TRUE(hasEvent(r, "imu", "connected to"));
  EXPECT_EQ(statusOf(r, "imu").connects, 1u);
}

TEST(CaptureReplay, UnplugReplugLogsTheGapAndLeavesOtherSourcesAlone) {
  WHEELCHAIR_REQUIRE_PTYS();
  TempDir tmp;
  capture::ReplayOptions ro;
  ro.speed = 4;
  ro.outages = {capture::parseOutage("imu@1.0+0.6")};
  auto r = runScenario(tmp, test::captureRecording(3.0), ro);
  for (auto k : {io::StreamKind::Encoders, io::StreamKind::Motors, io::StreamKind::Sonar,
                 io::StreamKind::Pozyx, io::StreamKind::Joystick})
    test::expectSameStream(r.expected, r.captured, k);
  const auto& imu = replayOf(r, "imu");
  EXPECT_EQ(imu.ptys, 2u);
  ASSERT_GT(imu.dropped_unplugged, 40u);
  const double gap_begin = imu.dropped_times.front(), gap_end = imu.dropped_times.back();
  // (1e-5 s tolerances: the replay's times are the text's, the expected ones went through
  // MRPT's 100 ns clock and differ by an ulp.)
  // IMU: the original minus one contiguous block that holds the outage. Lines the replay sent
  // just before pulling the cable may be lost with it (a hang-up discards unread input);
  // nothing after the replug is lost.
  const auto& e = r.expected.imu;
  const auto& g = r.captured.imu;
  std::size_t i = 0, j = 0;
  while (i < e.size() && j < g.size() && e[i].t_s == g[j].t_s) ++i, ++j;
  const std::size_t missing_begin = i;
  while (i < e.size() && (j >= g.size() || e[i].t_s != g[j].t_s)) ++i;
  ASSERT_LT(missing_begin, e.size());
  EXPECT_LE(e[missing_begin].t_s, gap_begin);
  EXPECT_GE(e[missing_begin].t_s, gap_begin - 0.25) << "lost more than the lines in flight";
  EXPECT_GT(e[i - 1].t_s, gap_end - 1e-5)
      << fmt::format("missing {:.4f}..{:.4f}, outage {:.4f}..{:.4f}", e[missing_begin].t_s,
                     e[i - 1].t_s, gap_begin, gap_end);
  EXPECT_LT(e[i - 1].t_s, gap_end + 1e-5) << "lost lines after the replug";
  io::Recording e_rest, g_rest;
  e_rest.imu.assign(e.begin() + i, e.end());
  g_rest.imu.assign(g.begin() + j, g.end());
  test::expectSameStream(e_rest, g_rest, io::StreamKind::Imu);
  // Logged: the hang-up, the reconnection, the gap with its extent.
  const auto& st = statusOf(r, "imu");
  EXPECT_EQ(st.disconnects, 1u);
  EXPECT_EQ(st.connects, 2u);
  EXPECT_EQ(st.gaps, 1u);
  EXPECT_TRUE(hasEvent(r, "imu", "disconnected from"));
  EXPECT_TRUE(hasEvent(r, "imu", "gap in IMU data"));
  EXPECT_NE(r.log.find("gap in IMU data"), std::string::npos);
  for (const char* other : {"motors", "encoders", "sonar", "pozyx", "joystick"})
    EXPECT_EQ(statusOf(r, other).disconnects, 0u) << other;
}
