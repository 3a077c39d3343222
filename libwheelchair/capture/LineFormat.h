// The one configurable text-line parser shared by every serial source of `wheelchair capture`
// (docs/capture.md, "Line formats"), and its inverse used by the replay (`replay-serial`).
//
// A source's line format is a template with one `{field}` per value, literal text between
// them and an optional trailing group in brackets that is present or absent as a whole:
//
//   line_format = {t},{gyro_z}[,{gyro_x},{gyro_y},{acc_x},{acc_y},{acc_z}]
//   line_format = $POS,{_},{x}, {y}            ({_} = a column that is ignored)
//
// A space in the template matches any run of blanks (also none); every other literal must
// match exactly. The field names are the recording-format columns of the stream
// (docs/recording-format.md) plus `t`, the device's own timestamp. Each value is converted by
// a linear calibration, physical = <field>_offset + <field>_gain * raw (defaults 0 and 1),
// e.g. raw ADC counts into amperes. For formats a template cannot express, `line_regex`
// (ECMAScript) with `line_fields` (the names of the capture groups, in order) is accepted.
//
// Example:
//   auto f = LineFormat::fromConfig(ini, "imu", io::StreamKind::Imu);
//   ParsedLine p;
//   if (f.parse("12.5,0.01", p)) { ... p.sample, p.device_time_s ... }
#pragma once

#include "libwheelchair/io/Samples.h"

#include <mrpt/config/CConfigFileBase.h>

#include <array>
#include <map>
#include <memory>
#include <optional>
#include <regex>
#include <string>
#include <string_view>
#include <vector>

namespace wheelchair::capture {

/// The outcome of parsing one line.
struct ParsedLine {
  io::AnySample sample;                 ///< physical values; t_s = device time if present, else 0
  std::optional<double> device_time_s;  ///< the `{t}` field (after t_gain/t_offset), if any
};

/// Linear calibration of one field: physical = offset + gain * raw.
struct Calibration {
  double gain = 1.0;
  double offset = 0.0;
  double toPhysical(double raw) const { return offset + gain * raw; }
};

class LineFormat {
 public:
  /// The default template of a stream (the recording-format CSV row; see docs/capture.md).
  static std::string defaultTemplate(io::StreamKind kind);
  /// Field names a stream accepts (besides `t` and `_`).
  static std::vector<std::string> fieldNames(io::StreamKind kind);

  /// From a template and per-field calibrations (missing ones are identity).
  LineFormat(io::StreamKind kind, const std::string& tmpl,
             const std::map<std::string, Calibration>& calib = {});
  /// From an INI section: line_format (or line_regex + line_fields), <field>_gain,
  /// <field>_offset, max_line_length. Throws std::invalid_argument naming the key.
  static LineFormat fromConfig(const mrpt::config::CConfigFileBase& ini, const std::string& section,
                               io::StreamKind kind);

  /// Parses a line (without its end of line; a trailing '\r' is accepted). False for
  /// anything that is not exactly one record of this format: wrong literal, missing or extra
  /// field, a value that is not a finite number, a tick count that is not an integer in
  /// [-2^31, 2^32), a negative sonar range, a partial optional group.
  bool parse(std::string_view line, ParsedLine& out) const;

  /// The line a device would send for `s` (no end of line), inverting the calibrations.
  /// Each raw value is the shortest decimal whose conversion gives back exactly the sample's
  /// double when one exists within a few ulps (`inexact` counts the values for which none
  /// does). Throws std::logic_error for regex formats (set `line_format` for replay).
  std::string format(const io::AnySample& s, std::size_t* inexact = nullptr) const;

  bool hasDeviceTime() const { return has_t_; }
  bool canFormat() const { return !regex_; }
  io::StreamKind kind() const { return kind_; }
  const std::string& describe() const { return description_; }
  std::size_t maxLineLength() const { return max_line_length_; }
  const Calibration& calibration(const std::string& field) const;

 private:
  struct Piece {
    bool is_field = false;
    std::string literal;  ///< for literals
    int field = -1;       ///< index into names_ (-1 = ignored column `{_}`)
    bool optional = false;
  };
  LineFormat() = default;
  void compile(const std::string& tmpl);
  void finish();
  bool assemble(const std::array<std::optional<double>, 8>& v, ParsedLine& out) const;
  static bool matchLiteral(std::string_view line, std::size_t& pos, const std::string& lit);

  io::StreamKind kind_ = io::StreamKind::Encoders;
  std::vector<std::string> names_;  ///< index 0 = "t", then fieldNames(kind)
  std::vector<Calibration> calib_;  ///< per names_ index
  std::vector<Piece> pieces_;
  std::shared_ptr<std::regex> regex_;
  std::vector<int> regex_fields_;
  bool has_t_ = false;
  std::size_t max_line_length_ = 512;
  std::string description_;
};

/// Parses a number the way the line parser does (whole token, finite). For tests and tools.
std::optional<double> parseFiniteNumber(std::string_view token);

}  // namespace wheelchair::capture
