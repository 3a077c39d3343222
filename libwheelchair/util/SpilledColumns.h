// Columns (std::vector of a trivially copyable T, e.g. a stream's sample times in s) set aside
// in an anonymous temporary file while a phase of a computation does not read them, and read
// back bit for bit before the next phase that does (the memory of long drives,
// docs/benchmarks.md "Tenth round"). spill() writes a column and releases its memory;
// restore() reads every column spilled since the last restore() back into its vector (which
// must still exist, empty).
//
// The file: util::TempFile (std::tmpfile: an unnamed file in /tmp, TMPDIR not consulted, nothing
// left behind). Every write and read is checked: a failure (no temporary file can be made, /tmp
// is full, a file-size limit) throws std::runtime_error, one line naming `what`, the temporary
// file and the system's reason, e.g.
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

#include "libwheelchair/util/TempFile.h"

#include <functional>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace wheelchair::util {

class SpilledColumns {
 public:
  explicit SpilledColumns(std::string what) : file_(std::move(what)) {}
  SpilledColumns(const SpilledColumns&) = delete;
  SpilledColumns& operator=(const SpilledColumns&) = delete;

  /// Writes v to the file and releases it (v empty). Throws (v unchanged) when it cannot.
  template <typename T>
  void spill(std::vector<T>& v) {
    static_assert(std::is_trivially_copyable_v<T>, "columns are written as bytes");
    if (v.empty()) return;
    const long at = file_.append(v.data(), sizeof(T) * v.size());
    const std::size_t n = v.size();
    std::vector<T>().swap(v);
    read_.push_back([this, &v, at, n] {
      v.resize(n);
      file_.read(at, v.data(), sizeof(T) * n);
    });
  }
  /// Every column spilled since the last restore() read back, in the order spilled.
  void restore() {
    for (auto& r : read_) r();
    read_.clear();
    file_.close();  // the file is gone once closed
  }
  /// Columns on the file (not yet restored).
  std::size_t spilled() const { return read_.size(); }

 private:
  TempFile file_;
  std::vector<std::function<void()>> read_;
};

}  // namespace wheelchair::util
