// An anonymous temporary file for data set aside while a long drive is processed (the memory of
// long drives, docs/benchmarks.md "Memory"): std::tmpfile, i.e. (glibc) an unnamed file in /tmp
// (O_TMPFILE, or one unlinked as soon as made; TMPDIR is not consulted). It has no name, so
// nothing is left behind when it is closed, on an error or after a crash. Made on the first
// append. Every write and read is checked: a failure (no temporary file can be made, /tmp is
// full, a file-size limit) throws std::runtime_error, one line naming `what`, the file and the
// system's reason, e.g.
//   "identify: the conditioned samples: temporary file (/tmp): cannot write: No space left on
//    device"
// Used by util::ScratchRecords (records appended and replayed) and util::SpilledColumns
// (columns set aside and restored).
//
// Example:
//   util::TempFile f("diagnose: the gyro streams");
//   const long at = f.append(v.data(), sizeof(double) * v.size());
//   f.read(at, v.data(), sizeof(double) * v.size());
#pragma once

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>

namespace wheelchair::util {

class TempFile {
 public:
  explicit TempFile(std::string what) : what_(std::move(what)) {}

  /// Writes `bytes` bytes at the end of the file (made if none yet); returns where they start.
  long append(const void* data, std::size_t bytes) {
    if (!f_) {
      f_.reset(std::tmpfile());
      if (!f_) fail("cannot create");
    }
    if (std::fseek(f_.get(), 0, SEEK_END) != 0) fail("cannot write");
    const long at = std::ftell(f_.get());
    if (at < 0) fail("cannot write");
    if (std::fwrite(data, 1, bytes, f_.get()) != bytes || std::fflush(f_.get()) != 0)
      fail("cannot write");
    return at;
  }
  /// Reads `bytes` bytes from offset `at` (written by append) into data.
  void read(long at, void* data, std::size_t bytes) {
    if (!f_ || std::fseek(f_.get(), at, SEEK_SET) != 0 ||
        std::fread(data, 1, bytes, f_.get()) != bytes)
      fail("cannot read back");
  }
  /// Closes the file (it is gone); the next append makes a new one.
  void close() { f_.reset(); }

  [[noreturn]] void fail(const char* how) const {
    const int e = errno;
    throw std::runtime_error(what_ + ": temporary file (/tmp): " + how + ": " +
                             (e ? std::strerror(e) : "unknown error"));
  }

 private:
  std::string what_;
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f_{nullptr, &std::fclose};
};

}  // namespace wheelchair::util
