// Fixed-size records kept in memory up to a limit and beyond it in an anonymous temporary file
// (util::TempFile: gone when closed, even after a crash), read back in order, wholly or a range
// [begin, end) (the memory of long drives, docs/benchmarks.md "Memory"). Every write and read is
// checked; a failure throws std::runtime_error naming `what`, the file and the system's reason.
//
// T must be trivially copyable (it is written as bytes). Example:
//   ScratchRecords<Row> rows("identify: the conditioned rows", 1 << 16);
//   rows.add(r);                                   // ... many
//   rows.replay(0, rows.size(), [](const Row& r) { use(r); });
#pragma once

#include "libwheelchair/util/TempFile.h"

#include <algorithm>
#include <functional>
#include <string>
#include <type_traits>
#include <vector>

namespace wheelchair::util {

template <typename T>
class ScratchRecords {
  static_assert(std::is_trivially_copyable_v<T>, "records are written as bytes");

 public:
  /// At most `in_memory` records are held in memory (the tail not yet written).
  ScratchRecords(std::string what, std::size_t in_memory)
      : file_(std::move(what)), in_memory_(std::max<std::size_t>(1, in_memory)) {}

  void add(const T& r) {
    if (mem_.size() == in_memory_) spill();
    mem_.push_back(r);
  }
  std::size_t size() const { return on_file_ + mem_.size(); }

  /// Calls f for the records [begin, end) in order.
  void replay(std::size_t begin, std::size_t end, const std::function<void(const T&)>& f) {
    end = std::min(end, size());
    if (begin < on_file_ && begin < end) {
      std::vector<T> chunk(std::min<std::size_t>(4096, on_file_ - begin));
      for (std::size_t i = begin; i < std::min(end, on_file_);) {
        const std::size_t want = std::min({chunk.size(), end - i, on_file_ - i});
        file_.read(long(i * sizeof(T)), chunk.data(), want * sizeof(T));
        for (std::size_t j = 0; j < want; ++j) f(chunk[j]);
        i += want;
      }
    }
    for (std::size_t i = std::max(begin, on_file_); i < end; ++i) f(mem_[i - on_file_]);
  }

 private:
  void spill() {
    file_.append(mem_.data(), mem_.size() * sizeof(T));
    on_file_ += mem_.size();
    mem_.clear();
  }

  TempFile file_;
  std::size_t in_memory_;
  std::vector<T> mem_;
  std::size_t on_file_ = 0;
};

}  // namespace wheelchair::util
