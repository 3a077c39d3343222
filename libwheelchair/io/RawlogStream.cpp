#include "libwheelchair/io/RawlogStream.h"

#include <algorithm>
#include <limits>
#include <tuple>

namespace wheelchair::io {

bool encoderLess(const EncoderSample& a, const EncoderSample& b) {
  return std::tie(a.t_s, a.right_ticks, a.left_ticks) <
         std::tie(b.t_s, b.right_ticks, b.left_ticks);
}
bool imuLess(const ImuSample& a, const ImuSample& b) {
  return std::tie(a.t_s, a.gyro_z_rad_s) < std::tie(b.t_s, b.gyro_z_rad_s);
}
bool motorLess(const MotorSample& a, const MotorSample& b) {
  return std::tie(a.t_s, a.current_right_A, a.current_left_A, a.vrc_right_V, a.vrc_left_V) <
         std::tie(b.t_s, b.current_right_A, b.current_left_A, b.vrc_right_V, b.vrc_left_V);
}
bool sonarLess(const SonarSample& a, const SonarSample& b) {
  return std::tie(a.t_s, a.range_m) < std::tie(b.t_s, b.range_m);
}
bool pozyxLess(const PozyxSample& a, const PozyxSample& b) {
  return std::tie(a.t_s, a.x_m, a.y_m) < std::tie(b.t_s, b.x_m, b.y_m);
}

std::size_t RecordingSummary::size() const {
  std::size_t n = 0;
  for (const std::size_t c : counts) n += c;
  return n;
}

RecordingSummary summarize(const Recording& rec) {
  RecordingSummary s;
  s.counts = {rec.encoders.size(),     rec.imu.size(),      rec.motors.size(),
              rec.sonar.size(),        rec.pozyx.size(),    rec.joystick.size(),
              rec.ground_truth.size(), rec.landmarks.size()};
  s.start_s = rec.startTime();
  s.end_s = rec.endTime();
  s.lateness_s = std::numeric_limits<double>::infinity();
  s.meta = rec.meta;
  return s;
}

RawlogSampleReader::RawlogSampleReader(const std::string& path) : in_(path) {}

bool RawlogSampleReader::next(AnySample& s, std::size_t& stream_index) {
  mrpt::serialization::CSerializable::Ptr obj;
  for (;;) {
    const auto got = in_.nextSample(s, obj);
    if (got == RawlogReader::Got::End) break;
    if (got == RawlogReader::Got::Sample) {
      stream_index = index_[s.index()]++;
      return true;
    }
    auto o = std::dynamic_pointer_cast<mrpt::obs::CObservation>(obj);
    if (!o) {
      ++ignored_;
      continue;
    }
    if (auto text = io::headerText(*o)) {
      header_text_ = *text;
      continue;
    }
    auto sample = fromObservation(*o);
    if (!sample) {
      ++ignored_;
      continue;
    }
    s = std::move(*sample);
    stream_index = index_[s.index()]++;
    return true;
  }
  return false;
}

void RawlogWindowReader::read(const std::function<void(const AnySample&, std::size_t)>& push,
                              int block) {
  AnySample s;
  std::size_t k = 0;
  for (int i = 0; i < block; ++i) {
    if (!in_.next(s, k)) {
      eof_ = true;
      watermark_ = std::numeric_limits<double>::infinity();
      return;
    }
    t_max_ = std::max(t_max_, timeOf(s));
    acc_.add(s);
    push(s, k);
  }
  watermark_ = t_max_ - lateness_s_;
}

TimeOrderedRawlogWriter::TimeOrderedRawlogWriter(const std::string& path,
                                                 const config::WheelchairConfig& cfg,
                                                 const std::vector<StreamKind>& expected)
    : out_(path), cfg_(cfg) {
  for (const StreamKind k : expected) expected_[static_cast<int>(k)] = true;
}

void TimeOrderedRawlogWriter::add(const AnySample& s) {
  const int k = static_cast<int>(s.index());
  expected_[k] = true;  // a stream nobody announced: wait for it too
  t_min_ = std::min(t_min_, timeOf(s));
  ++counts_[k];
  buf_[k].push_back(s);
  emit(false);
}

void TimeOrderedRawlogWriter::emit(bool all) {
  // forEachInTimeOrder's rule (the earliest head, ties to the lower stream), applied only
  // when every stream that may still deliver has a head (or at the end).
  for (;;) {
    int best = -1;
    double best_t = std::numeric_limits<double>::infinity(), first_t = best_t;
    for (int k = 0; k < kNumStreams; ++k) {
      if (buf_[k].empty()) {
        if (expected_[k] && !all) return;
        continue;
      }
      const double t = timeOf(buf_[k].front());
      first_t = std::min(first_t, t);
      if (best < 0 || t < best_t) {
        best = k;
        best_t = t;
      }
    }
    if (best < 0) return;
    if (!header_written_) {
      header_t_ = first_t;
      out_.writeHeader(meta_, cfg_, header_t_);
      header_written_ = true;
    }
    out_.write(buf_[best].front(), cfg_);
    buf_[best].pop_front();
  }
}

void TimeOrderedRawlogWriter::commit() {
  emit(true);
  const double t0 = counts_ == std::array<std::size_t, kNumStreams>{} ? 0.0 : t_min_;
  if (!header_written_) out_.writeHeader(meta_, cfg_, t0);
  if (header_written_ && header_t_ != t0)
    throw HeaderTimeMismatch("a sample earlier than every stream's first one");
  out_.commit();
}

RecordingSummary SummaryAccumulator::finish(const RawlogSampleReader& in) const {
  RecordingSummary sum = sum_;
  if (sum.size()) {
    sum.start_s = t_min_;
    sum.end_s = t_max_;
  }
  sum.report.records = in.recordsRead();
  sum.report.ignored = in.ignored();
  sum.report.broken = in.error();
  sum.report.header_text = in.headerText();
  if (!in.headerText().empty()) sum.meta = headerMeta(in.headerText());
  return sum;
}

RecordingSummary scanRawlog(const std::string& path) {
  RawlogSampleReader in(path);
  SummaryAccumulator acc;
  AnySample s;
  std::size_t k = 0;
  while (in.next(s, k)) acc.add(s);
  return acc.finish(in);
}

RecordingSummary scanRawlogSalvaging(const std::string& path, bool salvage, std::string* warning) {
  RecordingSummary sum = scanRawlog(path);
  if (sum.report.broken) {
    const std::string w = salvageOrThrow(path, *sum.report.broken, sum.size(), salvage);
    if (warning) *warning = w;
  }
  return sum;
}

}  // namespace wheelchair::io
