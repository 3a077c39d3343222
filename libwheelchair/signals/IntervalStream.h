// prepareIntervalMeans (IntervalSignals.h) as the samples come: `identify` on long drives
// (docs/benchmarks.md "Memory"). The same steps 1-4, made with bounded memory:
//
//   * streams: encoder intervals (sensors::WheelSpeedConverter, the loop of
//     wheelSpeedsFromTicks), motor samples (sanitised as they come: the file must be in time
//     order; the motor voltage U needs the next sample), the gyro (omega from the gyro only);
//     each keeps only the samples the next grid point and the next interval means still need;
//   * interval means of the currents, voltages and gyro over each encoder interval, made as
//     soon as the motor (and IMU) stream has passed the interval's end (the running integrals F
//     are the same sums, in the same order, as intervalMeans');
//   * grid points decided as soon as every stream has passed them: coverage, then the raw
//     values; runs of covered points at least 2 edge_trim_s + 1 s long are the segments;
//   * the zero-phase Butterworth by blocks (StreamingFiltfilt): the forward pass runs as the
//     samples come; the backward pass of a block of 8192 samples starts (at its steady state)
//     40 fs/fc samples after the block (~180 time constants of the filter: the start-up
//     difference is below 1e-70 of the signal when it reaches the block). The last block ends
//     with the odd reflection of the whole-series filter; segments shorter than 2 blocks are
//     filtered whole (filtfiltButter2 itself).
//
// Memory: a few blocks of the filter (~2 MB) and the stream samples of the time the slowest
// stream lags behind; a stream that is absent or silent for a long time (no motor samples, an
// encoder gap) makes the others wait for that time (no grid point can be decided meanwhile).
//
// Rows come out in the order of the segments of prepareIntervalMeans, each row what the segment
// holds at k (IntervalRow); the noise floors and has_voltage come from finish(). Equal to
// prepareIntervalMeans: the backward filter pass started a run-in early reaches the block
// with the whole-series pass' state to the bit in every case measured
// (tests/identification/test_identify_streamed.cpp checks the rows to 1e-12 and prints the
// count of bit-identical ones: all so far).
//
// Example:
//   IntervalConditioner c(cfg, o, [&](const IntervalRow& r) { use(r); });
//   c.beginRecording(0);
//   while (reader.next(s, k)) c.add(s);   // samples in file order (time-ordered file)
//   c.endRecording();
//   const IntervalSignals noise = c.finish();   // noise floors, has_voltage; no segments
#pragma once

#include "libwheelchair/io/Samples.h"
#include "libwheelchair/sensors/Filtering.h"
#include "libwheelchair/signals/IntervalSignals.h"

#include <deque>
#include <functional>
#include <memory>
#include <vector>

namespace wheelchair::signals {

/// filtfiltButter2 (sensors/Filtering.h) over C aligned channels pushed one sample at a time;
/// each sample comes back once filtered (see the header comment for the block rule). Example:
///   StreamingFiltfilt f(2, 2.0, 100.0, 0, [](long j, const double* raw, const double* y) {});
///   f.push(x);  ...  f.finish();
class StreamingFiltfilt {
 public:
  /// Receives sample j (0-based) with its raw and filtered values (C each).
  using Emit = std::function<void(long j, const double* raw, const double* filtered)>;
  /// `min_lag`: a sample is never emitted before `min_lag` later samples have been pushed
  /// (except by finish()).
  StreamingFiltfilt(int channels, double cutoff_hz, double rate_hz, long min_lag, Emit emit);
  void push(const double* x);
  /// Filters and emits what is left (the series ends here).
  void finish();
  long pushed() const { return n_; }
  /// Samples per emitted block and the backward pass' run-in after it.
  long blockSize() const { return block_; }
  long runIn() const { return run_in_; }

 private:
  void start();
  void forward(const double* x);
  void emitBlock(long count, bool last);
  void emitFrom(const std::vector<double>& out, long count);

  int C_;
  double cutoff_hz_, rate_hz_;
  sensors::Biquad f_;
  long pad_, block_, run_in_, first_;
  Emit emit_;
  long n_ = 0;                    ///< pushed
  long e0_ = 0;                   ///< first sample not emitted
  bool started_ = false;          ///< forward pass running (else samples wait in raw_)
  std::deque<double> raw_, fwd_;  ///< samples e0_.. (C interleaved)
  std::vector<double> z1_, z2_;   ///< forward state per channel
};

/// prepareIntervalMeans over samples pushed in file order (header comment).
class IntervalConditioner {
 public:
  using RowSink = std::function<void(const IntervalRow&)>;
  IntervalConditioner(const config::WheelchairConfig& cfg, const IntervalSignalOptions& o,
                      RowSink sink);
  ~IntervalConditioner();
  IntervalConditioner(const IntervalConditioner&) = delete;
  IntervalConditioner& operator=(const IntervalConditioner&) = delete;

  void beginRecording(int index);
  /// Encoder, motor and (with gyro_omega) IMU samples; the others are ignored. Throws
  /// std::invalid_argument when a stream goes back in time (the file is not in time order).
  void add(const io::AnySample& s);
  void endRecording();
  /// The noise floors and has_voltage of all recordings (segments empty: they went to the sink).
  IntervalSignals finish();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace wheelchair::signals
