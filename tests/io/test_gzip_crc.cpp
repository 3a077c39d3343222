// io/GzipCrc: the carry-less-multiplication CRC-32 gives zlib's values, and it is the crc32()
// zlib's inflate/deflate call (gzip round trips pass, a damaged trailer is still detected).
#include "libwheelchair/io/GzipCrc.h"

#include <dlfcn.h>
#include <zlib.h>

#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <vector>

namespace {

using wheelchair::io::gzipCrc32;

std::vector<unsigned char> randomBytes(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::vector<unsigned char> v(n);
  for (auto& b : v) b = static_cast<unsigned char>(rng());
  return v;
}

// zlib's own crc32_z (not interposed: the program replaces crc32 only).
std::uint32_t zlibCrc(std::uint32_t crc, const unsigned char* p, std::size_t n) {
  return static_cast<std::uint32_t>(crc32_z(crc, p, n));
}

TEST(GzipCrc, GivesZlibsValueForEveryLengthAlignmentAndStart) {
  const auto data = randomBytes(1200, 1);
  std::mt19937 rng(2);
  for (std::size_t off = 0; off < 16; ++off) {
    for (std::size_t n = 0; n + off <= 1100 + 16 && n <= 1100; ++n) {
      const std::uint32_t start = off % 3 == 0 ? 0 : static_cast<std::uint32_t>(rng());
      ASSERT_EQ(gzipCrc32(start, data.data() + off, n), zlibCrc(start, data.data() + off, n))
          << "offset " << off << " length " << n;
    }
  }
  for (unsigned seed = 0; seed < 20; ++seed) {  // large blocks, in pieces as inflate passes them
    const auto big = randomBytes(1 + (seed * 52361) % (1 << 20), seed);
    std::uint32_t a = 0, b = 0;
    for (std::size_t at = 0; at < big.size();) {
      const std::size_t n = std::min<std::size_t>(big.size() - at, 1 + rng() % 70000);
      a = gzipCrc32(a, big.data() + at, n);
      b = zlibCrc(b, big.data() + at, n);
      at += n;
    }
    ASSERT_EQ(a, b) << seed;
  }
  // The check value of the CRC-32 catalogue; all-zero and all-one blocks.
  const char* check = "123456789";
  EXPECT_EQ(gzipCrc32(0, reinterpret_cast<const unsigned char*>(check), 9), 0xCBF43926u);
  const std::vector<unsigned char> zeros(4096, 0), ones(4096, 0xff);
  EXPECT_EQ(gzipCrc32(0, zeros.data(), zeros.size()), zlibCrc(0, zeros.data(), zeros.size()));
  EXPECT_EQ(gzipCrc32(0, ones.data(), ones.size()), zlibCrc(0, ones.data(), ones.size()));
  EXPECT_EQ(gzipCrc32(123, nullptr, 10), 0u);  // zlib: a null buffer gives 0
}

TEST(GzipCrc, IsTheCrc32ThatZlibCalls) {
  // The program's definition is found first (zlib's inflate/deflate bind to it), zlib's next.
  void* first = dlsym(RTLD_DEFAULT, "crc32");
  void* next = dlsym(RTLD_NEXT, "crc32");
  ASSERT_NE(first, nullptr);
  ASSERT_NE(next, nullptr);
  EXPECT_NE(first, next);
  EXPECT_EQ(first, reinterpret_cast<void*>(&::crc32));
  std::printf("carry-less multiplication path: %s\n",
              wheelchair::io::gzipCrc32IsAccelerated() ? "yes" : "no (zlib's tables)");
}

TEST(GzipCrc, GzipRoundTripsAndDetectsADamagedTrailer) {
  const auto data = randomBytes(300000, 7);
  z_stream z{};
  ASSERT_EQ(deflateInit2(&z, 1, Z_DEFLATED, 16 + 15, 8, Z_DEFAULT_STRATEGY), Z_OK);  // gzip
  std::vector<unsigned char> gz(deflateBound(&z, data.size()) + 64);
  z.next_in = const_cast<unsigned char*>(data.data());
  z.avail_in = static_cast<uInt>(data.size());
  z.next_out = gz.data();
  z.avail_out = static_cast<uInt>(gz.size());
  ASSERT_EQ(deflate(&z, Z_FINISH), Z_STREAM_END);
  gz.resize(z.total_out);
  deflateEnd(&z);
  // The trailer's CRC (little-endian, 8 bytes from the end) is zlib's value of the data.
  std::uint32_t stored = 0;
  for (int i = 3; i >= 0; --i) stored = (stored << 8) | gz[gz.size() - 8 + i];
  EXPECT_EQ(stored, zlibCrc(0, data.data(), data.size()));
  const auto inflateAll = [&data](const std::vector<unsigned char>& in) {
    z_stream s{};
    EXPECT_EQ(inflateInit2(&s, 16 + 15), Z_OK);
    std::vector<unsigned char> out(data.size() + 16);
    s.next_in = const_cast<unsigned char*>(in.data());
    s.avail_in = static_cast<uInt>(in.size());
    s.next_out = out.data();
    s.avail_out = static_cast<uInt>(out.size());
    const int r = inflate(&s, Z_FINISH);
    inflateEnd(&s);
    return r;
  };
  EXPECT_EQ(inflateAll(gz), Z_STREAM_END);
  auto damaged = gz;
  damaged[damaged.size() - 6] ^= 0x10;  // one bit of the stored CRC
  EXPECT_EQ(inflateAll(damaged), Z_DATA_ERROR);
}

}  // namespace
