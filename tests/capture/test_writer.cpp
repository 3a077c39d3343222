// Continuous rawlog writing (RawlogAppender: one complete gzip member per flush) and the
// merge of the sources in timestamp order (MergeBuffer).
#include "CaptureTestUtil.h"

#include "libwheelchair/capture/HostClock.h"
#include "libwheelchair/capture/MergeBuffer.h"
#include "libwheelchair/capture/RawlogAppender.h"

#include <filesystem>

using namespace wheelchair;
using namespace wheelchair::capture;
using wheelchair::test::TempDir;

namespace {

mrpt::obs::CObservation::Ptr obsAt(const io::AnySample& s) {
  return io::toObservation(s, config::WheelchairConfig());
}

}  // namespace

TEST(Writer, Crc32OfTheCheckString) {
  EXPECT_EQ(crc32("123456789", 9), 0xCBF43926u);
}

TEST(Writer, EachFlushIsACompleteMemberAndEveryCutReadsAsAPrefix) {
  TempDir tmp;
  const std::string path = tmp / "a.rawlog";
  const auto rec = test::captureRecording(1.0);
  std::vector<io::AnySample> all;
  io::forEachInTimeOrder(rec, [&](const io::AnySample& s) { all.push_back(s); });
  std::vector<uint64_t> member_ends;
  {
    RawlogAppender::Options o;
    o.fsync = false;
    RawlogAppender w(path, o);
    for (std::size_t i = 0; i < all.size(); ++i) {
      w.write(*obsAt(all[i]));
      if (i % 100 == 99) {
        w.flush();
        member_ends.push_back(w.bytesOnDisk());
        EXPECT_EQ(w.recordsOnDisk(), i + 1);
        // Readable while being written: exactly what was flushed, no error.
        io::RawlogReadReport rep;
        const auto so_far = io::readRawlog(path, &rep, true);
        EXPECT_FALSE(rep.broken.has_value());
        EXPECT_EQ(so_far.size(), i + 1);
      }
    }
    w.close();
    member_ends.push_back(w.bytesOnDisk());
  }
  EXPECT_THROW(RawlogAppender(path, RawlogAppender::Options{}), WriteError);  // no silent overwrite
  const std::string full = test::readFile(path);
  const auto whole = io::readRawlog(path);  // the original through MRPT's clock and floats
  ASSERT_EQ(whole.size(), all.size());
  // A file cut anywhere (power cut mid-write) reads as a prefix; the break is reported.
  std::size_t last_count = 0;
  for (std::size_t cut = 0; cut <= full.size(); cut += std::max<std::size_t>(1, full.size() / 97)) {
    const std::string p = tmp / "cut.rawlog";
    test::writeFile(p, full.substr(0, cut));
    io::RawlogReadReport rep;
    io::Recording got;
    ASSERT_NO_THROW(got = io::readRawlog(p, &rep, true)) << "cut at " << cut;
    EXPECT_GE(got.size(), last_count) << "cut at " << cut;
    last_count = got.size();
    const bool at_member_end =
        cut == 0 || std::count(member_ends.begin(), member_ends.end(), cut) > 0;
    if (at_member_end) EXPECT_FALSE(rep.broken.has_value()) << "cut at " << cut;
    test::expectPrefix(whole, got);
    // Every record of every complete member is there.
    std::size_t complete = 0;
    for (std::size_t m = 0; m < member_ends.size(); ++m)
      if (member_ends[m] <= cut) complete = std::min<std::size_t>((m + 1) * 100, all.size());
    EXPECT_GE(got.size(), complete) << "cut at " << cut;
  }
}

TEST(Writer, FlushPeriodIsHonoured) {
  TempDir tmp;
  RawlogAppender::Options o;
  o.flush_period_s = 0.2;
  o.fsync = false;
  RawlogAppender w(tmp / "a.rawlog", o);
  w.write(*obsAt(io::SonarSample{1.0, 2.0}));
  EXPECT_FALSE(w.flushIfDue(HostClock::monotonic()));
  test::sleepFor(0.25);
  EXPECT_TRUE(w.flushIfDue(HostClock::monotonic()));
  EXPECT_EQ(w.recordsOnDisk(), 1u);
  EXPECT_THROW(RawlogAppender(tmp / "b.rawlog", RawlogAppender::Options{1, 2.0}), WriteError);
}

TEST(Writer, MergeOrdersByTimestampWithinTheWindowAndKeepsEachSourcesOrder) {
  MergeBuffer m(3, {1, 0, 2}, 0.5);
  std::vector<std::pair<std::size_t, double>> out;
  auto sink = [&](std::size_t src, const mrpt::obs::CObservation& o) {
    out.emplace_back(src, mrpt::Clock::toDouble(o.timestamp));
  };
  m.push(0, obsAt(io::ImuSample{10.03, 0}), 0.0);
  m.push(0, obsAt(io::ImuSample{10.01, 0}), 0.0);  // a device clock going back: kept in order
  m.push(1, obsAt(io::EncoderSample{10.02, 0, 0}), 0.1);
  m.push(2, obsAt(io::SonarSample{10.02, 1}), 0.1);
  EXPECT_EQ(m.release(0.3, false, sink), 0u);  // nothing has waited 0.5 s yet
  m.push(1, obsAt(io::EncoderSample{10.00, 0, 0}), 0.4);
  EXPECT_EQ(m.release(0.55, false, sink), 0u);  // 10.00 (source 1) is the earliest and young
  EXPECT_EQ(m.release(0.95, false, sink), 5u);
  const std::vector<std::pair<std::size_t, double>> want = {
      {1, 10.02}, {1, 10.00}, {2, 10.02}, {0, 10.03}, {0, 10.01}};
  // Source 1 first: its head 10.02 ties with source 2's 10.02 and ranks first (ENCODERS).
  ASSERT_EQ(out.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) {
    EXPECT_EQ(out[i].first, want[i].first) << i;
    EXPECT_NEAR(out[i].second, want[i].second, 1e-6) << i;
  }
  EXPECT_EQ(m.late(1), 1u);
  EXPECT_EQ(m.late(0), 1u);
  m.push(2, obsAt(io::SonarSample{11.0, 1}), 1.0);
  EXPECT_EQ(m.release(1.0, true, sink), 1u);  // drain at the end
}
