#include "libwheelchair/capture/MergeBuffer.h"

namespace wheelchair::capture {

MergeBuffer::MergeBuffer(std::size_t num_sources, std::vector<int> rank, double window_s)
    : q_(num_sources), rank_(std::move(rank)), late_(num_sources, 0), window_s_(window_s) {
  rank_.resize(num_sources, 0);
}

void MergeBuffer::push(std::size_t source, mrpt::obs::CObservation::Ptr obs, double host_mono) {
  q_[source].push_back(Item{std::move(obs), host_mono});
  ++size_;
}

std::size_t MergeBuffer::release(
    double host_mono, bool all,
    const std::function<void(std::size_t, const mrpt::obs::CObservation&)>& out) {
  std::size_t n = 0;
  for (;;) {
    int best = -1;
    for (std::size_t i = 0; i < q_.size(); ++i) {
      if (q_[i].empty()) continue;
      if (best < 0) {
        best = static_cast<int>(i);
        continue;
      }
      const auto& a = q_[i].front().obs->timestamp;
      const auto& b = q_[best].front().obs->timestamp;
      if (a < b || (a == b && rank_[i] < rank_[best])) best = static_cast<int>(i);
    }
    if (best < 0) break;
    Item& it = q_[best].front();
    if (!all && host_mono - it.host_mono < window_s_) break;
    if (any_written_ && it.obs->timestamp < last_written_)
      ++late_[best];
    else
      last_written_ = it.obs->timestamp;
    any_written_ = true;
    out(static_cast<std::size_t>(best), *it.obs);
    q_[best].pop_front();
    --size_;
    ++n;
  }
  return n;
}

}  // namespace wheelchair::capture
