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
// Example:
//   std::string warning;
//   const RecordingSummary sum = scanRawlogSalvaging("drive.rawlog", salvage, &warning);
//   RawlogSampleReader in("drive.rawlog");
//   AnySample s; std::size_t k;
//   while (in.next(s, k)) { ... }   // k: index of s within its stream
#pragma once

#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/Samples.h"

#include <array>
#include <map>
#include <memory>
#include <optional>
#include <string>

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

 private:
  RawlogReader in_;
  std::array<std::size_t, kNumStreams> index_{};
  std::size_t ignored_ = 0;
  std::string header_text_;
  friend RecordingSummary scanRawlog(const std::string& path);
};

/// Pass 1 (see the header comment). A broken file is not an error here: see report.broken.
RecordingSummary scanRawlog(const std::string& path);

/// scanRawlog with the commands' `--salvage` rule (as io::readRawlogSalvaging): a damaged
/// file throws one line unless `salvage`; with it `*warning` says where and why it broke.
RecordingSummary scanRawlogSalvaging(const std::string& path, bool salvage, std::string* warning);

}  // namespace wheelchair::io
