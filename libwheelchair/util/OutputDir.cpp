#include "libwheelchair/util/OutputDir.h"

#include <fmt/format.h>

#include <filesystem>
#include <stdexcept>

namespace fs = std::filesystem;

namespace wheelchair::util {

OutputDir::OutputDir(std::string dir) : dir_(std::move(dir)) {
  if (dir_.empty()) throw std::invalid_argument("no output directory given");
  std::error_code ec;
  const auto st = fs::symlink_status(dir_, ec);
  if (fs::exists(st) && !fs::is_directory(fs::status(dir_, ec)))
    throw std::runtime_error(fmt::format("{}: exists and is not a directory", dir_));
  // Remember which levels are new, innermost last, to remove exactly those on failure.
  for (fs::path p = fs::path(dir_).lexically_normal(); !p.empty() && !fs::exists(p, ec);
       p = p.parent_path()) {
    created_dirs_.insert(created_dirs_.begin(), p.string());
    if (p == p.parent_path()) break;
  }
  fs::create_directories(dir_, ec);
  if (ec)
    throw std::runtime_error(fmt::format("{}: cannot create directory: {}", dir_, ec.message()));
}

std::string OutputDir::file(const std::string& name) {
  files_.push_back((fs::path(dir_) / name).string());
  return files_.back();
}

OutputDir::~OutputDir() {
  if (committed_) return;
  std::error_code ec;
  // A directory this run created holds only this run's files: remove it whole (the outermost
  // new level). Otherwise remove the files this run named.
  if (!created_dirs_.empty()) {
    fs::remove_all(created_dirs_.front(), ec);
    return;
  }
  for (const auto& f : files_) fs::remove(f, ec);
}

RemoveUnlessKept::~RemoveUnlessKept() {
  if (kept_) return;
  std::error_code ec;
  for (const auto& p : paths_) fs::remove_all(p, ec);  // a file, or a directory we wrote
}

}  // namespace wheelchair::util
