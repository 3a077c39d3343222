// Atomic, fully checked file output: a result is either complete at its path or absent.
//
// Every writer of the project goes through AtomicFile. The content goes to a temporary file
// in the target's directory (hidden name `.NAME.XXXXXX.tmp`, so the final rename stays on one
// file system and is atomic); commit() flushes, fsyncs and closes it, checking each step, and
// only then renames it over the target. Any failure (a full disk, a write error reported only
// at close, a vanished directory) throws one std::runtime_error line naming the target and
// the system's reason, e.g. "out/ekf.tum: cannot write: No space left on device", and removes
// the temporary. The destructor of an uncommitted file removes the temporary and never
// throws, so an exception anywhere in a writer leaves neither the target nor a temporary.
//
// The target must be absent or a regular file: a symbolic link, FIFO, device, socket or
// directory is refused before anything is written (replacing `/dev/sda` or a link into
// another tree with a regular file is never what a user meant).
//
// Two ways to fill the file:
//   - through stream(): an std::ostream over the temporary's descriptor (64 kB buffer; a
//     write of 64 kB or more goes to the file directly; a failed write(2) puts the stream
//     in bad state and keeps errno for the message);
//   - by name, for libraries that open files themselves (MRPT's gzip stream, OpenCV's
//     imwrite): write tempPath(), close it, check that library's own result, then commit().
//
// Example:
//   util::AtomicFile out("out/ekf.tum");
//   out.stream() << "# timestamp x y z qx qy qz qw\n";
//   for (...) { out.stream() << ...; out.check(); }   // check(): fail early on a full disk
//   out.commit();                                      // throws on any failure
//
// Or in one call: util::writeFileAtomically(path, [&](std::ostream& os) { os << ...; });
#pragma once

#include <functional>
#include <memory>
#include <ostream>
#include <string>
#include <string_view>

namespace wheelchair::util {

/// Throws (one line naming `path`) unless `path` is absent or a regular file.
void checkOutputTarget(const std::string& path);

class AtomicFile {
 public:
  /// Checks the target (checkOutputTarget) and creates the temporary beside it.
  explicit AtomicFile(std::string path);
  ~AtomicFile();  // removes the temporary unless committed; never throws
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  const std::string& path() const { return path_; }
  /// The temporary file (exists until commit() or destruction).
  const std::string& tempPath() const { return tmp_; }
  /// Stream writing the temporary file.
  std::ostream& stream();
  /// Throws if a write through stream() has failed so far (call it every so often in long
  /// writers so that a full disk stops the work early).
  void check() const;
  /// Flushes, fsyncs, closes and renames into place; throws on any failure (the temporary is
  /// removed, the target untouched). Idempotent once it has succeeded.
  void commit();
  bool committed() const { return committed_; }

 private:
  [[noreturn]] void fail(const std::string& what, int err);
  void removeTemp() noexcept;

  struct Buf;
  std::string path_, tmp_;
  int fd_ = -1;
  std::unique_ptr<Buf> buf_;
  std::unique_ptr<std::ostream> os_;
  bool committed_ = false;
};

/// Writes `path` atomically with `fill` (see AtomicFile).
void writeFileAtomically(const std::string& path, const std::function<void(std::ostream&)>& fill);
/// Writes `text` to `path` atomically.
void writeFileAtomically(const std::string& path, std::string_view text);

}  // namespace wheelchair::util
