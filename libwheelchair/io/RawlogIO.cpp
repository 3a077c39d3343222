#include "libwheelchair/io/RawlogIO.h"

#include <fmt/format.h>
#include <mrpt/core/Clock.h>
#include <mrpt/obs/CObservationBearingRange.h>
#include <mrpt/obs/CObservationComment.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CObservationRange.h>
#include <mrpt/obs/CObservationRawDAQ.h>
#include <mrpt/obs/CObservationRobotPose.h>
#include <mrpt/serialization/CArchive.h>

#include <cmath>
#include <filesystem>
#include <sstream>

namespace fs = std::filesystem;
using namespace mrpt::obs;

namespace wheelchair::io {

namespace {

// MRPT stores sonar ranges and landmark sightings as float: read them back as the decimal
// value the float prints as (shortest representation), which is what was recorded.
double floatAsDecimal(float x) { return std::strtod(fmt::format("{}", x).c_str(), nullptr); }

constexpr double kUnknownZVariance_m2 = 1e6;
constexpr const char* kHeaderFirstLine = "# libwheelchair recording";
const mrpt::obs::TIMUDataIndex kImuExtra[5] = {IMU_WX, IMU_WY, IMU_X_ACC, IMU_Y_ACC, IMU_Z_ACC};

template <class T>
typename T::Ptr stamped(StreamKind k, double t_s) {
  auto o = T::Create();
  o->timestamp = mrpt::Clock::fromDouble(t_s);
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
          o->sensorConeApperture = static_cast<float>(2 * cfg.sonar.cone_half_angle_deg * M_PI / 180);
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
          o->sensorPose = mrpt::poses::CPose3D(cfg.pozyx.lever_x_m, cfg.pozyx.lever_y_m, 0, 0, 0, 0);
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
  if (auto o = dynamic_cast<const CObservationOdometry*>(&obs); o && o->hasEncodersInfo &&
                                                                 label == "ENCODERS") {
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
  if (auto o = dynamic_cast<const CObservationRange*>(&obs); o && label == "SONAR" &&
                                                              !o->sensedData.empty()) {
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
  if (auto o = dynamic_cast<const CObservationBearingRange*>(&obs); o && label == "LANDMARKS" &&
                                                                     !o->sensedData.empty()) {
    const auto& m = o->sensedData.front();
    return LandmarkSample{t, m.landmarkID, floatAsDecimal(m.range), floatAsDecimal(m.yaw)};
  }
  return std::nullopt;
}

// ---------------------------------------------------------------- RawlogWriter

RawlogWriter::RawlogWriter(const std::string& path, int compression_level)
    : path_(path), tmp_(path + ".tmp") {
  out_ = std::make_unique<mrpt::io::CFileGZOutputStream>();
  std::string err;
  if (!out_->open(tmp_, compression_level, err))
    throw std::runtime_error(fmt::format("{}: cannot open for writing: {}", tmp_, err));
}

RawlogWriter::~RawlogWriter() {
  if (!committed_) {
    out_.reset();
    std::error_code ec;
    fs::remove(tmp_, ec);
  }
}

void RawlogWriter::write(const mrpt::serialization::CSerializable& obj) {
  auto ar = mrpt::serialization::archiveFrom(*out_);
  ar << obj;
  ++count_;
}

void RawlogWriter::write(const AnySample& s, const config::WheelchairConfig& cfg) {
  write(*toObservation(s, cfg));
}

void RawlogWriter::writeHeader(const std::map<std::string, std::string>& meta,
                               const config::WheelchairConfig& cfg, double t_s) {
  auto c = CObservationComment::Create();
  c->timestamp = mrpt::Clock::fromDouble(t_s);
  c->sensorLabel = "META";
  std::ostringstream ss;
  ss << kHeaderFirstLine << "\n[recording]\n";
  for (const auto& [k, v] : meta) ss << k << " = " << v << "\n";
  ss << "# configuration used when writing this file\n" << cfg.text();
  c->text = ss.str();
  write(*c);
}

void RawlogWriter::commit() {
  out_->close();
  std::error_code ec;
  fs::rename(tmp_, path_, ec);
  if (ec) throw std::runtime_error(fmt::format("{}: cannot rename into place: {}", path_, ec.message()));
  committed_ = true;
}

// ---------------------------------------------------------------- RawlogReader

RawlogReader::RawlogReader(const std::string& path) : path_(path) {
  if (!fs::exists(path)) throw std::runtime_error(fmt::format("{}: no such file", path));
  file_size_ = fs::file_size(path);
  if (!in_.open(path)) throw std::runtime_error(fmt::format("{}: cannot open", path));
}

bool RawlogReader::next(mrpt::serialization::CSerializable::Ptr& obj) {
  if (error_) return false;
  const uint64_t pos = in_.getPosition();
  try {
    auto ar = mrpt::serialization::archiveFrom(in_);
    obj = ar.ReadObject();
  } catch (const mrpt::serialization::CExceptionEOF&) {
    // A clean end of file only if nothing of a record was read, and only after at least one
    // record: a non-empty file that yields nothing (e.g. a damaged gzip stream, which zlib
    // ends early) is not a rawlog we can read.
    if (in_.getPosition() == pos && (index_ > 0 || file_size_ == 0)) return false;
    if (in_.getPosition() == pos) {
      error_ = RawlogBreak{index_, pos, "no readable record (not a rawlog, or damaged from the start)"};
      return false;
    }
    error_ = RawlogBreak{index_, pos, "truncated record (unexpected end of file)"};
    return false;
  } catch (const std::exception& e) {
    std::string what = e.what();
    if (const auto nl = what.find('\n'); nl != std::string::npos) what = what.substr(0, nl);
    error_ = RawlogBreak{index_, pos, "corrupt record: " + what};
    return false;
  }
  if (!obj) {
    error_ = RawlogBreak{index_, pos, "corrupt record (null object)"};
    return false;
  }
  ++index_;
  return true;
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
  const std::string mark = "# configuration used when writing this file\n";
  const auto at = text.find(mark);
  return at == std::string::npos ? std::string() : text.substr(at + mark.size());
}

std::string describeBreak(const std::string& path, const RawlogBreak& b) {
  return fmt::format("{}: record {} (uncompressed byte {}): {}", path, b.record_index,
                     b.byte_offset, b.what);
}

void writeRawlog(const Recording& rec, const std::string& path, const config::WheelchairConfig& cfg) {
  RawlogWriter w(path);
  w.writeHeader(rec.meta, cfg, rec.startTime());
  forEachInTimeOrder(rec, [&](const AnySample& s) { w.write(s, cfg); });
  w.commit();
}

Recording readRawlog(const std::string& path, RawlogReadReport* report, bool allow_truncated) {
  RawlogReader in(path);
  Recording rec;
  RawlogReadReport rep;
  mrpt::serialization::CSerializable::Ptr obj;
  while (in.next(obj)) {
    ++rep.records;
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
    if (auto s = fromObservation(*o)) append(rec, *s);
    else ++rep.ignored;
  }
  rep.broken = in.error();
  if (rep.broken && !allow_truncated) throw std::runtime_error(describeBreak(path, *rep.broken));
  if (report) *report = rep;
  return rec;
}

}  // namespace wheelchair::io
