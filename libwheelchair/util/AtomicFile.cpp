#include "libwheelchair/util/AtomicFile.h"

#include <fmt/format.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <streambuf>
#include <vector>

namespace wheelchair::util {

namespace {

const char* kindOf(mode_t m) {
  if (S_ISLNK(m)) return "a symbolic link";
  if (S_ISFIFO(m)) return "a FIFO";
  if (S_ISCHR(m) || S_ISBLK(m)) return "a device";
  if (S_ISSOCK(m)) return "a socket";
  if (S_ISDIR(m)) return "a directory";
  return "not a regular file";
}

}  // namespace

void checkOutputTarget(const std::string& path) {
  if (path.empty()) throw std::runtime_error("output path is empty");
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return;
    throw std::runtime_error(
        fmt::format("{}: cannot check output path: {}", path, std::strerror(errno)));
  }
  if (!S_ISREG(st.st_mode))
    throw std::runtime_error(fmt::format("{}: is {}; refusing to replace it with a regular file",
                                         path, kindOf(st.st_mode)));
}

/// std::streambuf over a file descriptor: 64 kB buffer, write(2) retried on EINTR and short
/// writes; the first failure's errno is kept and every later write fails.
struct AtomicFile::Buf : std::streambuf {
  explicit Buf(int fd) : fd(fd), data(1 << 16) { setp(data.data(), data.data() + data.size()); }
  int fd;
  int err = 0;
  std::vector<char> data;

  // Writes [p, p + left) to the file (false and `err` set on a failure).
  bool writeAll(const char* p, std::size_t left) {
    while (left > 0 && err == 0) {
      const ssize_t n = ::write(fd, p, left);
      if (n < 0) {
        if (errno == EINTR) continue;
        err = errno;
      } else {
        p += n;
        left -= static_cast<std::size_t>(n);
      }
    }
    return err == 0;
  }
  bool drain() {
    writeAll(pbase(), static_cast<std::size_t>(pptr() - pbase()));
    setp(data.data(), data.data() + data.size());
    return err == 0;
  }
  // A block at least as large as the buffer goes to the file without being copied into it
  // (the estimates CSV writes its rows in 256 kB blocks).
  std::streamsize xsputn(const char* s, std::streamsize n) override {
    if (n < static_cast<std::streamsize>(data.size())) return std::streambuf::xsputn(s, n);
    if (!drain() || !writeAll(s, static_cast<std::size_t>(n))) return 0;
    return n;
  }
  int_type overflow(int_type ch) override {
    if (!drain()) return traits_type::eof();
    if (!traits_type::eq_int_type(ch, traits_type::eof())) {
      *pptr() = traits_type::to_char_type(ch);
      pbump(1);
    }
    return traits_type::not_eof(ch);
  }
  int sync() override { return drain() ? 0 : -1; }
};

AtomicFile::AtomicFile(std::string path) : path_(std::move(path)) {
  checkOutputTarget(path_);
  const std::filesystem::path p(path_);
  const std::string dir = p.has_parent_path() ? p.parent_path().string() : std::string(".");
  std::string templ =
      (std::filesystem::path(dir) / ("." + p.filename().string() + ".XXXXXX.tmp")).string();
  std::vector<char> name(templ.begin(), templ.end());
  name.push_back('\0');
  fd_ = ::mkstemps(name.data(), 4);
  if (fd_ < 0)
    throw std::runtime_error(
        fmt::format("{}: cannot create a file in {}: {}", path_, dir, std::strerror(errno)));
  tmp_ = name.data();
  // mkstemp creates 0600; give the result the permissions a plain open() would (0666 & ~umask).
  const mode_t mask = ::umask(0);
  ::umask(mask);
  ::fchmod(fd_, 0666 & ~mask);
}

AtomicFile::~AtomicFile() {
  if (!committed_) removeTemp();
}

void AtomicFile::removeTemp() noexcept {
  os_.reset();
  buf_.reset();
  if (fd_ >= 0) {
    ::close(fd_);
    fd_ = -1;
  }
  if (!tmp_.empty()) ::unlink(tmp_.c_str());
}

std::ostream& AtomicFile::stream() {
  if (committed_) throw std::logic_error(path_ + ": stream() after commit()");
  if (!os_) {
    buf_ = std::make_unique<Buf>(fd_);
    os_ = std::make_unique<std::ostream>(buf_.get());
  }
  return *os_;
}

void AtomicFile::check() const {
  if (buf_ && buf_->err != 0) const_cast<AtomicFile*>(this)->fail("cannot write", buf_->err);
  if (os_ && !*os_) const_cast<AtomicFile*>(this)->fail("cannot write", buf_ ? buf_->err : 0);
}

void AtomicFile::fail(const std::string& what, int err) {
  removeTemp();
  throw std::runtime_error(err != 0 ? fmt::format("{}: {}: {}", path_, what, std::strerror(err))
                                    : fmt::format("{}: {}", path_, what));
}

void AtomicFile::commit() {
  if (committed_) return;
  if (os_) {
    os_->flush();
    check();
  }
  if (::fsync(fd_) != 0 && errno != EINVAL && errno != EROFS) fail("cannot write", errno);
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) fail("cannot write", errno);
  // The by-name writers opened and closed the temporary themselves; it must still be there.
  struct stat st {};
  if (::stat(tmp_.c_str(), &st) != 0) fail("temporary file vanished", errno);
  checkOutputTarget(path_);  // the target may have been replaced meanwhile
  if (::rename(tmp_.c_str(), path_.c_str()) != 0) fail("cannot rename into place", errno);
  committed_ = true;
  os_.reset();
  buf_.reset();
}

void writeFileAtomically(const std::string& path, const std::function<void(std::ostream&)>& fill) {
  AtomicFile f(path);
  fill(f.stream());
  f.commit();
}

void writeFileAtomically(const std::string& path, std::string_view text) {
  AtomicFile f(path);
  f.stream().write(text.data(), static_cast<std::streamsize>(text.size()));
  f.commit();
}

}  // namespace wheelchair::util
