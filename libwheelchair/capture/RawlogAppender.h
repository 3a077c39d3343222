// Continuous, crash-safe rawlog writing for `wheelchair capture` (docs/capture.md, "Writing").
//
// A rawlog is a gzip file; gzip allows a file to be a sequence of complete "members" and
// every gzip reader (zlib's gzread, hence mrpt::io::CFileGZInputStream, io::RawlogReader,
// RawLogViewer, rawlog-edit) reads them as one stream. Records are serialized into memory
// and, at least every flush period (<= 1 s), written as ONE complete member in one burst:
// mrpt::io::CFileGZOutputStream opened in APPEND mode, written, closed (then fsync). So at
// any time the file is a whole number of complete members, each ending on a record
// boundary:
//  - kill -9 / power cut: the file holds every record up to the last flush; at worst the
//    member being written in that burst is cut, and readers stop cleanly before it;
//  - the file can be read (`wheelchair info`, rawlog-edit) while it is being written;
//  - a failed write (full disk, EFBIG, I/O error) is detected (write count, then the
//    member's gzip trailer - CRC-32 and length - checked on disk), the partial member is cut
//    off again (ftruncate), and WriteError is thrown: the file stays readable to its end.
#pragma once

#include <mrpt/io/CMemoryStream.h>
#include <mrpt/serialization/CSerializable.h>

#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>

namespace wheelchair::capture {

struct WriteError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class RawlogAppender {
 public:
  struct Options {
    int compression_level = 1;    ///< 0 (stored) .. 9; 1 = fast, MRPT's grabber default
    double flush_period_s = 1.0;  ///< a member is written at least this often
    bool fsync = true;            ///< fsync after every member (power-cut safety)
    std::size_t max_pending_bytes = 8u << 20;  ///< flush early above this (uncompressed)
  };

  /// Creates `path` (fails if it exists unless overwrite). Throws WriteError.
  RawlogAppender(const std::string& path, Options opt, bool overwrite = false);
  ~RawlogAppender();  ///< best-effort final flush (errors swallowed; call close() to see them)

  /// Serializes a record into the pending buffer (nothing touches the disk).
  void write(const mrpt::serialization::CSerializable& obj);
  /// Writes the pending records as one member if the flush period elapsed since the last
  /// flush (or the buffer is large). Returns true if it wrote. Throws WriteError.
  bool flushIfDue(double mono_now);
  /// Writes the pending records now (no-op when none). Throws WriteError.
  void flush();
  /// Final flush; further writes are errors. Throws WriteError.
  void close();

  const std::string& path() const { return path_; }
  std::size_t recordsOnDisk() const { return records_on_disk_; }
  std::size_t recordsPending() const { return records_pending_; }
  uint64_t bytesOnDisk() const { return good_size_; }
  std::size_t members() const { return members_; }
  /// Monotonic time of the last successful flush (or of creation).
  double lastFlushMono() const { return last_flush_mono_; }

 private:
  void writeMember();
  [[noreturn]] void fail(const std::string& what, int err);

  std::string path_;
  Options opt_;
  int fd_ = -1;  ///< kept open for fstat/pread/ftruncate/fsync
  std::unique_ptr<mrpt::io::CMemoryStream> pending_;
  std::size_t records_pending_ = 0, records_on_disk_ = 0, members_ = 0;
  uint64_t good_size_ = 0;
  double last_flush_mono_ = 0;
  bool failed_ = false, closed_ = false;
};

/// CRC-32 (gzip's polynomial), for checking a member's trailer.
uint32_t crc32(const void* data, std::size_t n, uint32_t crc = 0);

}  // namespace wheelchair::capture
