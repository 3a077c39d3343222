// A rawlog read as a stream of samples, for commands whose memory must not grow with the
// drive (docs/benchmarks.md, "Memory"). Two passes over the file:
//
//   1. scanRawlog(path): counts per stream, first/last time, the META header and how far the
//      file is out of time order: lateness_s = max over samples of (latest time read before
//      it - its time), 0 for a time-ordered file. A break (truncated or corrupt file) is found
//      here, so the salvage rule (io::salvageOrThrow) is applied before any work starts.
//   2. RawlogSampleReader(path): the samples again, in file order, each with its index within
//      its stream (0-based, as io::readRawlog would store it), stopping where pass 1 stopped.
//
// A consumer that needs the samples in time order keeps a merge window: after reading a
// sample of time t_max (the latest so far), every sample still to come has t >= t_max -
// lateness_s, so everything strictly before that watermark is complete and can be processed
// (estimation::runEstimator's streaming overload does this). Memory is then bounded by the
// samples of `lateness_s` seconds instead of the whole drive.
//
// A file known to be in time order needs no pass 1: RawlogWindowReader(path, 0) summarises
// what it reads (summary(), after the end: scanRawlog's result) and latenessSeen() tells when
// the assumption failed (estimation::runEstimatorOnePass, what `wheelchair filter` tries first).
//
// Example:
//   std::string warning;
//   const RecordingSummary sum = scanRawlogSalvaging("drive.rawlog", salvage, &warning);
//   RawlogSampleReader in("drive.rawlog");
//   AnySample s; std::size_t k;
//   while (in.next(s, k)) { ... }   // k: index of s within its stream
#pragma once

#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/Samples.h"

#include <algorithm>
#include <array>
#include <deque>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace wheelchair::io {

/// What a recording holds, without its samples.
struct RecordingSummary {
  std::array<std::size_t, kNumStreams> counts{};  ///< samples per stream (StreamKind order)
  double start_s = 0, end_s = 0;  ///< earliest / latest time (Recording::startTime/endTime)
  double lateness_s = 0;          ///< see the header comment (0: time-ordered)
  std::map<std::string, std::string> meta;  ///< `[recording]` keys of the header
  RawlogReadReport report;                  ///< records, ignored, break, header text

  std::size_t count(StreamKind k) const { return counts[static_cast<int>(k)]; }
  std::size_t size() const;  ///< all samples (Recording::size)
};

/// The summary of an in-memory recording (lateness_s: +infinity, nothing is known to be in
/// order; report empty).
RecordingSummary summarize(const Recording& rec);

/// Samples of a rawlog in file order (header and foreign records skipped); stops at a clean
/// end or at the first broken record (error()), like RawlogReader.
class RawlogSampleReader {
 public:
  explicit RawlogSampleReader(const std::string& path);  ///< throws like RawlogReader
  /// Next sample and its index within its stream; false at the end or at a break.
  bool next(AnySample& s, std::size_t& stream_index);
  const std::optional<RawlogBreak>& error() const { return in_.error(); }
  std::size_t recordsRead() const { return in_.recordsRead(); }
  const std::string& headerText() const { return header_text_; }
  std::size_t ignored() const { return ignored_; }  ///< records skipped (not ours)
  double fractionRead() const { return in_.fractionRead(); }

 private:
  RawlogReader in_;
  std::array<std::size_t, kNumStreams> index_{};
  std::size_t ignored_ = 0;
  std::string header_text_;
};

/// The RecordingSummary of samples seen in file order: add() each, then finish() with the
/// reader once it has stopped (records, break, header). scanRawlog is this over a whole file.
class SummaryAccumulator {
 public:
  void add(const AnySample& s) {
    const double t = timeOf(s);
    if (t_max_ - t > sum_.lateness_s) sum_.lateness_s = t_max_ - t;
    t_min_ = std::min(t_min_, t);
    t_max_ = std::max(t_max_, t);
    ++sum_.counts[s.index()];
  }
  double lateness() const { return sum_.lateness_s; }  ///< so far
  RecordingSummary finish(const RawlogSampleReader& in) const;

 private:
  RecordingSummary sum_;
  double t_min_ = std::numeric_limits<double>::infinity();
  double t_max_ = -std::numeric_limits<double>::infinity();
};

/// Pass 2 with the merge window (see the header comment): read() passes a block of samples to
/// `push` in file order and moves watermark(), below which every sample has been passed.
class RawlogWindowReader {
 public:
  RawlogWindowReader(const std::string& path, double lateness_s)
      : in_(path), lateness_s_(lateness_s) {}
  /// Reads up to `block` samples; at the end of the file eof() and watermark() = +infinity.
  void read(const std::function<void(const AnySample&, std::size_t)>& push, int block = 256);
  double watermark() const { return watermark_; }
  bool eof() const { return eof_; }
  /// How far out of time order the samples read so far are (RecordingSummary::lateness_s):
  /// above the window's `lateness_s`, samples were passed after the watermark had moved past
  /// them (a one-pass reader that assumed an order must then start again from a scan).
  double latenessSeen() const { return acc_.lateness(); }
  /// The summary of what was read (after eof(): scanRawlog's result for the file).
  RecordingSummary summary() const { return acc_.finish(in_); }
  double fractionRead() const { return in_.fractionRead(); }

 private:
  RawlogSampleReader in_;
  SummaryAccumulator acc_;
  double lateness_s_;
  double t_max_ = -std::numeric_limits<double>::infinity();
  double watermark_ = -std::numeric_limits<double>::infinity();
  bool eof_ = false;
};

/// The (time, value) order of each stream: time, then the values in declaration order (the
/// order the estimators and dead reckoning sort a stream in, so that a recording's result
/// does not depend on the order its samples were stored in).
bool encoderLess(const EncoderSample& a, const EncoderSample& b);
bool imuLess(const ImuSample& a, const ImuSample& b);  ///< time, gyro z
bool motorLess(const MotorSample& a, const MotorSample& b);
bool sonarLess(const SonarSample& a, const SonarSample& b);
bool pozyxLess(const PozyxSample& a, const PozyxSample& b);  ///< time, x, y

/// One stream in (time, value) order (`less`), stable (equal samples keep their stored order):
/// either an in-memory vector (the vector itself when already in order, else a sorted copy)
/// or samples pushed as read from a file, kept in a heap until taken. Example:
///   SortedStream<ImuSample> s(imuLess);
///   s.push(sample, k);                          // as read (k: index within the stream)
///   while (auto* h = s.head(reader.watermark())) { use(*h); s.pop(); }
template <typename T>
class SortedStream {
 public:
  using Less = bool (*)(const T&, const T&);
  explicit SortedStream(Less less) : less_(less) {}

  void attach(const std::vector<T>& v) {
    if (std::is_sorted(v.begin(), v.end(), less_)) {
      view_ = &v;
      return;
    }
    std::vector<std::size_t> order(v.size());
    for (std::size_t i = 0; i < v.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return less_(v[a], v[b]); });
    store_.reserve(v.size());
    for (const std::size_t i : order) store_.push_back(v[i]);
    order_ = std::move(order);
    view_ = &store_;
  }
  void push(const T& s, std::size_t stored) {
    heap_.push_back({s, stored});
    std::push_heap(heap_.begin(), heap_.end(), later_);
  }
  /// The next sample if it is known complete: its time is below `watermark` (all samples
  /// before the watermark have been pushed); null otherwise or when the stream is done.
  const T* head(double watermark) const {
    if (view_) return pos_ < view_->size() ? &(*view_)[pos_] : nullptr;
    return !heap_.empty() && heap_.front().s.t_s < watermark ? &heap_.front().s : nullptr;
  }
  /// Index as stored of the current head.
  std::size_t headStored() const {
    if (view_) return pos_ < order_.size() ? order_[pos_] : pos_;
    return heap_.front().stored;
  }
  void pop() {
    if (view_) {
      ++pos_;
      return;
    }
    std::pop_heap(heap_.begin(), heap_.end(), later_);
    heap_.pop_back();
  }
  /// Samples pushed and not yet taken.
  std::size_t buffered() const { return heap_.size(); }
  /// Nothing buffered (with the file read to its end: the stream is done).
  bool drained() const { return view_ ? pos_ >= view_->size() : heap_.empty(); }

 private:
  struct Item {
    T s;
    std::size_t stored;
  };
  Less less_;
  const std::vector<T>* view_ = nullptr;
  std::vector<T> store_;
  std::vector<std::size_t> order_;
  std::size_t pos_ = 0;
  struct Later {  // heap order: x comes after y
    Less less;
    bool operator()(const Item& x, const Item& y) const {
      return less(y.s, x.s) || (!less(x.s, y.s) && x.stored > y.stored);
    }
  };
  std::vector<Item> heap_;
  Later later_{less_};
};

/// io::writeRawlog for samples that arrive as they are produced (stream by stream, each in its
/// own order): the same file, byte for byte, holding back only what the time-ordered merge
/// cannot decide yet (each stream's samples until every expected stream has one).
/// writeRawlog writes the header with the recording's earliest time; here it is the earliest
/// first sample of the expected streams, which is the same for streams whose times increase;
/// commit() throws HeaderTimeMismatch (nothing written) when a later sample was earlier, so
/// the caller can fall back to writeRawlog. Example:
///   TimeOrderedRawlogWriter w("sim.rawlog", cfg, {StreamKind::Encoders, StreamKind::Imu});
///   w.setMeta(meta);  w.add(sample);  ...;  w.commit();
class TimeOrderedRawlogWriter {
 public:
  struct HeaderTimeMismatch : std::runtime_error {
    using std::runtime_error::runtime_error;
  };
  /// Creates the temporary beside `path` (a bad path fails here, before any work).
  /// `expected`: every stream that will deliver samples (an undeclared one is waited for only
  /// from its first sample on, too late for what was written before it).
  TimeOrderedRawlogWriter(const std::string& path, const config::WheelchairConfig& cfg,
                          const std::vector<StreamKind>& expected);
  /// The header's `[recording]` keys (before the first add()).
  void setMeta(std::map<std::string, std::string> meta) { meta_ = std::move(meta); }
  void add(const AnySample& s);
  void commit();
  /// Samples added per stream.
  const std::array<std::size_t, kNumStreams>& counts() const { return counts_; }

 private:
  void emit(bool all);

  RawlogWriter out_;
  const config::WheelchairConfig& cfg_;
  std::map<std::string, std::string> meta_;
  std::array<bool, kNumStreams> expected_{};
  std::array<std::deque<AnySample>, kNumStreams> buf_;
  std::array<std::size_t, kNumStreams> counts_{};
  bool header_written_ = false;
  double header_t_ = 0, t_min_ = std::numeric_limits<double>::infinity();
};

/// Pass 1 (see the header comment). A broken file is not an error here: see report.broken.
RecordingSummary scanRawlog(const std::string& path);

/// scanRawlog with the commands' `--salvage` rule (as io::readRawlogSalvaging): a damaged
/// file throws one line unless `salvage`; with it `*warning` says where and why it broke.
RecordingSummary scanRawlogSalvaging(const std::string& path, bool salvage, std::string* warning);

}  // namespace wheelchair::io
