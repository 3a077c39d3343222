// The rawlog reader's gzip layer (ISA-L's inflate): files of several gzip members (what
// capture appends, one member per flush) read as their concatenated data, as zlib's gzread
// reads them; a wrong trailer CRC-32 or length is damage, after every intact record.
#include "../common/GzipUtil.h"
#include "../common/TestUtil.h"
#include "SyntheticRecording.h"

#include "libwheelchair/io/RawlogIO.h"

#include <gtest/gtest.h>

using namespace wheelchair;
using wheelchair::test::TempDir;

namespace {

/// A gzip rawlog of a recording long enough to span several 128 KiB input blocks and 256 KiB
/// output buffers; its uncompressed bytes in `*raw`.
std::string gzipRawlog(const TempDir& tmp, const io::Recording& rec, std::string* raw) {
  const std::string path = tmp / "one.rawlog";
  io::writeRawlog(rec, path, config::WheelchairConfig());
  *raw = test::gunzip(path);
  return path;
}

void expectSameSamples(const io::Recording& a, const io::Recording& b) {
  ASSERT_EQ(a.size(), b.size());
  ASSERT_EQ(a.encoders.size(), b.encoders.size());
  for (std::size_t i = 0; i < a.encoders.size(); ++i) {
    EXPECT_EQ(a.encoders[i].t_s, b.encoders[i].t_s);
    EXPECT_EQ(a.encoders[i].left_ticks, b.encoders[i].left_ticks);
  }
  ASSERT_EQ(a.motors.size(), b.motors.size());
  for (std::size_t i = 0; i < a.motors.size(); ++i)
    EXPECT_EQ(a.motors[i].current_left_A, b.motors[i].current_left_A);
  EXPECT_EQ(a.meta, b.meta);
}

}  // namespace

TEST(RawlogGzip, SeveralMembersReadAsTheirConcatenation) {
  TempDir tmp;
  const auto rec = test::syntheticRecording(60.0);
  std::string raw;
  const auto one = gzipRawlog(tmp, rec, &raw);
  ASSERT_GT(raw.size(), std::size_t{1} << 19);
  const auto expected = io::readRawlog(one);
  ASSERT_EQ(expected.size(), rec.size());
  // Members split at arbitrary bytes (mid-record), one of them empty, one a single byte.
  const std::size_t k1 = raw.size() / 3 + 11, k2 = k1 + 1;
  std::string multi;
  for (const auto& part :
       {raw.substr(0, k1), std::string(), raw.substr(k1, k2 - k1), raw.substr(k2)}) {
    test::gzipTo(tmp / "member.gz", part);
    multi += test::readFile(tmp / "member.gz");
  }
  const std::string path = tmp / "multi.rawlog";
  test::writeFile(path, multi);
  expectSameSamples(io::readRawlog(path), expected);

  io::RawlogReader r(path);
  mrpt::serialization::CSerializable::Ptr obj;
  std::size_t n = 0;
  while (r.next(obj)) ++n;
  EXPECT_FALSE(r.error());
  EXPECT_EQ(n, expected.size() + 1);  // + the META header
  EXPECT_DOUBLE_EQ(r.fractionRead(), 1.0);

  // Bytes after the last member that do not start another one are ignored (as by gzread);
  // a cut inside the last member is a cut.
  test::writeFile(path, multi + std::string(5, '\0'));
  expectSameSamples(io::readRawlog(path), expected);
  test::writeFile(path, multi.substr(0, multi.size() - 100));
  io::RawlogReadReport rep;
  const auto part = io::readRawlog(path, &rep, true);
  ASSERT_TRUE(rep.broken);
  EXPECT_NE(rep.broken->what.find("file cut short: the gzip stream ends at uncompressed byte"),
            std::string::npos)
      << rep.broken->what;
  EXPECT_LT(part.size(), expected.size());
}

TEST(RawlogGzip, WrongTrailerCrcOrLengthIsDamageAfterTheIntactRecords) {
  TempDir tmp;
  const auto rec = test::syntheticRecording(20.0);
  std::string raw;
  const std::string good = test::readFile(gzipRawlog(tmp, rec, &raw));
  // The gzip trailer: CRC-32 (4 bytes), then the data length mod 2^32 (4 bytes).
  for (const std::size_t from_end : {8u, 5u, 4u}) {
    std::string bad = good;
    bad[bad.size() - from_end] ^= 0x01;
    const std::string path = tmp / "bad.rawlog";
    test::writeFile(path, bad);
    io::RawlogReadReport rep;
    const auto part = io::readRawlog(path, &rep, true);
    ASSERT_TRUE(rep.broken) << from_end;
    EXPECT_EQ(part.size(), rec.size()) << from_end;  // every record before the check is read
    EXPECT_EQ(rep.broken->what,
              "compressed data damaged at uncompressed byte " + std::to_string(raw.size()) +
                  " (inflate: incorrect data check (gzip trailer CRC-32 or length))")
        << from_end;
    EXPECT_THROW(io::readRawlog(path), std::runtime_error);
  }
}
