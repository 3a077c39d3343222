// gzip helpers for tests, with zlib (an independent implementation of the format the
// library's reader inflates with ISA-L).
#pragma once

#include <zlib.h>

#include <string>

namespace wheelchair::test {

/// The uncompressed content of a gzip file (every member), as zlib's gzread gives it.
inline std::string gunzip(const std::string& path) {
  gzFile f = gzopen(path.c_str(), "rb");
  std::string out;
  if (!f) return out;
  char buf[1 << 16];
  int n;
  while ((n = gzread(f, buf, sizeof buf)) > 0) out.append(buf, static_cast<std::size_t>(n));
  gzclose(f);
  return out;
}

/// Writes `data` to `path` as one gzip member (level 1).
inline void gzipTo(const std::string& path, const std::string& data) {
  gzFile f = gzopen(path.c_str(), "wb1");
  gzwrite(f, data.data(), static_cast<unsigned>(data.size()));
  gzclose(f);
}

}  // namespace wheelchair::test
