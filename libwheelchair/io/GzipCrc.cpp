#include "libwheelchair/io/GzipCrc.h"

#include <zlib.h>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define WHEELCHAIR_CLMUL_CRC 1
#else
#define WHEELCHAIR_CLMUL_CRC 0
#endif

namespace wheelchair::io {

namespace {

#if WHEELCHAIR_CLMUL_CRC
#define WHEELCHAIR_CLMUL __attribute__((target("pclmul,sse4.1")))

WHEELCHAIR_CLMUL inline __m128i load(const unsigned char* p) {
  return _mm_loadu_si128(reinterpret_cast<const __m128i*>(p));
}
// a * k (low and high halves, carry-less) + b: one 128-bit fold.
WHEELCHAIR_CLMUL inline __m128i fold(__m128i a, __m128i k, __m128i b) {
  return _mm_xor_si128(_mm_xor_si128(_mm_clmulepi64_si128(a, k, 0x11), b),
                       _mm_clmulepi64_si128(a, k, 0x00));
}

// CRC-32 of buf[0, len) in the pre- and post-inverted form (the register zlib keeps:
// ~crc in, ~result out), for len >= 64 and a multiple of 16.
WHEELCHAIR_CLMUL std::uint32_t foldCrc(const unsigned char* buf, std::size_t len,
                                       std::uint32_t crc) {
  // x^(4*128+32) and x^(4*128-32) mod P (fold by 64 bytes), x^(128+32) and x^(128-32) (by 16),
  // x^64 mod P (128 -> 64 bits), P' and mu = x^64 / P for the Barrett step; all bit-reflected.
  const __m128i k1k2 = _mm_set_epi64x(0x01c6e41596LL, 0x0154442bd4LL);
  const __m128i k3k4 = _mm_set_epi64x(0x00ccaa009eLL, 0x01751997d0LL);
  const __m128i k5k0 = _mm_set_epi64x(0, 0x0163cd6124LL);
  const __m128i poly = _mm_set_epi64x(0x01f7011641LL, 0x01db710641LL);
  __m128i x1 = _mm_xor_si128(load(buf), _mm_cvtsi32_si128(static_cast<int>(crc)));
  __m128i x2 = load(buf + 16), x3 = load(buf + 32), x4 = load(buf + 48);
  buf += 64;
  len -= 64;
  for (; len >= 64; buf += 64, len -= 64) {
    x1 = fold(x1, k1k2, load(buf));
    x2 = fold(x2, k1k2, load(buf + 16));
    x3 = fold(x3, k1k2, load(buf + 32));
    x4 = fold(x4, k1k2, load(buf + 48));
  }
  x1 = fold(x1, k3k4, x2);
  x1 = fold(x1, k3k4, x3);
  x1 = fold(x1, k3k4, x4);
  for (; len >= 16; buf += 16, len -= 16) x1 = fold(x1, k3k4, load(buf));
  // 128 -> 64 bits.
  const __m128i mask32 = _mm_setr_epi32(~0, 0, ~0, 0);
  x1 = _mm_xor_si128(_mm_srli_si128(x1, 8), _mm_clmulepi64_si128(x1, k3k4, 0x10));
  x1 = _mm_xor_si128(_mm_clmulepi64_si128(_mm_and_si128(x1, mask32), k5k0, 0x00),
                     _mm_srli_si128(x1, 4));
  // Barrett reduction to 32 bits.
  __m128i t = _mm_clmulepi64_si128(_mm_and_si128(x1, mask32), poly, 0x10);
  t = _mm_clmulepi64_si128(_mm_and_si128(t, mask32), poly, 0x00);
  return static_cast<std::uint32_t>(_mm_extract_epi32(_mm_xor_si128(x1, t), 1));
}

// (Before this initialiser runs, e.g. from another static constructor, zlib's path is used.)
const bool kClmul = [] {
  __builtin_cpu_init();
  return __builtin_cpu_supports("pclmul") && __builtin_cpu_supports("sse4.1");
}();
#endif

}  // namespace

bool gzipCrc32IsAccelerated() {
#if WHEELCHAIR_CLMUL_CRC
  return kClmul;
#else
  return false;
#endif
}

std::uint32_t gzipCrc32(std::uint32_t crc, const unsigned char* buf, std::size_t len) {
  if (buf == nullptr) return 0;  // zlib's answer for a null buffer
#if WHEELCHAIR_CLMUL_CRC
  if (len >= 64 && kClmul) {
    const std::size_t blocks = len & ~static_cast<std::size_t>(15);
    crc = ~foldCrc(buf, blocks, ~crc);
    buf += blocks;
    len -= blocks;
    if (len == 0) return crc;
  }
#endif
  return static_cast<std::uint32_t>(crc32_z(crc, buf, len));
}

}  // namespace wheelchair::io

// zlib's entry point, called by inflate() and deflate() through their PLT (see the header).
// zlib masks the CRC to 32 bits.
extern "C" uLong crc32(uLong crc, const Bytef* buf, uInt len) {
  return wheelchair::io::gzipCrc32(static_cast<std::uint32_t>(crc & 0xffffffffUL), buf, len);
}
