// Process-wide memory settings for the commands that hold a long drive's arrays.
//
// returnLargeBlocksToSystem(): every heap block of at least `threshold_bytes` (default 1 MB)
// gets its own mapping, given back to the system when it is freed. glibc's default raises that
// threshold with every such block freed, up to 32 MB, after which a long drive's arrays (a
// stage's streams, rows and designs, 1-30 MB each) come from the shared heap: what one stage
// frees there stays resident and fragmented while the next one grows. Measured on
// `wheelchair diagnose` (docs/benchmarks.md, "Memory"): peak RSS of a one-hour drive 200-212
// -> 196 MB, ten hours 1037-1047 -> 1023 MB, for more system time (page faults of fresh
// mappings: +0.3 s on one hour, 11.5 -> 28 s on ten hours; total CPU time +8 %).
// No effect (and no error) with another C library.
//
// Example: at the start of a command, before reading its input:
//   util::returnLargeBlocksToSystem();
#pragma once

#include <cstddef>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace wheelchair::util {

inline void returnLargeBlocksToSystem(std::size_t threshold_bytes = 1024 * 1024) {
#if defined(__GLIBC__)
  mallopt(M_MMAP_THRESHOLD, static_cast<int>(threshold_bytes));
#else
  (void)threshold_bytes;
#endif
}

}  // namespace wheelchair::util
