#include "libwheelchair/capture/LineFormat.h"

#include "libwheelchair/util/Text.h"

#include "libwheelchair/io/TextFormat.h"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>

namespace wheelchair::capture {

using io::StreamKind;

namespace {

bool isNumberChar(char c) {
  return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '.' ||
         c == '+' || c == '-';
}

bool isBlank(char c) {
  return c == ' ' || c == '\t';
}

using util::trim;

// Fields holding integer tick counts (no calibration, integer syntax).
bool isTickField(StreamKind k, int idx) {
  return k == StreamKind::Encoders && idx >= 1;
}

std::optional<int64_t> parseInteger(std::string_view tok) {
  if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
  int64_t v = 0;
  const auto [p, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), v);
  if (ec != std::errc() || p != tok.data() + tok.size() || tok.empty()) return std::nullopt;
  return v;
}

}  // namespace

std::optional<double> parseFiniteNumber(std::string_view tok) {
  if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
  if (tok.empty()) return std::nullopt;
  double v = 0;
  const auto [p, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), v);
  if (ec != std::errc() || p != tok.data() + tok.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

std::vector<std::string> LineFormat::fieldNames(StreamKind kind) {
  switch (kind) {
    case StreamKind::Encoders:
      return {"right_ticks", "left_ticks"};
    case StreamKind::Imu:
      return {"gyro_z", "gyro_x", "gyro_y", "acc_x", "acc_y", "acc_z"};
    case StreamKind::Motors:
      return {"current_right", "current_left", "vrc_right", "vrc_left"};
    case StreamKind::Sonar:
      return {"range"};
    case StreamKind::Pozyx:
      return {"x", "y", "z"};
    case StreamKind::Joystick:
      return {"v_cmd", "w_cmd"};
    default:
      throw std::invalid_argument(
          fmt::format("stream {} has no capture source", io::streamLabel(kind)));
  }
}

std::string LineFormat::defaultTemplate(StreamKind kind) {
  switch (kind) {
    case StreamKind::Encoders:
      return "{t},{right_ticks},{left_ticks}";
    case StreamKind::Imu:
      return "{t},{gyro_z}[,{gyro_x},{gyro_y},{acc_x},{acc_y},{acc_z}]";
    case StreamKind::Motors:
      return "{t},{current_right},{current_left},{vrc_right},{vrc_left}";
    case StreamKind::Sonar:
      return "{t},{range}";
    case StreamKind::Pozyx:
      return "{t},{x},{y}[,{z}]";
    case StreamKind::Joystick:
      return "{t},{v_cmd},{w_cmd}";
    default:
      fieldNames(kind);  // throws
  }
  return {};
}

LineFormat::LineFormat(StreamKind kind, const std::string& tmpl,
                       const std::map<std::string, Calibration>& calib)
    : kind_(kind) {
  names_ = {"t"};
  for (auto& n : fieldNames(kind)) names_.push_back(n);
  calib_.assign(names_.size(), Calibration{});
  for (const auto& [name, c] : calib) {
    const auto it = std::find(names_.begin(), names_.end(), name);
    if (it == names_.end())
      throw std::invalid_argument(fmt::format("calibration of unknown field '{}'", name));
    calib_[it - names_.begin()] = c;
  }
  compile(tmpl);
  finish();
}

const Calibration& LineFormat::calibration(const std::string& field) const {
  const auto it = std::find(names_.begin(), names_.end(), field);
  if (it == names_.end()) throw std::invalid_argument("unknown field " + field);
  return calib_[it - names_.begin()];
}

void LineFormat::compile(const std::string& tmpl) {
  description_ = tmpl;
  bool in_optional = false, seen_optional = false;
  std::vector<bool> used(names_.size(), false);
  std::string lit;
  auto flush_literal = [&] {
    if (!lit.empty()) pieces_.push_back(Piece{false, lit, -1, in_optional});
    lit.clear();
  };
  for (std::size_t i = 0; i < tmpl.size(); ++i) {
    const char c = tmpl[i];
    if (c == '[') {
      if (in_optional || seen_optional)
        throw std::invalid_argument("line_format: only one optional [...] group is allowed");
      flush_literal();
      in_optional = seen_optional = true;
    } else if (c == ']') {
      if (!in_optional) throw std::invalid_argument("line_format: ']' without '['");
      flush_literal();
      in_optional = false;
      if (i + 1 != tmpl.size())
        throw std::invalid_argument("line_format: the optional [...] group must end the line");
    } else if (c == '{') {
      const auto close = tmpl.find('}', i);
      if (close == std::string::npos) throw std::invalid_argument("line_format: '{' without '}'");
      const std::string name = tmpl.substr(i + 1, close - i - 1);
      flush_literal();
      int idx = -1;
      if (name != "_") {
        const auto it = std::find(names_.begin(), names_.end(), name);
        if (it == names_.end())
          throw std::invalid_argument(
              fmt::format("line_format: unknown field '{{{}}}' for {} (fields: t, {}, _)", name,
                          io::streamLabel(kind_), fmt::join(fieldNames(kind_), ", ")));
        idx = static_cast<int>(it - names_.begin());
        if (used[idx])
          throw std::invalid_argument(fmt::format("line_format: field '{{{}}}' twice", name));
        used[idx] = true;
      }
      if (!pieces_.empty() && pieces_.back().is_field)
        throw std::invalid_argument("line_format: two fields need a separator between them");
      pieces_.push_back(Piece{true, {}, idx, in_optional});
      i = close;
    } else {
      lit.push_back(c);
    }
  }
  if (in_optional) throw std::invalid_argument("line_format: '[' without ']'");
  flush_literal();
  // A literal after a field must not start with a character a number can contain.
  for (std::size_t i = 1; i < pieces_.size(); ++i) {
    if (pieces_[i - 1].is_field && !pieces_[i].is_field) {
      const char c0 = pieces_[i].literal[0];
      if (!isBlank(c0) && isNumberChar(c0))
        throw std::invalid_argument(
            fmt::format("line_format: separator '{}' after a field is ambiguous (use line_regex)",
                        pieces_[i].literal));
    }
  }
  // Which fields are present, and where.
  std::vector<int> opt_of(names_.size(), -1);
  for (const auto& p : pieces_)
    if (p.is_field && p.field >= 0) opt_of[p.field] = p.optional ? 1 : 0;
  has_t_ = opt_of[0] == 0;
  if (opt_of[0] == 1) throw std::invalid_argument("line_format: {t} cannot be optional");
  // Required fields: everything but the IMU extras and the Pozyx z.
  for (std::size_t f = 1; f < names_.size(); ++f) {
    const bool optional_field =
        (kind_ == StreamKind::Imu && f >= 2) || (kind_ == StreamKind::Pozyx && names_[f] == "z");
    if (!optional_field && opt_of[f] != 0)
      throw std::invalid_argument(fmt::format(
          "line_format: required field {{{}}} missing (or in the optional group)", names_[f]));
  }
  if (kind_ == StreamKind::Imu) {
    // gyro_x..acc_z together: all or none, all in the same place.
    for (std::size_t f = 3; f < names_.size(); ++f)
      if (opt_of[f] != opt_of[2])
        throw std::invalid_argument(
            "line_format: the IMU extras gyro_x, gyro_y, acc_x, acc_y, acc_z go together");
  }
}

void LineFormat::finish() {
  for (std::size_t f = 0; f < names_.size(); ++f)
    if (isTickField(kind_, static_cast<int>(f)) &&
        (calib_[f].gain != 1.0 || calib_[f].offset != 0.0))
      throw std::invalid_argument(
          fmt::format("{}: tick counts are recorded as counted (no gain/offset)", names_[f]));
}

LineFormat LineFormat::fromConfig(const mrpt::config::CConfigFileBase& ini,
                                  const std::string& section, StreamKind kind) {
  std::map<std::string, Calibration> calib;
  std::vector<std::string> names = {"t"};
  for (auto& n : fieldNames(kind)) names.push_back(n);
  auto read_num = [&](const std::string& key, double def) {
    const std::string raw = trim(ini.read_string(section, key, "", false));
    if (raw.empty()) return def;
    const auto v = parseFiniteNumber(raw);
    if (!v)
      throw std::invalid_argument(
          fmt::format("[{}] {} = '{}': not a number", section, key, util::quoteInput(raw)));
    return *v;
  };
  for (const auto& n : names) {
    Calibration c{read_num(n + "_gain", 1.0), read_num(n + "_offset", 0.0)};
    if (c.gain == 0) throw std::invalid_argument(fmt::format("[{}] {}_gain = 0", section, n));
    calib[n] = c;
  }
  const std::string regex = ini.read_string(section, "line_regex", "", false);
  LineFormat f;
  try {
    if (!regex.empty()) {
      f = LineFormat(kind, defaultTemplate(kind), calib);  // names and calibrations
      f.pieces_.clear();
      f.regex_ = std::make_shared<std::regex>(regex, std::regex::ECMAScript);
      const std::string fields = ini.read_string(section, "line_fields", "", false);
      if (fields.empty()) throw std::invalid_argument("line_regex needs line_fields");
      std::string tmpl;  // validate the field list through the template compiler
      std::stringstream ss(fields);
      std::string name;
      while (std::getline(ss, name, ',')) {
        name = trim(name);
        const auto it = std::find(names.begin(), names.end(), name);
        f.regex_fields_.push_back(name == "_" ? -1 : static_cast<int>(it - names.begin()));
        if (name != "_" && it == names.end())
          throw std::invalid_argument("line_fields: unknown field " + name);
        tmpl += (tmpl.empty() ? "{" : " {") + name + "}";
      }
      if (f.regex_fields_.size() != f.regex_->mark_count())
        throw std::invalid_argument(
            fmt::format("line_fields names {} fields, line_regex has {} groups",
                        f.regex_fields_.size(), f.regex_->mark_count()));
      LineFormat check(kind, tmpl, calib);  // required fields, duplicates
      f.has_t_ = check.has_t_;
      f.description_ = "regex " + regex + " -> " + fields;
    } else {
      f = LineFormat(kind, ini.read_string(section, "line_format", defaultTemplate(kind), false),
                     calib);
    }
  } catch (const std::regex_error& e) {
    throw std::invalid_argument(fmt::format("[{}] line_regex: {}", section, e.what()));
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(fmt::format("[{}] {}", section, e.what()));
  }
  f.max_line_length_ = static_cast<std::size_t>(ini.read_int(section, "max_line_length", 512));
  return f;
}

bool LineFormat::matchLiteral(std::string_view line, std::size_t& pos, const std::string& lit) {
  for (char c : lit) {
    if (isBlank(c)) {
      while (pos < line.size() && isBlank(line[pos])) ++pos;
    } else {
      if (pos >= line.size() || line[pos] != c) return false;
      ++pos;
    }
  }
  return true;
}

bool LineFormat::parse(std::string_view line, ParsedLine& out) const {
  while (!line.empty() && (line.back() == '\r' || line.back() == '\n' || isBlank(line.back())))
    line.remove_suffix(1);
  while (!line.empty() && isBlank(line.front())) line.remove_prefix(1);
  if (line.empty() || line.size() > max_line_length_) return false;
  std::array<std::optional<double>, 8> v;
  auto take = [&](int field, std::string_view tok) {
    if (field < 0) return !tok.empty();
    if (isTickField(kind_, field)) {
      const auto i = parseInteger(tok);
      if (!i || *i < std::numeric_limits<int32_t>::min() ||
          *i > static_cast<int64_t>(std::numeric_limits<uint32_t>::max()))
        return false;
      v[field] = static_cast<double>(*i);
      return true;
    }
    const auto x = parseFiniteNumber(tok);
    if (!x) return false;
    v[field] = calib_[field].toPhysical(*x);
    return std::isfinite(*v[field]);
  };
  if (regex_) {
    std::match_results<std::string_view::const_iterator> m;
    if (!std::regex_match(line.begin(), line.end(), m, *regex_)) return false;
    for (std::size_t g = 0; g < regex_fields_.size(); ++g) {
      if (!m[g + 1].matched) continue;
      if (!take(regex_fields_[g], std::string_view(&*m[g + 1].first, m[g + 1].length())))
        return false;
    }
    return assemble(v, out);
  }
  std::size_t pos = 0;
  for (std::size_t i = 0; i < pieces_.size(); ++i) {
    const Piece& p = pieces_[i];
    if (p.optional && (i == 0 || !pieces_[i - 1].optional) && pos == line.size()) break;
    if (p.is_field) {
      const std::size_t b = pos;
      while (pos < line.size() && isNumberChar(line[pos])) ++pos;
      if (!take(p.field, line.substr(b, pos - b))) return false;
    } else if (!matchLiteral(line, pos, p.literal)) {
      return false;
    }
  }
  if (pos != line.size()) return false;
  return assemble(v, out);
}

bool LineFormat::assemble(const std::array<std::optional<double>, 8>& v, ParsedLine& out) const {
  out.device_time_s.reset();
  if (v[0]) out.device_time_s = *v[0];
  const double t = v[0].value_or(0.0);
  auto req = [&](int i) -> std::optional<double> { return v[i]; };
  switch (kind_) {
    case StreamKind::Encoders: {
      if (!v[1] || !v[2]) return false;
      auto wrap = [](double x) {
        return static_cast<int32_t>(static_cast<uint32_t>(static_cast<int64_t>(x)));
      };
      out.sample = io::EncoderSample{t, wrap(*v[1]), wrap(*v[2])};
      return true;
    }
    case StreamKind::Imu: {
      if (!v[1]) return false;
      io::ImuSample s{t, *v[1], false, {}};
      int extras = 0;
      for (int i = 2; i <= 6; ++i) extras += v[i].has_value();
      if (extras != 0 && extras != 5) return false;
      if (extras == 5) {
        s.has_extra = true;
        for (int i = 0; i < 5; ++i) s.extra[i] = *v[2 + i];
      }
      out.sample = s;
      return true;
    }
    case StreamKind::Motors:
      for (int i = 1; i <= 4; ++i)
        if (!req(i)) return false;
      out.sample = io::MotorSample{t, *v[1], *v[2], *v[3], *v[4]};
      return true;
    case StreamKind::Sonar:
      if (!v[1] || *v[1] < 0) return false;
      out.sample = io::SonarSample{t, *v[1]};
      return true;
    case StreamKind::Pozyx:
      if (!v[1] || !v[2]) return false;
      out.sample = io::PozyxSample{t, *v[1], *v[2], v[3].has_value(), v[3].value_or(0.0)};
      return true;
    case StreamKind::Joystick:
      if (!v[1] || !v[2]) return false;
      out.sample = io::JoystickSample{t, *v[1], *v[2]};
      return true;
    default:
      return false;
  }
}

namespace {

// The raw value whose calibration gives back x exactly (preferring an integer), or the
// closest one found.
double invertCalibration(const Calibration& c, double x, bool& exact) {
  const double r0 = (x - c.offset) / c.gain;
  const double ri = std::round(r0);
  if (c.toPhysical(ri) == x) return ri;
  if (c.toPhysical(r0) == x) return r0;
  double lo = r0, hi = r0;
  for (int i = 0; i < 64; ++i) {
    lo = std::nextafter(lo, -std::numeric_limits<double>::infinity());
    if (c.toPhysical(lo) == x) return lo;
    hi = std::nextafter(hi, std::numeric_limits<double>::infinity());
    if (c.toPhysical(hi) == x) return hi;
  }
  exact = false;
  return r0;
}

}  // namespace

std::string LineFormat::format(const io::AnySample& s, std::size_t* inexact) const {
  if (regex_)
    throw std::logic_error("a line_regex format cannot be written: set line_format for replay");
  if (io::kindOf(s) != kind_)
    throw std::logic_error("LineFormat::format: sample of another stream");
  std::array<std::optional<double>, 8> v;
  v[0] = io::timeOf(s);
  std::visit(
      [&](const auto& x) {
        using T = std::decay_t<decltype(x)>;
        if constexpr (std::is_same_v<T, io::EncoderSample>) {
          v[1] = x.right_ticks;
          v[2] = x.left_ticks;
        } else if constexpr (std::is_same_v<T, io::ImuSample>) {
          v[1] = x.gyro_z_rad_s;
          if (x.has_extra)
            for (int i = 0; i < 5; ++i) v[2 + i] = x.extra[i];
        } else if constexpr (std::is_same_v<T, io::MotorSample>) {
          v[1] = x.current_right_A;
          v[2] = x.current_left_A;
          v[3] = x.vrc_right_V;
          v[4] = x.vrc_left_V;
        } else if constexpr (std::is_same_v<T, io::SonarSample>) {
          v[1] = x.range_m;
        } else if constexpr (std::is_same_v<T, io::PozyxSample>) {
          v[1] = x.x_m;
          v[2] = x.y_m;
          if (x.has_z) v[3] = x.z_m;
        } else if constexpr (std::is_same_v<T, io::JoystickSample>) {
          v[1] = x.v_cmd_m_s;
          v[2] = x.omega_cmd_rad_s;
        }
      },
      s);
  // The optional group is written when every field in it is available.
  bool write_optional = true;
  for (const auto& p : pieces_)
    if (p.optional && p.is_field && p.field >= 0 && !v[p.field]) write_optional = false;
  std::string line;
  for (const auto& p : pieces_) {
    if (p.optional && !write_optional) continue;
    if (!p.is_field) {
      line += p.literal;
    } else if (p.field < 0) {
      line += '0';
    } else if (isTickField(kind_, p.field)) {
      line += std::to_string(static_cast<int64_t>(*v[p.field]));
    } else {
      bool exact = true;
      const double raw = invertCalibration(calib_[p.field], *v[p.field], exact);
      if (!exact && inexact) ++*inexact;
      line += io::formatNumber(raw);
    }
  }
  return line;
}

}  // namespace wheelchair::capture
