// Columns (std::vector of a trivially copyable T, e.g. a stream's sample times in s) set aside
// in an anonymous temporary file while a phase of a computation does not read them, and read
// back bit for bit before the next phase that does (the memory of long drives,
// docs/benchmarks.md "Tenth round"). spill() writes a column and releases its memory;
// restore() reads every column spilled since the last restore() back into its vector (which
// must still exist, empty). Without a usable temporary file (none can be made, or a write
// fails) a column simply stays in memory. A failed read back throws std::runtime_error naming
// `what` and the system's reason (the column would be lost otherwise).
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

  /// Writes v to the file and releases it (v empty); v stays as it is when it cannot be written.
  template <typename T>
  void spill(std::vector<T>& v) {
    static_assert(std::is_trivially_copyable_v<T>, "columns are written as bytes");
    if (v.empty() || unusable_) return;
    if (!f_) f_.reset(std::tmpfile());
    if (!f_ || std::fseek(f_.get(), 0, SEEK_END) != 0) {
      unusable_ = true;
      return;
    }
    const long at = std::ftell(f_.get());
    if (at < 0 || std::fwrite(v.data(), sizeof(T), v.size(), f_.get()) != v.size() ||
        std::fflush(f_.get()) != 0) {
      unusable_ = true;  // what was written is never read: v stays in memory
      return;
    }
    const std::size_t n = v.size();
    std::vector<T>().swap(v);
    read_.push_back([this, &v, at, n] {
      v.resize(n);
      if (std::fseek(f_.get(), at, SEEK_SET) != 0 ||
          std::fread(v.data(), sizeof(T), n, f_.get()) != n)
        throw std::runtime_error(what_ +
                                 ": temporary file: cannot read back: " + std::strerror(errno));
    });
  }
  /// Every column spilled since the last restore() read back, in the order spilled.
  void restore() {
    for (auto& r : read_) r();
    read_.clear();
    f_.reset();  // the file is gone once closed
    unusable_ = false;
  }
  /// Columns on the file (not yet restored).
  std::size_t spilled() const { return read_.size(); }

 private:
  std::string what_;
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f_{nullptr, &std::fclose};
  bool unusable_ = false;
  std::vector<std::function<void()>> read_;
};

}  // namespace wheelchair::util
