// `wheelchair capture`: runs every source of a capture configuration (config/capture.ini),
// each in its own thread, merges their observations in timestamp order and writes them
// continuously to a gzip rawlog (docs/capture.md).
//
// Threads: one per source, looping on CGenericSensor::doProcess() (each call waits at most
// 1/process_rate for data, so a stop request is seen within that time); the calling thread
// runs the loop that every 10 ms collects the sources' queued observations
// (CGenericSensor::getObservations), merges them (MergeBuffer), writes (RawlogAppender,
// a gzip member at least every flush_period_s), logs events and prints the live status.
//
// Example:
//   CaptureOptions o;
//   o.config_path = "config/capture.ini";
//   o.output = "drive.rawlog";
//   CaptureSession s(o);
//   std::atomic<bool> stop{false};
//   int rc = s.run(&stop);   // until stop, o.duration_s, or a write error
#pragma once

#include "libwheelchair/capture/CaptureSource.h"
#include "libwheelchair/capture/MergeBuffer.h"
#include "libwheelchair/capture/RawlogAppender.h"

#include <atomic>
#include <cstdio>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace wheelchair::capture {

struct CaptureOptions {
  std::string config_path;     ///< the capture INI
  std::string output;          ///< rawlog to write
  double duration_s = 0;       ///< stop after this long (0 = until stopped)
  bool overwrite = false;      ///< replace an existing output
  bool verbose = false;        ///< live status even when stderr is not a terminal
  std::string vehicle_config;  ///< overrides [capture] vehicle_config
  std::FILE* status_out = stderr;
  /// Prints one line on the console (between live status updates) and in the event log.
  using Say = std::function<void(const std::string&)>;
  /// Called on the capture loop's thread with every observation as it is written (merged
  /// timestamp order; a late one out of order), e.g. the live health monitor of
  /// `wheelchair capture --health`. It must not throw and must be quick (the loop runs every
  /// 10 ms).
  std::function<void(const mrpt::obs::CObservation&, const Say&)> on_record;
  /// Called once after the last observation was written and the file closed (also after a
  /// write error), before the final summary.
  std::function<void(const Say&)> on_finish;
};

class CaptureSession {
 public:
  /// Loads the configuration and creates the sources; throws std::invalid_argument (bad
  /// configuration) or WriteError (output cannot be created).
  explicit CaptureSession(CaptureOptions opt);
  ~CaptureSession();

  /// Captures until *stop becomes true, the duration elapses or writing fails.
  /// Returns 0 on a clean stop, 1 after a write error (see error()).
  int run(const std::atomic<bool>* stop = nullptr);
  /// Thread-safe stop request (alternative to the flag passed to run()).
  void requestStop() { stop_requested_ = true; }

  std::vector<SourceStatus> status() const;
  /// Every event logged so far (connections, hang-ups, gaps, garbage samples, errors).
  std::vector<CaptureEvent> events() const;
  const std::string& error() const { return error_; }
  std::size_t recordsWritten() const { return records_written_; }
  /// The vehicle configuration the samples are converted with (recorded in the header).
  const config::WheelchairConfig& vehicleConfig() const { return vehicle_; }
  /// Whether an enabled source captures stream `k`.
  bool captures(io::StreamKind k) const;
  /// Observations written after one with a later timestamp (arrived beyond the window).
  std::size_t lateRecords() const;
  const std::string& logPath() const { return log_path_; }

 private:
  void collect(double mono);
  void writeObservation(const mrpt::obs::CObservation& obs);
  void writeHeader(mrpt::Clock::time_point t);
  void handleEvents();
  void printStatus(double mono, bool final_summary);
  void clearStatus();
  void logLine(const std::string& text, bool to_terminal);

  CaptureOptions opt_;
  std::string ini_text_;
  config::WheelchairConfig vehicle_;
  std::map<std::string, std::string> recording_meta_;
  std::vector<std::unique_ptr<CaptureSource>> sources_;
  std::unique_ptr<MergeBuffer> merge_;
  std::unique_ptr<RawlogAppender> out_;
  RawlogAppender::Options out_opt_;
  double window_s_ = 0.5, status_period_s_ = 1.0;
  bool header_written_ = false;
  std::size_t records_written_ = 0;
  std::atomic<bool> stop_requested_{false}, stop_threads_{false};
  std::string error_;
  std::string log_path_;
  std::ofstream log_;
  bool tty_ = false, live_ = false;
  int status_lines_ = 0;
  double start_mono_ = 0, last_status_mono_ = 0;
  std::vector<uint64_t> last_records_;
  std::vector<double> rates_;
  mutable std::mutex events_mtx_;
  std::vector<CaptureEvent> events_;
};

}  // namespace wheelchair::capture
