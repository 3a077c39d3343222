// Columns (std::vector of a trivially copyable T, e.g. a stream's sample times in s) set aside
// in an anonymous temporary file while a phase of a computation does not read them, and read
// back bit for bit before the next phase that does (the memory of long drives,
// docs/benchmarks.md "Tenth round"). spill() writes a column and releases its memory;
// restore() reads every column spilled since the last restore() back into its vector (which
// must still exist, empty).
//
// The file: std::tmpfile, i.e. (glibc) an unnamed file in /tmp (O_TMPFILE, or one unlinked as
// soon as made); TMPDIR is not consulted. It has no name in /tmp, so nothing is left behind
// when it is closed, on an error or after a crash. Every write and read is checked: a failure (no
// temporary file can be made, /tmp is full, a file-size limit) throws std::runtime_error, one line
// naming `what`, the temporary file and the system's reason, e.g.
//   "diagnose: the fit parts' streams: temporary file (/tmp): cannot write: No space left on
//    device"
// A column whose write failed is still in its vector (nothing of it is lost).
//
// Example:
//   util::SpilledColumns idle("diagnose: the gyro streams");
//   idle.spill(streams.tg);       // streams.tg is empty now
//   ...                           // a phase that does not read streams.tg
//   idle.restore();               // streams.tg is back, the same values
#pragma once

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace wheelchair::util {

class SpilledColumns {
 public:
  explicit SpilledColumns(std::string what) : what_(std::move(what)) {}
  SpilledColumns(const SpilledColumns&) = delete;
  SpilledColumns& operator=(const SpilledColumns&) = delete;

  /// Writes v to the file and releases it (v empty). Throws (v unchanged) when it cannot.
  template <typename T>
  void spill(std::vector<T>& v) {
    static_assert(std::is_trivially_copyable_v<T>, "columns are written as bytes");
    if (v.empty()) return;
    if (!f_) {
      f_.reset(std::tmpfile());
      if (!f_) fail("cannot create");
    }
    if (std::fseek(f_.get(), 0, SEEK_END) != 0) fail("cannot write");
    const long at = std::ftell(f_.get());
    if (at < 0) fail("cannot write");
    if (std::fwrite(v.data(), sizeof(T), v.size(), f_.get()) != v.size() ||
        std::fflush(f_.get()) != 0)
      fail("cannot write");
    const std::size_t n = v.size();
    std::vector<T>().swap(v);
    read_.push_back([this, &v, at, n] {
      v.resize(n);
      if (std::fseek(f_.get(), at, SEEK_SET) != 0 ||
          std::fread(v.data(), sizeof(T), n, f_.get()) != n)
        fail("cannot read back");
    });
  }
  /// Every column spilled since the last restore() read back, in the order spilled.
  void restore() {
    for (auto& r : read_) r();
    read_.clear();
    f_.reset();  // the file is gone once closed
  }
  /// Columns on the file (not yet restored).
  std::size_t spilled() const { return read_.size(); }

 private:
  [[noreturn]] void fail(const char* how) const {
    const int e = errno;
    throw std::runtime_error(what_ + ": temporary file (/tmp): " + how + ": " +
                             (e ? std::strerror(e) : "unknown error"));
  }
  std::string what_;
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f_{nullptr, &std::fclose};
  std::vector<std::function<void()>> read_;
};

}  // namespace wheelchair::util
