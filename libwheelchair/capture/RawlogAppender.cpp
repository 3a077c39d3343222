#include "libwheelchair/capture/RawlogAppender.h"

#include "libwheelchair/capture/HostClock.h"

#include <fmt/format.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/serialization/CArchive.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <array>
#include <cerrno>
#include <cstring>

namespace wheelchair::capture {

uint32_t crc32(const void* data, std::size_t n, uint32_t crc) {
  static const std::array<uint32_t, 256> table = [] {
    std::array<uint32_t, 256> t{};
    for (uint32_t i = 0; i < 256; ++i) {
      uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  crc = ~crc;
  const auto* p = static_cast<const uint8_t*>(data);
  for (std::size_t i = 0; i < n; ++i) crc = table[(crc ^ p[i]) & 0xFF] ^ (crc >> 8);
  return ~crc;
}

RawlogAppender::RawlogAppender(const std::string& path, Options opt, bool overwrite)
    : path_(path), opt_(opt), pending_(std::make_unique<mrpt::io::CMemoryStream>()) {
  if (opt_.compression_level < 0 || opt_.compression_level > 9)
    throw WriteError("compression level must be 0..9");
  if (opt_.flush_period_s <= 0 || opt_.flush_period_s > 1.0)
    throw WriteError("flush period must be in (0, 1] s");
  const int flags = O_RDWR | O_CREAT | O_CLOEXEC | (overwrite ? O_TRUNC : O_EXCL);
  fd_ = ::open(path.c_str(), flags, 0644);
  if (fd_ < 0) {
    if (errno == EEXIST)
      throw WriteError(fmt::format("{}: already exists (use --force to overwrite)", path));
    throw WriteError(fmt::format("{}: cannot create: {}", path, std::strerror(errno)));
  }
  last_flush_mono_ = HostClock::monotonic();
}

RawlogAppender::~RawlogAppender() {
  try {
    if (!failed_ && !closed_) close();
  } catch (...) {
  }
  if (fd_ >= 0) ::close(fd_);
}

void RawlogAppender::write(const mrpt::serialization::CSerializable& obj) {
  if (failed_ || closed_) throw WriteError(path_ + ": write after close or failure");
  auto ar = mrpt::serialization::archiveFrom(*pending_);
  ar << obj;
  ++records_pending_;
}

bool RawlogAppender::flushIfDue(double mono_now) {
  if (mono_now - last_flush_mono_ < opt_.flush_period_s &&
      pending_->getTotalBytesCount() < opt_.max_pending_bytes)
    return false;
  flush();
  return true;
}

void RawlogAppender::flush() {
  if (failed_) throw WriteError(path_ + ": writing stopped after an error");
  if (records_pending_ > 0) writeMember();
  last_flush_mono_ = HostClock::monotonic();
}

void RawlogAppender::close() {
  if (closed_) return;
  flush();
  closed_ = true;
}

void RawlogAppender::fail(const std::string& what, int err) {
  failed_ = true;
  // Cut off whatever part of the member reached the disk: the file ends with the last
  // complete member again.
  std::string cut;
  if (::ftruncate(fd_, static_cast<off_t>(good_size_)) != 0)
    cut = fmt::format("; could not cut the partial member off: {}", std::strerror(errno));
  ::fsync(fd_);
  throw WriteError(fmt::format("{}: {}{}{}", path_, what,
                               err ? std::string(": ") + std::strerror(err) : std::string(), cut));
}

void RawlogAppender::writeMember() {
  const auto n = static_cast<std::size_t>(pending_->getTotalBytesCount());
  const void* data = pending_->getRawBufferData();
  mrpt::io::CFileGZOutputStream out;
  std::string err;
  errno = 0;
  if (!out.open(path_, opt_.compression_level, err, mrpt::io::OpenMode::APPEND))
    fail("cannot open for appending (" + err + ")", errno);
  errno = 0;
  const std::size_t w = out.Write(data, n);
  int e = errno;
  out.close();
  if (w != n) fail(fmt::format("write failed after {} of {} bytes", w, n), e ? e : errno);
  e = errno;
  // Check on disk that the member is complete: size, gzip magic, CRC-32 and length trailer.
  struct stat stt {};
  if (::fstat(fd_, &stt) != 0) fail("fstat", errno);
  const auto size = static_cast<uint64_t>(stt.st_size);
  uint8_t head[2] = {0, 0}, tail[8] = {};
  bool ok = size >= good_size_ + 18 && ::pread(fd_, head, 2, static_cast<off_t>(good_size_)) == 2 &&
            head[0] == 0x1f && head[1] == 0x8b &&
            ::pread(fd_, tail, 8, static_cast<off_t>(size - 8)) == 8;
  if (ok) {
    auto le32 = [](const uint8_t* p) {
      return uint32_t(p[0]) | (uint32_t(p[1]) << 8) | (uint32_t(p[2]) << 16) |
             (uint32_t(p[3]) << 24);
    };
    ok = le32(tail) == crc32(data, n) && le32(tail + 4) == static_cast<uint32_t>(n);
  }
  if (!ok)
    fail("incomplete write (gzip member not complete on disk)",
         e == ENOSPC || e == EFBIG || e == EIO || e == EDQUOT ? e : 0);
  if (opt_.fsync && ::fsync(fd_) != 0) {
    const int fe = errno;
    if (fe != EINVAL && fe != EROFS) fail("fsync", fe);  // not supported: nothing to sync
  }
  good_size_ = size;
  records_on_disk_ += records_pending_;
  records_pending_ = 0;
  ++members_;
  pending_ = std::make_unique<mrpt::io::CMemoryStream>();
}

}  // namespace wheelchair::capture
