// An output directory that is either complete or, on failure, as it was before.
//
// Commands that write several files into a directory (report, diagnose --report) create it
// through OutputDir, name every file they write with file(), and call commit() at the end.
// If commit() is never reached (an exception: a full disk, a failed figure), the destructor
// removes the directory if OutputDir created it (with everything in it), otherwise the files
// named so far, so a failed run leaves no half report. Each file itself is written with
// util::AtomicFile.
//
// Example:
//   util::OutputDir out("report/");
//   util::writeFileAtomically(out.file("index.md"), [&](std::ostream& os) { os << md; });
//   out.commit();
#pragma once

#include <string>
#include <vector>

namespace wheelchair::util {

class OutputDir {
 public:
  /// Creates `dir` (and its parents) if missing; throws one line if it exists and is not a
  /// directory or cannot be created.
  explicit OutputDir(std::string dir);
  ~OutputDir();  // unless committed: removes what this run created (see above); never throws
  OutputDir(const OutputDir&) = delete;
  OutputDir& operator=(const OutputDir&) = delete;

  const std::string& dir() const { return dir_; }
  /// Path of `name` inside the directory, remembered for the clean-up.
  std::string file(const std::string& name);
  void commit() { committed_ = true; }

 private:
  std::string dir_;
  std::vector<std::string> created_dirs_, files_;
  bool committed_ = false;
};

/// For commands that write several separate files (e.g. identify --json + --write-config):
/// files already committed are removed again if a later one fails, so a failed run leaves
/// none of its outputs. add() each path once it is written; keep() at the end.
class RemoveUnlessKept {
 public:
  RemoveUnlessKept() = default;
  ~RemoveUnlessKept();  // removes the added paths unless keep() was called; never throws
  RemoveUnlessKept(const RemoveUnlessKept&) = delete;
  RemoveUnlessKept& operator=(const RemoveUnlessKept&) = delete;
  void add(const std::string& path) { paths_.push_back(path); }
  void keep() { kept_ = true; }

 private:
  std::vector<std::string> paths_;
  bool kept_ = false;
};

}  // namespace wheelchair::util
