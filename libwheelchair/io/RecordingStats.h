// Per-stream timing statistics of a recording, accumulated one observation at a time so
// that `wheelchair info` streams files of any size in constant memory.
//
// Example:
//   RecordingStats st;
//   st.add("IMU", "mrpt::obs::CObservationIMU", t_s);   // for every observation
//   nlohmann::json j = st.toJson();
#pragma once

#include <nlohmann/json.hpp>

#include <limits>
#include <map>
#include <string>

namespace wheelchair::io {

struct StreamStats {
  std::string label;
  std::string mrpt_class;
  std::size_t count = 0;
  double t_first_s = 0, t_last_s = 0;
  double t_min_s = std::numeric_limits<double>::infinity();
  double t_max_s = -std::numeric_limits<double>::infinity();
  double largest_gap_s = 0;       ///< largest forward step between consecutive samples
  double largest_gap_at_s = 0;    ///< time where that gap starts
  std::size_t out_of_order = 0;   ///< samples earlier than their predecessor
  std::size_t duplicates = 0;     ///< samples with the same timestamp as their predecessor

  double span_s() const { return count ? t_max_s - t_min_s : 0.0; }
  /// (count - 1) / span: the mean rate (Hz); 0 for fewer than two samples.
  double meanRate_hz() const { return count > 1 && span_s() > 0 ? (count - 1) / span_s() : 0.0; }
};

class RecordingStats {
 public:
  void add(const std::string& label, const std::string& mrpt_class, double t_s);
  const std::map<std::string, StreamStats>& streams() const { return streams_; }
  double start_s() const;
  double end_s() const;
  double duration_s() const { return streams_.empty() ? 0.0 : end_s() - start_s(); }
  std::size_t total() const;
  nlohmann::json toJson() const;
  /// Fixed-width table for terminals.
  std::string toText() const;

 private:
  std::map<std::string, StreamStats> streams_;
};

}  // namespace wheelchair::io
