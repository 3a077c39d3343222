// zlib's crc32() with carry-less multiplication (PCLMULQDQ), for the gzip trailer check of
// every rawlog read and written.
//
// Inflating a rawlog computes the CRC-32 of every decompressed byte (the gzip member's
// check value); zlib 1.2.13 does it byte-serially with tables (~0.7 cycles a byte: ~1.4 % of a
// one-hour `wheelchair filter`, docs/benchmarks.md, "Eleventh round"). zlib's inflate and
// deflate call crc32() through their PLT, so the definition in GzipCrc.cpp, linked into the
// program, is the one they use (ELF interposition, as estimation/SundialsDispatch.cpp does for
// SUNDIALS). The CRC is a pure function of the bytes, so the value is the same; only the method
// differs: blocks of 64 bytes are folded 4 x 128 bits at a time by multiplication with x^k mod
// P(x) in GF(2) (Gopal et al., "Fast CRC computation for generic polynomials using PCLMULQDQ",
// Intel 2009; the bit-reflected constants for P = 0x04C11DB7), then reduced to 32 bits by
// Barrett reduction; lengths below 64, the last len % 16 bytes and CPUs without PCLMULQDQ and
// SSE4.1 go to zlib's own crc32_z. tests/io/test_gzip_crc.cpp compares it with zlib's on every
// length 0-1100 at every alignment and on random blocks of up to 1 MB.
#pragma once

#include <cstddef>
#include <cstdint>

namespace wheelchair::io {

/// CRC-32 (gzip/zlib polynomial) of buf[0, len) continuing `crc` (0 to start), as zlib's
/// crc32_z(crc, buf, len): the value every rawlog's gzip trailer holds.
std::uint32_t gzipCrc32(std::uint32_t crc, const unsigned char* buf, std::size_t len);

/// Whether gzipCrc32 uses the carry-less multiplication path on this CPU.
bool gzipCrc32IsAccelerated();

}  // namespace wheelchair::io
