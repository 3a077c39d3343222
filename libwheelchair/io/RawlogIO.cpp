#include "libwheelchair/io/RawlogIO.h"

#include "libwheelchair/config/Options.h"
#include "libwheelchair/util/AtomicFile.h"
#include "libwheelchair/util/Text.h"

#include <fmt/format.h>
#include <isa-l/igzip_lib.h>
#include <mrpt/core/Clock.h>
#include <mrpt/io/CStream.h>
#include <mrpt/obs/CObservationBearingRange.h>
#include <mrpt/obs/CObservationComment.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CObservationRange.h>
#include <mrpt/obs/CObservationRawDAQ.h>
#include <mrpt/obs/CObservationRobotPose.h>
#include <mrpt/serialization/CArchive.h>
#include <zlib.h>

#include <fcntl.h>
#include <unistd.h>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <sstream>
#include <stdexcept>

namespace fs = std::filesystem;
using namespace mrpt::obs;

namespace wheelchair::io {

namespace {

// MRPT stores sonar ranges and landmark sightings as float: read them back as the decimal
// value the float prints as (shortest representation), which is what was recorded.
double floatAsDecimal(float x) {
  return std::strtod(fmt::format("{}", x).c_str(), nullptr);
}

constexpr double kUnknownZVariance_m2 = 1e6;
constexpr const char* kHeaderFirstLine = "# libwheelchair recording";
constexpr const char* kHeaderCrcKey = "# header crc32 = ";
constexpr const char* kHeaderConfigMark = "# configuration used when writing this file\n";

/// CRC-32 of the header text and its timestamp (so a flipped bit in either is detected).
unsigned long headerCrc(std::string_view text, mrpt::Clock::time_point t) {
  const std::string stamp = fmt::format("{}", t.time_since_epoch().count());
  auto crc = crc32(0L, reinterpret_cast<const Bytef*>(text.data()), static_cast<uInt>(text.size()));
  return crc32(crc, reinterpret_cast<const Bytef*>(stamp.data()), static_cast<uInt>(stamp.size()));
}

// [recording]: free-form metadata of a recording (meta.ini, the rawlog header, capture.ini),
// so that a header text loads as a configuration (WheelchairConfig::fromText) strictly.
[[maybe_unused]] const bool kRegistered = config::registerOptions([] {
  return std::vector<config::Options>{
      config::Options("recording")
          .anyKey("free-form metadata of the recording (operator, notes, scenario, ...)")};
});
const mrpt::obs::TIMUDataIndex kImuExtra[5] = {IMU_WX, IMU_WY, IMU_X_ACC, IMU_Y_ACC, IMU_Z_ACC};

// MRPT's clock counts 100 ns ticks since 1601 in an unsigned-compatible range: a negative or
// non-finite time would wrap to a date ~1.8e12 s away instead of failing.
mrpt::Clock::time_point mrptTime(double t_s) {
  if (!(t_s >= 0) || !std::isfinite(t_s))
    throw std::invalid_argument(
        fmt::format("timestamp {} s cannot be stored (times are finite seconds >= 0)", t_s));
  return mrpt::Clock::fromDouble(t_s);
}

template <class T>
typename T::Ptr stamped(StreamKind k, double t_s) {
  auto o = T::Create();
  o->timestamp = mrptTime(t_s);
  o->sensorLabel = streamLabel(k);
  return o;
}

CObservationRawDAQ::Ptr daq(StreamKind k, double t_s, std::vector<double> values) {
  auto o = stamped<CObservationRawDAQ>(k, t_s);
  o->AIN_channel_count = static_cast<uint16_t>(values.size());
  o->AIN_double = std::move(values);
  return o;
}

}  // namespace

CObservation::Ptr toObservation(const AnySample& s, const config::WheelchairConfig& cfg) {
  const StreamKind k = kindOf(s);
  return std::visit(
      [&](const auto& x) -> CObservation::Ptr {
        using T = std::decay_t<decltype(x)>;
        if constexpr (std::is_same_v<T, EncoderSample>) {
          auto o = stamped<CObservationOdometry>(k, x.t_s);
          o->hasEncodersInfo = true;
          o->encoderRightTicks = x.right_ticks;
          o->encoderLeftTicks = x.left_ticks;
          return o;
        } else if constexpr (std::is_same_v<T, ImuSample>) {
          auto o = stamped<CObservationIMU>(k, x.t_s);
          o->set(IMU_WZ, x.gyro_z_rad_s);
          if (x.has_extra)
            for (int i = 0; i < 5; ++i) o->set(kImuExtra[i], x.extra[i]);
          return o;
        } else if constexpr (std::is_same_v<T, MotorSample>) {
          return daq(k, x.t_s, {x.current_right_A, x.current_left_A, x.vrc_right_V, x.vrc_left_V});
        } else if constexpr (std::is_same_v<T, SonarSample>) {
          auto o = stamped<CObservationRange>(k, x.t_s);
          o->minSensorDistance = static_cast<float>(cfg.sonar.min_range_m);
          o->maxSensorDistance = static_cast<float>(cfg.sonar.max_range_m);
          o->sensorConeApperture =
              static_cast<float>(2 * cfg.sonar.cone_half_angle_deg * M_PI / 180);
          CObservationRange::TMeasurement m;
          m.sensorID = 0;
          m.sensorPose = mrpt::math::TPose3D(cfg.sonar.x_m, cfg.sonar.y_m, 0,
                                             cfg.sonar.yaw_deg * M_PI / 180, 0, 0);
          m.sensedDistance = static_cast<float>(x.range_m);
          o->sensedData.push_back(m);
          return o;
        } else if constexpr (std::is_same_v<T, PozyxSample>) {
          auto o = stamped<CObservationRobotPose>(k, x.t_s);
          o->pose.mean = mrpt::poses::CPose3D(x.x_m, x.y_m, x.has_z ? x.z_m : 0.0, 0, 0, 0);
          o->pose.cov.setZero();
          const double var = cfg.pozyx.noise_m * cfg.pozyx.noise_m;
          o->pose.cov(0, 0) = var;
          o->pose.cov(1, 1) = var;
          o->pose.cov(2, 2) = x.has_z ? var : kUnknownZVariance_m2;
          // Orientation is not measured by the tag.
          for (int i = 3; i < 6; ++i) o->pose.cov(i, i) = kUnknownZVariance_m2;
          o->sensorPose =
              mrpt::poses::CPose3D(cfg.pozyx.lever_x_m, cfg.pozyx.lever_y_m, 0, 0, 0, 0);
          return o;
        } else if constexpr (std::is_same_v<T, JoystickSample>) {
          return daq(k, x.t_s, {x.v_cmd_m_s, x.omega_cmd_rad_s});
        } else if constexpr (std::is_same_v<T, GroundTruthPoseSample>) {
          auto o = stamped<CObservationRobotPose>(k, x.t_s);
          o->pose.mean = mrpt::poses::CPose3D(x.x_m, x.y_m, 0, x.phi_rad, 0, 0);
          o->pose.cov.setZero();
          for (int i = 0; i < 6; ++i) o->pose.cov(i, i) = 1e-6;  // motion capture, ~1 mm
          return o;
        } else {
          static_assert(std::is_same_v<T, LandmarkSample>);
          auto o = stamped<CObservationBearingRange>(k, x.t_s);
          CObservationBearingRange::TMeasurement m;
          m.landmarkID = x.landmark_id;
          m.range = static_cast<float>(x.range_m);
          m.yaw = static_cast<float>(x.bearing_rad);
          m.pitch = 0;
          o->sensedData.push_back(m);
          return o;
        }
      },
      s);
}

std::optional<AnySample> fromObservation(const CObservation& obs) {
  const double t = mrpt::Clock::toDouble(obs.timestamp);
  const std::string& label = obs.sensorLabel;
  if (auto o = dynamic_cast<const CObservationOdometry*>(&obs);
      o && o->hasEncodersInfo && label == "ENCODERS") {
    return EncoderSample{t, o->encoderRightTicks, o->encoderLeftTicks};
  }
  if (auto o = dynamic_cast<const CObservationIMU*>(&obs); o && label == "IMU" && o->has(IMU_WZ)) {
    ImuSample s{t, o->get(IMU_WZ), o->has(IMU_WX), {}};
    if (s.has_extra)
      for (int i = 0; i < 5; ++i) s.extra[i] = o->has(kImuExtra[i]) ? o->get(kImuExtra[i]) : 0.0;
    return s;
  }
  if (auto o = dynamic_cast<const CObservationRawDAQ*>(&obs)) {
    const auto& a = o->AIN_double;
    if (label == "MOTORS" && a.size() == 4) return MotorSample{t, a[0], a[1], a[2], a[3]};
    if (label == "JOYSTICK" && a.size() == 2) return JoystickSample{t, a[0], a[1]};
    return std::nullopt;
  }
  if (auto o = dynamic_cast<const CObservationRange*>(&obs);
      o && label == "SONAR" && !o->sensedData.empty()) {
    return SonarSample{t, floatAsDecimal(o->sensedData.front().sensedDistance)};
  }
  if (auto o = dynamic_cast<const CObservationRobotPose*>(&obs)) {
    const auto& m = o->pose.mean;
    if (label == "POZYX") {
      const bool has_z = o->pose.cov(2, 2) < kUnknownZVariance_m2;
      return PozyxSample{t, m.x(), m.y(), has_z, has_z ? m.z() : 0.0};
    }
    if (label == "GROUND_TRUTH") return GroundTruthPoseSample{t, m.x(), m.y(), m.yaw()};
    return std::nullopt;
  }
  if (auto o = dynamic_cast<const CObservationBearingRange*>(&obs);
      o && label == "LANDMARKS" && !o->sensedData.empty()) {
    const auto& m = o->sensedData.front();
    return LandmarkSample{t, m.landmarkID, floatAsDecimal(m.range), floatAsDecimal(m.yaw)};
  }
  return std::nullopt;
}

// ---------------------------------------------------------------- RawlogWriter

/// mrpt::io::CStream that gzip-compresses (zlib, gzip wrapper) into an AtomicFile. Every
/// deflate call and every write is checked; the first failure is kept in `error` (one line
/// naming the target) and thrown, since MRPT wraps exceptions thrown through its archives in
/// multi-line texts, RawlogWriter rethrows `error` itself.
struct RawlogWriter::GzipOut : mrpt::io::CStream {
  util::AtomicFile file;
  z_stream zs{};
  bool open = false;
  uint64_t pos = 0;
  std::string error;
  std::vector<unsigned char> chunk = std::vector<unsigned char>(1 << 16);

  GzipOut(const std::string& path, int level) : file(path) {
    if (deflateInit2(&zs, level, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK)
      throw std::runtime_error(fmt::format("{}: cannot initialise gzip compression", path));
    open = true;
  }
  ~GzipOut() override {
    if (open) deflateEnd(&zs);
  }
  [[noreturn]] void fail(const std::string& what) {
    error = what;
    throw std::runtime_error(what);
  }
  void pump(int flush) {
    int rc = Z_OK;
    do {
      zs.next_out = chunk.data();
      zs.avail_out = static_cast<uInt>(chunk.size());
      rc = deflate(&zs, flush);
      if (rc == Z_STREAM_ERROR) fail(file.path() + ": gzip compression failed");
      file.stream().write(reinterpret_cast<const char*>(chunk.data()),
                          static_cast<std::streamsize>(chunk.size() - zs.avail_out));
    } while (zs.avail_out == 0 || (flush == Z_FINISH && rc != Z_STREAM_END));
    try {
      file.check();  // a full disk stops the writer here, not at the end
    } catch (const std::exception& e) {
      fail(e.what());
    }
  }
  size_t Read(void*, size_t) override { throw std::logic_error("GzipOut is write-only"); }
  size_t Write(const void* buf, size_t n) override {
    if (!error.empty()) throw std::runtime_error(error);
    zs.next_in = static_cast<Bytef*>(const_cast<void*>(buf));
    zs.avail_in = static_cast<uInt>(n);
    pump(Z_NO_FLUSH);
    pos += n;
    return n;
  }
  uint64_t Seek(int64_t, TSeekOrigin) override { throw std::logic_error("GzipOut cannot seek"); }
  uint64_t getTotalBytesCount() const override { return pos; }
  uint64_t getPosition() const override { return pos; }
  std::string getStreamDescription() const override { return file.path(); }
  void finish() {
    zs.next_in = nullptr;
    zs.avail_in = 0;
    pump(Z_FINISH);
    deflateEnd(&zs);
    open = false;
    try {
      file.commit();
    } catch (const std::exception& e) {
      fail(e.what());
    }
  }
};

RawlogWriter::RawlogWriter(const std::string& path, int compression_level)
    : path_(path), out_(std::make_unique<GzipOut>(path, compression_level)) {}

RawlogWriter::~RawlogWriter() = default;  // AtomicFile removes the temporary unless committed

void RawlogWriter::write(const mrpt::serialization::CSerializable& obj) {
  try {
    auto ar = mrpt::serialization::archiveFrom(*out_);
    ar << obj;
  } catch (const std::exception& e) {
    if (!out_->error.empty()) throw std::runtime_error(out_->error);
    throw std::runtime_error(fmt::format("{}: cannot serialize record {}: {}", path_, count_,
                                         util::oneLineMessage(e.what())));
  }
  ++count_;
}

void RawlogWriter::write(const AnySample& s, const config::WheelchairConfig& cfg) {
  write(*toObservation(s, cfg));
}

void RawlogWriter::writeHeader(const std::map<std::string, std::string>& meta,
                               const config::WheelchairConfig& cfg, double t_s) {
  auto c = CObservationComment::Create();
  c->timestamp = mrptTime(t_s);
  c->sensorLabel = "META";
  std::ostringstream ss;
  ss << kHeaderFirstLine << "\n[recording]\n";
  for (const auto& [k, v] : meta) ss << k << " = " << v << "\n";
  ss << kHeaderConfigMark << cfg.text();
  std::string text = ss.str();
  if (!text.empty() && text.back() != '\n') text += '\n';
  // A checksum of the text before it, so a damaged header is reported as such (RawlogReader).
  const auto crc = headerCrc(text, c->timestamp);
  c->text = text + fmt::format("{}{:08x}\n", kHeaderCrcKey, crc);
  write(*c);
}

void RawlogWriter::commit() {
  if (committed_) return;
  if (!out_->error.empty()) throw std::runtime_error(out_->error);
  out_->finish();
  committed_ = true;
}

// ---------------------------------------------------------------- RawlogReader

namespace {

/// Reads a gzip file -- every member of it, as zlib's gzread does (capture appends one member
/// per flush) -- or, like gzread, a file that does not start with the gzip magic 1f 8b as it
/// is, into `buf`. The file is read in 128 KiB blocks and inflated by ISA-L's streaming
/// isal_inflate (Intel ISA-L, typically 2-3x zlib's speed) with crc_flag ISAL_GZIP: it parses
/// each member's header and checks its trailer (CRC-32 and length of the data). Bytes after a
/// member that do not start another one end the data, as in gzread.
class Inflater {
 public:
  static constexpr std::size_t kBufBytes = 1 << 18;
  static constexpr std::size_t kInBytes = 1 << 17;
  std::vector<unsigned char> buf = std::vector<unsigned char>(kBufBytes);
  std::size_t beg = 0, end = 0;  ///< buffered, not yet handed out: buf[beg, end)
  uint64_t inflated = 0;         ///< uncompressed bytes produced
  std::string error;             ///< set when the data is damaged or cut (never at a clean end)
  bool eof = false;              ///< the last byte has been produced (clean end or damage)

  Inflater() = default;
  Inflater(const Inflater&) = delete;
  Inflater& operator=(const Inflater&) = delete;
  ~Inflater() {
    if (fd_ >= 0) ::close(fd_);
  }
  /// Opens `path` and looks at its first bytes; false (errno set) if it cannot be opened.
  bool open(const std::string& path) {
    fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd_ < 0) return false;
    st_.next_in = in_.data();
    st_.avail_in = 0;
    gzip_ = input(2) && isGzipStart();
    if (gzip_) startMember();
    return true;
  }
  /// Compressed (file) bytes consumed so far.
  uint64_t fileBytesUsed() const { return file_read_ - st_.avail_in; }
  /// Fills the free part of the buffer (less only at the end of the data, clean or not: no
  /// read after it).
  void more() {
    if (beg > 0) {
      std::memmove(buf.data(), buf.data() + beg, end - beg);
      end -= beg;
      beg = 0;
    }
    if (gzip_) {
      inflateMore();
      return;
    }
    while (end < buf.size()) {
      if (st_.avail_in == 0 && !input(1)) break;
      const std::size_t k = std::min<std::size_t>(st_.avail_in, buf.size() - end);
      std::memcpy(buf.data() + end, st_.next_in, k);
      st_.next_in += k;
      st_.avail_in -= static_cast<uint32_t>(k);
      end += k;
      inflated += k;
    }
    if (end < buf.size()) eof = true;
  }
  /// At least `n` bytes buffered unless the data ends first; the number buffered.
  std::size_t fill(std::size_t n) {
    while (end - beg < n && !eof) more();
    return end - beg;
  }

 private:
  bool isGzipStart() const { return st_.next_in[0] == 0x1f && st_.next_in[1] == 0x8b; }
  /// At least `n` compressed bytes at st_.next_in unless the file ends first.
  bool input(std::size_t n) {
    while (st_.avail_in < n && st_.avail_in < in_.size() && !file_end_) {
      std::memmove(in_.data(), st_.next_in, st_.avail_in);
      st_.next_in = in_.data();
      const ssize_t got = ::read(fd_, in_.data() + st_.avail_in, in_.size() - st_.avail_in);
      if (got < 0 && errno == EINTR) continue;
      if (got < 0) read_errno_ = errno;
      if (got <= 0) {
        file_end_ = true;
        break;
      }
      st_.avail_in += static_cast<uint32_t>(got);
      file_read_ += static_cast<uint64_t>(got);
    }
    return st_.avail_in >= n;
  }
  void startMember() {
    uint8_t* next = st_.next_in;
    const uint32_t avail = st_.avail_in;
    isal_inflate_init(&st_);
    st_.next_in = next;
    st_.avail_in = avail;
    st_.crc_flag = ISAL_GZIP;
  }
  void inflateMore() {
    while (end < buf.size() && !eof) {
      if (st_.block_state == ISAL_BLOCK_FINISH) {  // a member ended: another one, or the end
        if (!input(2) || !isGzipStart()) {
          eof = true;
          break;
        }
        startMember();
      }
      if (st_.avail_in == 0) input(1);
      const auto state = st_.block_state;
      const auto bits = st_.read_in_length;
      const uint32_t avail = st_.avail_in;
      st_.next_out = buf.data() + end;
      st_.avail_out = static_cast<uint32_t>(buf.size() - end);
      const int rc = isal_inflate(&st_);
      const auto got = static_cast<std::size_t>(st_.next_out - (buf.data() + end));
      end += got;
      inflated += got;
      if (rc != ISAL_DECOMP_OK) {
        damaged(inflateError(rc));
      } else if (got == 0 && st_.avail_in == avail && st_.block_state == state &&
                 st_.read_in_length == bits && st_.block_state != ISAL_BLOCK_FINISH &&
                 !input(std::size_t{st_.avail_in} + 1)) {
        // No progress on all the input there is, and the file has no more: cut (or unreadable).
        if (read_errno_ != 0)
          damaged(fmt::format("read error: {}", std::strerror(read_errno_)));
        else
          cut();
      }
    }
  }
  static std::string inflateError(int rc) {
    switch (rc) {
      case ISAL_INVALID_BLOCK:
        return "invalid deflate block";
      case ISAL_INVALID_SYMBOL:
        return "invalid code";
      case ISAL_INVALID_LOOKBACK:
        return "invalid distance too far back";
      case ISAL_INVALID_WRAPPER:
        return "invalid gzip header";
      case ISAL_UNSUPPORTED_METHOD:
        return "unknown compression method";
      case ISAL_INCORRECT_CHECKSUM:
        return "incorrect data check (gzip trailer CRC-32 or length)";
      default:
        return fmt::format("isal_inflate error {}", rc);
    }
  }
  void damaged(const std::string& why) {
    eof = true;
    error =
        fmt::format("compressed data damaged at uncompressed byte {} (inflate: {})", inflated, why);
  }
  void cut() {
    eof = true;
    error = fmt::format("file cut short: the gzip stream ends at uncompressed byte {}", inflated);
  }

  int fd_ = -1;
  bool gzip_ = false;
  bool file_end_ = false;
  int read_errno_ = 0;
  uint64_t file_read_ = 0;
  std::vector<unsigned char> in_ = std::vector<unsigned char>(kInBytes);
  inflate_state st_{};
};

/// True if the first record of `path` names MRPT's comment class (the class of our header).
bool startsWithCommentRecord(const std::string& path) {
  Inflater in;
  if (!in.open(path)) return false;
  const std::size_t n = std::min<std::size_t>(in.fill(64), 64);
  return std::string_view(reinterpret_cast<const char*>(in.buf.data() + in.beg), n)
             .find("CObservationComment") != std::string_view::npos;
}

/// Why record 0 (if it is, or was meant to be, our META header) is damaged; nullopt if fine.
std::optional<std::string> headerDamage(const mrpt::serialization::CSerializable& obj) {
  const auto* c = dynamic_cast<const CObservationComment*>(&obj);
  if (!c) return std::nullopt;
  const std::string& t = c->text;
  if (t.rfind(kHeaderFirstLine, 0) != 0) {
    if (t.find("\n[recording]\n") != std::string::npos)
      return fmt::format("its first line is not '{}'", kHeaderFirstLine);
    return std::nullopt;  // some other comment: not ours
  }
  // The checksum line is the last line: '#', the key, 8 hex digits (files written before the
  // checksum existed end with a configuration line, which never starts with '#').
  const std::size_t crc_line = std::strlen(kHeaderCrcKey) + 8;
  if (t.size() < crc_line + 1 || t.back() != '\n') return std::nullopt;
  const std::size_t k = t.size() - 1 - crc_line;
  if (t[k] != '#' || (k > 0 && t[k - 1] != '\n')) return std::nullopt;
  if (t.compare(k, std::strlen(kHeaderCrcKey), kHeaderCrcKey) != 0)
    return std::string("checksum line damaged");
  const auto crc = headerCrc(std::string_view(t).substr(0, k), c->timestamp);
  if (t.compare(k + std::strlen(kHeaderCrcKey), 8, fmt::format("{:08x}", crc)) != 0)
    return std::string("checksum mismatch (a byte of the header text changed)");
  return std::nullopt;
}

}  // namespace

/// mrpt::io::CStream reading a gzip (or, like MRPT's reader, an uncompressed) file through
/// Inflater, keeping its error: MRPT's own reader turns a damaged gzip stream into a silent end
/// of file, which at a record boundary would look like a clean end. The decompressed bytes go
/// through a buffer (MRPT reads field by field; one read call per field cost more than the
/// decompression), which also lets nextSample() decode a record in place.
struct RawlogReader::GzipIn : mrpt::io::CStream, Inflater {
  uint64_t pos = 0;  ///< uncompressed bytes handed out (the reader's position)

  void consume(std::size_t n) {
    beg += n;
    pos += n;
  }
  size_t Read(void* out, size_t n) override {
    auto* o = static_cast<unsigned char*>(out);
    std::size_t done = 0;
    while (done < n) {
      if (beg == end) {
        if (eof) break;
        more();
        continue;
      }
      const std::size_t k = std::min(n - done, end - beg);
      std::memcpy(o + done, buf.data() + beg, k);
      beg += k;
      done += k;
    }
    pos += done;
    return done;
  }
  size_t Write(const void*, size_t) override { throw std::logic_error("GzipIn is read-only"); }
  uint64_t Seek(int64_t, TSeekOrigin) override { throw std::logic_error("GzipIn cannot seek"); }
  uint64_t getTotalBytesCount() const override { return pos; }
  uint64_t getPosition() const override { return pos; }
};

namespace {

/// Reads MRPT's serialization of the records nextSample() decodes in place (little-endian,
/// as MRPT writes on this platform): a class header (name length | 0x80, name, version byte),
/// the fields, the end flag 0x88. Any mismatch sets ok = false (the caller falls back).
struct FastCursor {
  const unsigned char* p;
  const unsigned char* e;
  bool ok = true;

  template <class T>
  T get() {
    T v{};
    if (!ok || static_cast<std::size_t>(e - p) < sizeof(T)) {
      ok = false;
      return v;
    }
    std::memcpy(&v, p, sizeof(T));
    p += sizeof(T);
    return v;
  }
  void expect(std::string_view bytes) {
    if (!ok || static_cast<std::size_t>(e - p) < bytes.size() ||
        std::memcmp(p, bytes.data(), bytes.size()) != 0) {
      ok = false;
      return;
    }
    p += bytes.size();
  }
  void skip(std::size_t n) {
    if (!ok || static_cast<std::size_t>(e - p) < n) {
      ok = false;
      return;
    }
    p += n;
  }
  /// A std::string field (uint32 length, bytes) equal to `s`.
  void label(std::string_view s) {
    if (get<uint32_t>() != s.size()) ok = false;
    expect(s);
  }
  /// A std::string field; its text.
  std::string_view label() {
    const auto n = get<uint32_t>();
    if (!ok || static_cast<std::size_t>(e - p) < n) {
      ok = false;
      return {};
    }
    std::string_view v(reinterpret_cast<const char*>(p), n);
    p += n;
    return v;
  }
  double time() {
    const auto ticks = get<uint64_t>();
    return mrpt::Clock::toDouble(mrpt::Clock::time_point(mrpt::Clock::duration(ticks)));
  }
  void endFlag() { expect(std::string_view("\x88", 1)); }
  void emptyVectors(int n) {
    for (int i = 0; i < n; ++i)
      if (get<uint32_t>() != 0) ok = false;
  }
};

/// MRPT's class header: name length | 0x80, the name, the version byte.
std::string classHeader(std::string_view name, uint8_t version) {
  std::string h(1, static_cast<char>(0x80 | name.size()));
  h += name;
  h += static_cast<char>(version);
  return h;
}

/// The sample of one record at c.p in the layouts listed at RawlogReader::nextSample; the
/// bytes it took, 0 if the record is not one of them.
std::size_t decodeInPlace(FastCursor c, AnySample& s) {
  static const std::string kOdometry = classHeader("mrpt::obs::CObservationOdometry", 2);
  static const std::string kImu = classHeader("mrpt::obs::CObservationIMU", 4);
  static const std::string kDaq = classHeader("mrpt::obs::CObservationRawDAQ", 0);
  static const std::string kPose2D = classHeader("mrpt::poses::CPose2D", 1);
  static const std::string kPose3D = classHeader("mrpt::poses::CPose3D", 3);
  const unsigned char* const start = c.p;
  const std::size_t left = static_cast<std::size_t>(c.e - c.p);
  const auto is = [&](const std::string& h) {
    return left >= h.size() && std::memcmp(c.p, h.data(), h.size()) == 0;
  };
  if (is(kImu)) {
    constexpr std::size_t N = mrpt::obs::COUNT_IMU_DATA_FIELDS;
    c.expect(kImu);
    c.expect(kPose3D);  // sensorPose: x, y, z, 3x3 rotation
    c.skip(12 * sizeof(double));
    c.endFlag();
    bool present[N];
    for (std::size_t i = 0; i < N; ++i) {
      const auto b = c.get<uint8_t>();
      if (b > 1) c.ok = false;
      present[i] = b == 1;
    }
    const double t = c.time();
    double raw[N];
    for (std::size_t i = 0; i < N; ++i) raw[i] = c.get<double>();
    c.label("IMU");
    c.endFlag();
    if (!c.ok || !present[IMU_WZ]) return 0;
    ImuSample x{t, raw[IMU_WZ], present[IMU_WX], {}};
    if (x.has_extra)
      for (int i = 0; i < 5; ++i) x.extra[i] = present[kImuExtra[i]] ? raw[kImuExtra[i]] : 0.0;
    s = x;
  } else if (is(kDaq)) {
    c.expect(kDaq);
    const std::string_view label = c.label();
    const double t = c.time();
    c.skip(sizeof(double));  // sample_rate
    c.emptyVectors(4);       // AIN_8bits, AIN_16bits, AIN_32bits, AIN_float
    const auto n = c.get<uint32_t>();
    double a[4] = {};
    if (n != 4 && n != 2) return 0;
    for (uint32_t i = 0; i < n; ++i) a[i] = c.get<double>();
    c.skip(sizeof(uint16_t) + sizeof(uint8_t));  // AIN_channel_count, AIN_interleaved
    c.emptyVectors(8);  // AOUT_8bits, AOUT_16bits, AOUT_float, AOUT_double, DIN, DOUT, CNTRIN_*
    c.endFlag();
    if (!c.ok) return 0;
    if (label == "MOTORS" && n == 4)
      s = MotorSample{t, a[0], a[1], a[2], a[3]};
    else if (label == "JOYSTICK" && n == 2)
      s = JoystickSample{t, a[0], a[1]};
    else
      return 0;
  } else if (is(kOdometry)) {
    c.expect(kOdometry);
    c.expect(kPose2D);  // odometry: x, y, phi
    c.skip(3 * sizeof(double));
    c.endFlag();
    c.label("ENCODERS");
    const double t = c.time();
    if (c.get<uint8_t>() != 1) return 0;  // hasEncodersInfo
    const auto left = c.get<int32_t>();
    const auto right = c.get<int32_t>();
    if (c.get<uint8_t>() != 0) return 0;  // hasVelocities
    c.endFlag();
    if (!c.ok) return 0;
    s = EncoderSample{t, right, left};
  } else {
    return 0;
  }
  return static_cast<std::size_t>(c.p - start);
}

}  // namespace

RawlogReader::RawlogReader(const std::string& path) : path_(path), in_(std::make_unique<GzipIn>()) {
  std::error_code ec;
  const auto st = fs::status(path, ec);
  if (!fs::exists(st)) throw std::runtime_error(fmt::format("{}: no such file", path));
  if (fs::is_directory(st))
    throw std::runtime_error(fmt::format("{}: is a directory, not a rawlog", path));
  if (fs::is_regular_file(st) && fs::file_size(path, ec) == 0)
    throw std::runtime_error(fmt::format("{}: empty file (0 bytes), not a rawlog", path));
  if (fs::is_regular_file(st)) file_bytes_ = static_cast<double>(fs::file_size(path, ec));
  if (!in_->open(path))
    throw std::runtime_error(fmt::format("{}: cannot open: {}", path, std::strerror(errno)));
}

RawlogReader::~RawlogReader() = default;

double RawlogReader::fractionRead() const {
  if (!(file_bytes_ > 0)) return 0;
  return std::min(1.0, static_cast<double>(in_->fileBytesUsed()) / file_bytes_);
}

void RawlogReader::setBreak(uint64_t pos, std::string what) {
  // Damage in the gzip layer shows in MRPT only as an early end or garbage: name it.
  if (!in_->error.empty()) what = in_->error;
  if (index_ == 0)
    what = startsWithCommentRecord(path_) ? "header record (META) damaged: " + what
                                          : "not a rawlog, or its first record is damaged: " + what;
  error_ = RawlogBreak{index_, pos, std::move(what)};
}

bool RawlogReader::next(mrpt::serialization::CSerializable::Ptr& obj) {
  if (error_) return false;
  const uint64_t pos = in_->pos;
  try {
    auto ar = mrpt::serialization::archiveFrom(*in_);
    obj = ar.ReadObject();
  } catch (const mrpt::serialization::CExceptionEOF&) {
    // A clean end of file only if nothing of a record was read, and only after at least one
    // record: a non-empty file that yields nothing (e.g. a damaged gzip stream, which zlib
    // ends early) is not a rawlog we can read.
    if (in_->pos == pos && index_ > 0 && in_->error.empty()) return false;
    setBreak(pos,
             in_->pos == pos ? "no readable record" : "truncated record (unexpected end of file)");
    return false;
  } catch (const std::bad_alloc&) {
    setBreak(pos, "corrupt record (a length field asks for more memory than available)");
    return false;
  } catch (const std::exception& e) {
    setBreak(pos, "corrupt record: " + util::oneLineMessage(e.what()));
    return false;
  }
  if (!obj) {
    setBreak(pos, "corrupt record (null object)");
    return false;
  }
  if (index_ == 0) {
    if (auto why = headerDamage(*obj)) {
      error_ = RawlogBreak{0, pos, "header record (META) damaged: " + *why};
      return false;
    }
  }
  ++index_;
  return true;
}

RawlogReader::Got RawlogReader::nextSample(AnySample& s,
                                           mrpt::serialization::CSerializable::Ptr& obj) {
  // Record 0 is the header (checked by next()); the largest record decoded in place is
  // ~450 bytes.
  constexpr std::size_t kWindow = 1024;
  if (!error_ && index_ > 0) {
    const std::size_t avail = in_->fill(kWindow);
    const unsigned char* p = in_->buf.data() + in_->beg;
    if (const std::size_t n = decodeInPlace(FastCursor{p, p + avail}, s)) {
      in_->consume(n);
      ++index_;
      return Got::Sample;
    }
  }
  return next(obj) ? Got::Object : Got::End;
}

std::optional<std::string> headerText(const mrpt::serialization::CSerializable& obj) {
  const auto* c = dynamic_cast<const CObservationComment*>(&obj);
  if (!c || c->text.rfind(kHeaderFirstLine, 0) != 0) return std::nullopt;
  return c->text;
}

std::map<std::string, std::string> headerMeta(const std::string& text) {
  std::map<std::string, std::string> meta;
  std::istringstream ss(text);
  std::string line, section;
  while (std::getline(ss, line)) {
    if (line.empty() || line[0] == '#') continue;
    if (line.front() == '[') {
      section = line.substr(1, line.find(']') - 1);
      continue;
    }
    const auto eq = line.find(" = ");
    if (section == "recording" && eq != std::string::npos)
      meta[line.substr(0, eq)] = line.substr(eq + 3);
  }
  return meta;
}

std::string headerConfigText(const std::string& text) {
  const std::string mark = kHeaderConfigMark;
  const auto at = text.find(mark);
  return at == std::string::npos ? std::string() : text.substr(at + mark.size());
}

std::string describeBreak(const std::string& path, const RawlogBreak& b) {
  return fmt::format("{}: record {} (uncompressed byte {}): {}", path, b.record_index,
                     b.byte_offset, b.what);
}

void writeRawlog(const Recording& rec, const std::string& path,
                 const config::WheelchairConfig& cfg) {
  RawlogWriter w(path);
  w.writeHeader(rec.meta, cfg, rec.startTime());
  forEachInTimeOrder(rec, [&](const AnySample& s) { w.write(s, cfg); });
  w.commit();
}

namespace {
bool isEmptyRegularFile(const std::string& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec) && fs::file_size(path, ec) == 0 && !ec;
}

/// Every complete record of `in` (our samples into the recording, the header's meta) and
/// where it broke, if it did.
Recording readRecords(RawlogReader& in, RawlogReadReport& rep) {
  Recording rec;
  mrpt::serialization::CSerializable::Ptr obj;
  AnySample sample;
  for (;;) {
    const auto got = in.nextSample(sample, obj);
    if (got == RawlogReader::Got::End) break;
    ++rep.records;
    if (got == RawlogReader::Got::Sample) {
      append(rec, sample);
      continue;
    }
    auto o = std::dynamic_pointer_cast<CObservation>(obj);
    if (!o) {
      ++rep.ignored;
      continue;
    }
    if (auto text = headerText(*o)) {
      rep.header_text = *text;
      rec.meta = headerMeta(*text);
      continue;
    }
    if (auto s = fromObservation(*o))
      append(rec, *s);
    else
      ++rep.ignored;
  }
  rep.broken = in.error();
  return rec;
}

}  // namespace

Recording readRawlog(const std::string& path, RawlogReadReport* report, bool allow_truncated) {
  // A capture cut before its first flush leaves a 0-byte file: with allow_truncated that is
  // an empty prefix; otherwise (and always for the commands) it is refused.
  if (allow_truncated && isEmptyRegularFile(path)) {
    if (report) *report = RawlogReadReport{};
    return Recording{};
  }
  RawlogReader in(path);
  RawlogReadReport rep;
  Recording rec = readRecords(in, rep);
  if (rep.broken && !allow_truncated) throw std::runtime_error(describeBreak(path, *rep.broken));
  if (report) *report = rep;
  return rec;
}

std::string salvageOrThrow(const std::string& path, const RawlogBreak& b, std::size_t data_records,
                           bool salvage) {
  if (!salvage && data_records > 0)
    throw std::runtime_error(describeBreak(path, b) +
                             " (--salvage uses the complete records before it)");
  if (data_records == 0)
    throw std::runtime_error(describeBreak(path, b) +
                             " (no complete data record before it to salvage)");
  return fmt::format("{}; salvaged the {} complete records before it", describeBreak(path, b),
                     b.record_index);
}

Recording readRawlogSalvaging(const std::string& path, bool salvage, std::string* warning,
                              RawlogReadReport* report) {
  RawlogReader in(path);  // refuses a 0-byte file
  RawlogReadReport rep;
  Recording rec = readRecords(in, rep);
  if (rep.broken) {
    const std::string w = salvageOrThrow(path, *rep.broken, rec.size(), salvage);
    if (warning) *warning = w;
  }
  if (report) *report = rep;
  return rec;
}

}  // namespace wheelchair::io
