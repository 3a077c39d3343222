// The reorder buffer of `wheelchair capture`: observations of all sources, merged in
// timestamp order with a bounded latency (docs/capture.md, "Merging").
//
// Each source keeps its own FIFO (its recorded order is never changed). An observation
// leaves the buffer when it is the earliest head of all FIFOs (ties: stream order ENCODERS,
// IMU, MOTORS, ... as in io::forEachInTimeOrder) and has waited `window_s` seconds of host
// time; so observations of different sources that arrive up to `window_s` apart are written
// in timestamp order, and none waits much longer than that. One that arrives later than
// that, with a timestamp before one already written, is still written (raw data is never
// dropped) and counted as late.
#pragma once

#include <mrpt/obs/CObservation.h>

#include <cstddef>
#include <deque>
#include <functional>
#include <vector>

namespace wheelchair::capture {

class MergeBuffer {
 public:
  /// `num_sources` FIFOs; `rank[i]` breaks timestamp ties (lower first).
  MergeBuffer(std::size_t num_sources, std::vector<int> rank, double window_s);

  void push(std::size_t source, mrpt::obs::CObservation::Ptr obs, double host_mono);
  /// Hands every due observation to `out`, in order. `all` = drain (end of capture).
  std::size_t release(
      double host_mono, bool all,
      const std::function<void(std::size_t source, const mrpt::obs::CObservation&)>& out);

  std::size_t size() const { return size_; }
  std::size_t late(std::size_t source) const { return late_[source]; }

 private:
  struct Item {
    mrpt::obs::CObservation::Ptr obs;
    double host_mono;
  };
  std::vector<std::deque<Item>> q_;
  std::vector<int> rank_;
  std::vector<std::size_t> late_;
  double window_s_;
  std::size_t size_ = 0;
  bool any_written_ = false;
  mrpt::Clock::time_point last_written_{};
};

}  // namespace wheelchair::capture
