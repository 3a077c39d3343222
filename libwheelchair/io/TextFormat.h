// The plain-text recording format (docs/recording-format.md): a directory with one CSV file
// per stream (encoders.csv, imu.csv, motors.csv required; sonar.csv, pozyx.csv,
// joystick.csv optional; meta.ini kept as-is).
//
// Reading is streamed: TextRecordingReader merges the files in time order one row at a time,
// so memory stays flat whatever the file size. Every error names the file and line.
// Writing goes to a temporary directory that is renamed into place on commit(), so a failed
// export never leaves a half-written recording.
//
// Example:
//   TextRecordingReader in("datasets/three_task");
//   AnySample s;
//   while (in.next(s)) { ... }
//   for (auto& w : in.warnings()) std::cerr << w << "\n";
#pragma once

#include "libwheelchair/config/Options.h"
#include "libwheelchair/io/Samples.h"
#include "libwheelchair/util/AtomicFile.h"

#include <fstream>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace wheelchair::io {

/// Thrown for malformed input; what() names the file and line.
struct FormatError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Streams the rows of one CSV file of the format.
class CsvStreamReader {
 public:
  CsvStreamReader(const std::string& path, StreamKind kind);
  /// Reads the next row; false at end of file. Throws FormatError on a malformed row.
  bool next(AnySample& out);
  const std::string& path() const { return path_; }
  std::size_t line() const { return line_no_; }
  /// Columns present in the header (e.g. imu.csv's optional ones).
  const std::vector<std::string>& columns() const { return columns_; }

 private:
  std::string path_;
  StreamKind kind_;
  std::ifstream in_;
  std::size_t line_no_ = 0;
  std::vector<std::string> columns_;
  std::string buf_;
  std::vector<double> values_;
};

/// Per-stream timestamp health, collected while reading (see also RecordingStats.h).
struct TimestampIssues {
  std::size_t out_of_order = 0;
  std::size_t duplicates = 0;
  std::size_t first_bad_line = 0;
};

class TextRecordingReader {
 public:
  explicit TextRecordingReader(const std::string& dir);
  ~TextRecordingReader();
  /// Next sample over all files in time order (file order kept within a file).
  bool next(AnySample& out);
  /// meta.ini [recording] keys.
  const std::map<std::string, std::string>& meta() const { return meta_; }
  /// Human-readable warnings (missing optional files, timestamp issues), filled as read.
  std::vector<std::string> warnings() const;
  /// Columns of each present file.
  std::map<StreamKind, std::vector<std::string>> columns() const;
  /// Refuse forward jumps of the merged timeline (all files) larger than max_gap_s (0: no
  /// check, the default): next() throws FormatError naming the file, line and size of the jump.
  /// `wheelchair import` sets it from [import] max_gap_s (default kDefaultMaxGapS).
  void setMaxGap(double max_gap_s) { max_gap_s_ = max_gap_s; }

 private:
  struct Source;
  std::vector<std::unique_ptr<Source>> sources_;
  std::map<std::string, std::string> meta_;
  std::vector<std::string> missing_optional_;
  double max_gap_s_ = 0;
  // The latest sample returned so far (out-of-order rows do not move it): its source (stable:
  // sources_ owns them), time and line, for the gap check's message.
  const Source* last_src_ = nullptr;
  double last_t_ = 0;  ///< s
  std::size_t last_line_ = 0;
};

/// Default of [import] max_gap_s (s): the largest forward jump of a recording's timeline that
/// `wheelchair import` accepts (docs/recording-format.md).
constexpr double kDefaultMaxGapS = 5.0;

/// [import] options of `wheelchair import` (config/Options.h key table).
struct ImportOptions {
  double max_gap_s = kDefaultMaxGapS;  ///< largest accepted forward jump of the timeline; 0: off
  config::Options options(const std::string& section = "import");
};

/// Whole recording in memory (for moderate sizes; use TextRecordingReader to stream).
Recording readTextRecording(const std::string& dir, std::vector<std::string>* warnings = nullptr);

/// Streams samples into a recording directory; files appear only on commit(). Every file is
/// an util::AtomicFile inside a temporary directory `DIR.tmp-export` that commit() renames to
/// DIR: any write failure (a full disk) throws one line naming the file and leaves neither DIR
/// nor the temporary directory. DIR must be absent, empty or a recording directory.
class TextRecordingWriter {
 public:
  explicit TextRecordingWriter(const std::string& dir);
  ~TextRecordingWriter();  // removes the temporary directory unless committed
  void write(const AnySample& s);
  void setMeta(const std::map<std::string, std::string>& meta) { meta_ = meta; }
  /// Optional streams are written only if they had samples; required ones always.
  void commit();

 private:
  std::ostream& fileFor(StreamKind k, const AnySample& first);
  std::string dir_, tmp_dir_;
  std::map<StreamKind, std::unique_ptr<util::AtomicFile>> files_;
  std::map<std::string, std::string> meta_;
  bool committed_ = false;
};

void writeTextRecording(const Recording& rec, const std::string& dir);

/// Formats a value with the shortest representation that reads back identically.
std::string formatNumber(double x);
/// Timestamps are exported at 1 microsecond resolution (MRPT clock ticks are 100 ns).
std::string formatTime(double t_s);

}  // namespace wheelchair::io
