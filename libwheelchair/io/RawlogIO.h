// Rawlogs: MRPT's native binary log (a gzip-compressed stream of serialized observations,
// "observations-only" format), readable by RawLogViewer and rawlog-edit.
//
// Every stream is stored in a standard MRPT class with a sensorLabel (docs/rawlog-mapping.md):
//   ENCODERS      CObservationOdometry  hasEncodersInfo, absolute ticks (right/left)
//   IMU           CObservationIMU       IMU_WZ (+ IMU_WX, IMU_WY, IMU_{X,Y,Z}_ACC if recorded)
//   MOTORS        CObservationRawDAQ    AIN_double = {current_right_A, current_left_A,
//                                                     vrc_right_V, vrc_left_V}
//   SONAR         CObservationRange     one measurement; sensor pose, cone and limits from
//                                       the configuration; a 0 reading kept as recorded
//   POZYX         CObservationRobotPose position in the anchor frame, covariance from the
//                                       configuration (z variance 1e6 m^2 when z not recorded)
//   JOYSTICK      CObservationRawDAQ    AIN_double = {v_cmd_m_s, omega_cmd_rad_s}
//   GROUND_TRUTH  CObservationRobotPose motion-capture pose (x, y, yaw)
//   LANDMARKS     CObservationBearingRange  one sighting: landmarkID, range, yaw
// The first record is a CObservationComment (label META) holding the recording's meta.ini
// keys and the configuration the file was written with.
//
// Writing goes through util::AtomicFile (a hidden temporary beside PATH, renamed on commit()):
// the gzip stream is produced with zlib by this class and every write, the gzip trailer, the
// fsync and the close are checked, so a full disk (even one that only shows at the final
// flush) throws one line "PATH: cannot write: No space left on device" and leaves neither PATH
// nor a temporary. The result is a standard gzip MRPT .rawlog (RawLogViewer, rawlog-edit).
// Reading is streamed record by record; a truncated or corrupt file yields every complete
// record, then reports the record index and byte offset where it broke (record 0, the META
// header, is reported as header damage). A 0-byte file is not a rawlog and is refused.
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/io/Samples.h"

#include <mrpt/obs/CObservation.h>

#include <memory>
#include <optional>
#include <string>

namespace wheelchair::io {

/// Builds the MRPT observation for a sample (sensor geometry from `cfg`).
mrpt::obs::CObservation::Ptr toObservation(const AnySample& s, const config::WheelchairConfig& cfg);
/// The sample an observation holds; nullopt for observations that are not ours (unknown
/// label/class combination, or the META comment).
std::optional<AnySample> fromObservation(const mrpt::obs::CObservation& obs);

class RawlogWriter {
 public:
  /// compression_level: 0 none .. 9 best (1 = fast, MRPT's default for grabbers).
  explicit RawlogWriter(const std::string& path, int compression_level = 1);
  ~RawlogWriter();  // removes the temporary file unless committed
  void write(const mrpt::serialization::CSerializable& obj);
  void write(const AnySample& s, const config::WheelchairConfig& cfg);
  void writeHeader(const std::map<std::string, std::string>& meta,
                   const config::WheelchairConfig& cfg, double t_s);
  std::size_t count() const { return count_; }
  void commit();

 private:
  struct GzipOut;
  std::string path_;
  std::unique_ptr<GzipOut> out_;
  std::size_t count_ = 0;
  bool committed_ = false;
};

/// Where a rawlog stopped being readable.
struct RawlogBreak {
  std::size_t record_index = 0;  ///< 0-based index of the first unreadable record
  uint64_t byte_offset = 0;      ///< uncompressed offset where it started
  std::string what;
};

class RawlogReader {
 public:
  /// Throws (one line) for a missing, 0-byte or unopenable file.
  explicit RawlogReader(const std::string& path);
  ~RawlogReader();
  /// Next record; false at a clean end of file or at the first broken record (see error()).
  bool next(mrpt::serialization::CSerializable::Ptr& obj);
  /// What nextSample() returned.
  enum class Got { Sample, Object, End };
  /// next() without building the MRPT object for the bulk of a recording: a record in one of
  /// the exact layouts this library writes for ENCODERS (CObservationOdometry v2, ticks, no
  /// velocities), IMU (CObservationIMU v4) and MOTORS / JOYSTICK (CObservationRawDAQ v0, only
  /// AIN_double) is decoded straight from the decompressed bytes into `s` (Got::Sample: the
  /// same sample fromObservation gives for the object). Any other record -- the header,
  /// sonar, Pozyx, foreign or damaged records, a record that does not match the layout byte
  /// for byte -- goes through next(obj) (Got::Object; decode it with fromObservation), so
  /// errors and their messages are next()'s. Got::End: clean end or break (error()).
  Got nextSample(AnySample& s, mrpt::serialization::CSerializable::Ptr& obj);
  const std::optional<RawlogBreak>& error() const { return error_; }
  std::size_t recordsRead() const { return index_; }
  const std::string& path() const { return path_; }
  /// Share of the (compressed) file read so far, 0..1 (progress displays).
  double fractionRead() const;

 private:
  void setBreak(uint64_t pos, std::string what);

  struct GzipIn;
  std::string path_;
  std::unique_ptr<GzipIn> in_;
  double file_bytes_ = 0;
  std::size_t index_ = 0;
  std::optional<RawlogBreak> error_;
};

/// Writes a whole recording (time-ordered merge of its streams) with a META header.
void writeRawlog(const Recording& rec, const std::string& path,
                 const config::WheelchairConfig& cfg);

struct RawlogReadReport {
  std::size_t records = 0;
  std::size_t ignored = 0;            ///< records that are not ours (other labels/classes)
  std::optional<RawlogBreak> broken;  ///< set when the file is truncated/corrupt
  std::string header_text;            ///< META comment text (meta keys + configuration)
};

/// Reads a whole rawlog into memory. Throws on a broken or 0-byte file unless
/// `allow_truncated`, in which case every complete record is returned and the break is in the
/// report (a 0-byte file, a capture cut before its first flush, is then an empty recording).
Recording readRawlog(const std::string& path, RawlogReadReport* report = nullptr,
                     bool allow_truncated = false);

/// readRawlog for the commands' `--salvage` option. Without `salvage`, a damaged file throws
/// one line naming the record index, byte offset and reason. With it, every complete record
/// before the break is used and `*warning` (if given) says where and why the file broke, e.g.
/// "d.rawlog: record 9155 (uncompressed byte 2221453): file cut short ...; salvaged the 9155
/// complete records before it". A file with no data record before the break is refused
/// either way. A 0-byte file is always refused.
Recording readRawlogSalvaging(const std::string& path, bool salvage, std::string* warning,
                              RawlogReadReport* report = nullptr);
/// The salvage rule for a file that broke at `b` after `data_records` complete data records
/// (for readers that stream, like `export`): throws the one-line refusal, or with `salvage`
/// returns the warning readRawlogSalvaging gives.
std::string salvageOrThrow(const std::string& path, const RawlogBreak& b, std::size_t data_records,
                           bool salvage);

/// If `obj` is our header record (a CObservationComment written by writeHeader; MRPT does
/// not serialize a comment's sensorLabel, so it is recognised by its first line), returns its
/// text.
std::optional<std::string> headerText(const mrpt::serialization::CSerializable& obj);
/// The `[recording]` keys (meta.ini) stored in a header text.
std::map<std::string, std::string> headerMeta(const std::string& header_text);

/// The configuration part of a header text (what writeHeader stored after the meta keys),
/// empty when the header holds none.
std::string headerConfigText(const std::string& header_text);

/// Human-readable "file: record N at byte B: what" for a break.
std::string describeBreak(const std::string& path, const RawlogBreak& b);

}  // namespace wheelchair::io
