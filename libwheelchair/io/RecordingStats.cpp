#include "libwheelchair/io/RecordingStats.h"

#include <fmt/format.h>

#include <algorithm>

namespace wheelchair::io {

void RecordingStats::add(const std::string& label, const std::string& mrpt_class, double t) {
  const std::string key = label + "|" + mrpt_class;
  auto [it, inserted] = streams_.try_emplace(key);
  StreamStats& s = it->second;
  if (inserted) {
    s.label = label;
    s.mrpt_class = mrpt_class;
    s.t_first_s = t;
  } else {
    const double dt = t - s.t_last_s;
    if (dt < 0) ++s.out_of_order;
    if (dt == 0) ++s.duplicates;
    if (dt > s.largest_gap_s) {
      s.largest_gap_s = dt;
      s.largest_gap_at_s = s.t_last_s;
    }
  }
  s.t_last_s = t;
  s.t_min_s = std::min(s.t_min_s, t);
  s.t_max_s = std::max(s.t_max_s, t);
  ++s.count;
}

double RecordingStats::start_s() const {
  double t = std::numeric_limits<double>::infinity();
  for (const auto& [k, s] : streams_) t = std::min(t, s.t_min_s);
  return streams_.empty() ? 0.0 : t;
}

double RecordingStats::end_s() const {
  double t = -std::numeric_limits<double>::infinity();
  for (const auto& [k, s] : streams_) t = std::max(t, s.t_max_s);
  return streams_.empty() ? 0.0 : t;
}

std::size_t RecordingStats::total() const {
  std::size_t n = 0;
  for (const auto& [k, s] : streams_) n += s.count;
  return n;
}

nlohmann::json RecordingStats::toJson() const {
  nlohmann::json j;
  j["start_s"] = start_s();
  j["end_s"] = end_s();
  j["duration_s"] = duration_s();
  j["observations"] = total();
  j["streams"] = nlohmann::json::array();
  for (const auto& [k, s] : streams_) {
    j["streams"].push_back({{"label", s.label},
                            {"class", s.mrpt_class},
                            {"count", s.count},
                            {"mean_rate_hz", s.meanRate_hz()},
                            {"start_s", s.t_min_s},
                            {"end_s", s.t_max_s},
                            {"span_s", s.span_s()},
                            {"largest_gap_s", s.largest_gap_s},
                            {"largest_gap_at_s", s.largest_gap_at_s},
                            {"out_of_order", s.out_of_order},
                            {"duplicate_timestamps", s.duplicates}});
  }
  return j;
}

std::string RecordingStats::toText() const {
  std::string out = fmt::format("{:<13} {:<36} {:>8} {:>9} {:>10} {:>15} {:>12} {:>15}\n",
                                "label", "MRPT class", "count", "rate (Hz)", "span (s)",
                                "largest gap (s)", "out of order", "same timestamp");
  for (const auto& [k, s] : streams_) {
    out += fmt::format("{:<13} {:<36} {:>8} {:>9.2f} {:>10.3f} {:>15.3f} {:>12} {:>15}\n", s.label,
                       s.mrpt_class, s.count, s.meanRate_hz(), s.span_s(), s.largest_gap_s,
                       s.out_of_order, s.duplicates);
  }
  out += fmt::format("total {} observations over {:.3f} s (from t = {:.6f} to {:.6f})\n", total(),
                     duration_s(), start_s(), end_s());
  out +=
      "(out of order: timestamps earlier than the one before in the file; same timestamp: equal "
      "to the one before)\n";
  return out;
}

}  // namespace wheelchair::io
