// Fixed-size records kept in memory up to a limit and beyond it in an anonymous temporary file
// (std::tmpfile: gone when closed, even after a crash), read back in order, wholly or a range
// [begin, end) (the memory of long drives, docs/benchmarks.md "Memory"). Every write and read is
// checked; a failure throws std::runtime_error naming `what` and the system's reason.
//
// T must be trivially copyable (it is written as bytes). Example:
//   ScratchRecords<Row> rows("identify: the conditioned rows", 1 << 16);
//   rows.add(r);                                   // ... many
//   rows.replay(0, rows.size(), [](const Row& r) { use(r); });
#pragma once

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <functional>
#include <memory>
#include <stdexcept>
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
      : what_(std::move(what)), in_memory_(std::max<std::size_t>(1, in_memory)) {}

  void add(const T& r) {
    if (mem_.size() == in_memory_) spill();
    mem_.push_back(r);
  }
  std::size_t size() const { return on_file_ + mem_.size(); }

  /// Calls f for the records [begin, end) in order.
  void replay(std::size_t begin, std::size_t end, const std::function<void(const T&)>& f) {
    end = std::min(end, size());
    if (begin < on_file_ && begin < end) {
      if (std::fseek(f_.get(), long(begin * sizeof(T)), SEEK_SET) != 0) fail("cannot read");
      std::vector<T> chunk(std::min<std::size_t>(4096, on_file_ - begin));
      for (std::size_t i = begin; i < std::min(end, on_file_);) {
        const std::size_t want = std::min({chunk.size(), end - i, on_file_ - i});
        if (std::fread(chunk.data(), sizeof(T), want, f_.get()) != want) fail("cannot read");
        for (std::size_t j = 0; j < want; ++j) f(chunk[j]);
        i += want;
      }
      if (std::fseek(f_.get(), 0, SEEK_END) != 0) fail("cannot read");
    }
    for (std::size_t i = std::max(begin, on_file_); i < end; ++i) f(mem_[i - on_file_]);
  }

 private:
  void spill() {
    if (!f_) {
      f_.reset(std::tmpfile());
      if (!f_) fail("cannot create");
    }
    if (std::fwrite(mem_.data(), sizeof(T), mem_.size(), f_.get()) != mem_.size())
      fail("cannot write");
    if (std::fflush(f_.get()) != 0) fail("cannot write");
    on_file_ += mem_.size();
    mem_.clear();
  }
  [[noreturn]] void fail(const char* how) const {
    throw std::runtime_error(what_ + ": scratch file (temporary directory): " + how + ": " +
                             std::strerror(errno));
  }

  std::string what_;
  std::size_t in_memory_;
  std::vector<T> mem_;
  std::size_t on_file_ = 0;
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f_{nullptr, &std::fclose};
};

}  // namespace wheelchair::util
