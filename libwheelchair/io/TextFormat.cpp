#include "libwheelchair/io/TextFormat.h"

#include "libwheelchair/util/Text.h"

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <filesystem>
#include <limits>

namespace fs = std::filesystem;

namespace wheelchair::io {

namespace {

struct Layout {
  std::vector<std::string> required;  // header columns that must be present, in order
  std::vector<std::string> optional;  // an allowed all-or-nothing tail of further columns
  bool required_file;
};

const Layout& layoutOf(StreamKind k) {
  static const std::map<StreamKind, Layout> kLayouts = {
      {StreamKind::Encoders, {{"t", "right_ticks", "left_ticks"}, {}, true}},
      {StreamKind::Imu, {{"t", "gyro_z"}, {"gyro_x", "gyro_y", "acc_x", "acc_y", "acc_z"}, true}},
      {StreamKind::Motors,
       {{"t", "current_right", "current_left", "vrc_right", "vrc_left"}, {}, true}},
      {StreamKind::Sonar, {{"t", "range"}, {}, false}},
      {StreamKind::Pozyx, {{"t", "x", "y"}, {"z"}, false}},
      {StreamKind::Joystick, {{"t", "v_cmd", "w_cmd"}, {}, false}},
      {StreamKind::GroundTruth, {{"t", "x", "y", "phi"}, {}, false}},
      {StreamKind::Landmarks, {{"t", "landmark_id", "range", "bearing"}, {}, false}},
  };
  return kLayouts.at(k);
}

std::string trim(std::string s) {
  while (!s.empty() && (s.back() == '\r' || s.back() == ' ' || s.back() == '\t')) s.pop_back();
  std::size_t b = 0;
  while (b < s.size() && (s[b] == ' ' || s[b] == '\t')) ++b;
  return s.substr(b);
}

std::vector<std::string> splitComma(const std::string& s) {
  std::vector<std::string> out;
  std::size_t start = 0;
  for (;;) {
    const std::size_t p = s.find(',', start);
    out.push_back(trim(s.substr(start, p == std::string::npos ? std::string::npos : p - start)));
    if (p == std::string::npos) break;
    start = p + 1;
  }
  return out;
}

std::string joinColumns(const std::vector<std::string>& c) {
  std::string s;
  for (std::size_t i = 0; i < c.size(); ++i) s += (i ? "," : "") + c[i];
  return s;
}

}  // namespace

std::string formatNumber(double x) {
  return fmt::format("{}", x);
}

std::string formatTime(double t_s) {
  const double us = std::round(t_s * 1e6) / 1e6;
  return fmt::format("{}", us);
}

// ---------------------------------------------------------------- CsvStreamReader

CsvStreamReader::CsvStreamReader(const std::string& path, StreamKind kind)
    : path_(path), kind_(kind), in_(path, std::ios::binary) {
  if (!in_) throw FormatError(fmt::format("{}: cannot open file", path));
  std::string header;
  if (!util::getBoundedLine(in_, header, util::kMaxLineBytes, path, 1))
    throw FormatError(fmt::format("{}: empty file (no header row)", path));
  line_no_ = 1;
  if (header.size() >= 3 && header.compare(0, 3, "\xEF\xBB\xBF") == 0) header.erase(0, 3);
  columns_ = splitComma(trim(header));
  const Layout& lay = layoutOf(kind);
  std::vector<std::string> full = lay.required;
  full.insert(full.end(), lay.optional.begin(), lay.optional.end());
  if (columns_ != lay.required && (lay.optional.empty() || columns_ != full)) {
    std::string expected = "'" + joinColumns(lay.required) + "'";
    if (!lay.optional.empty()) expected += " or '" + joinColumns(full) + "'";
    throw FormatError(fmt::format("{}:1: header '{}' is not {}", path,
                                  util::quoteInput(joinColumns(columns_)), expected));
  }
}

bool CsvStreamReader::next(AnySample& out) {
  for (;;) {
    if (!util::getBoundedLine(in_, buf_, util::kMaxLineBytes, path_, line_no_ + 1)) {
      if (in_.bad()) throw FormatError(fmt::format("{}:{}: read error", path_, line_no_ + 1));
      return false;
    }
    ++line_no_;
    if (trim(buf_).empty()) continue;  // blank lines (e.g. a trailing one) carry no data
    break;
  }
  const std::string where = fmt::format("{}:{}", path_, line_no_);
  // Parse the comma-separated fields without allocating per field.
  values_.clear();
  const char* p = buf_.data();
  const char* end = p + buf_.size();
  while (end > p && (end[-1] == '\r' || end[-1] == ' ' || end[-1] == '\t')) --end;
  std::size_t col = 0;
  for (;;) {
    while (p < end && (*p == ' ' || *p == '\t')) ++p;
    const std::size_t left = p < end ? static_cast<std::size_t>(end - p) : 0;
    const char* field_end = static_cast<const char*>(memchr(p, ',', left));
    if (!field_end) field_end = end;
    const char* fe = field_end;
    while (fe > p && (fe[-1] == ' ' || fe[-1] == '\t')) --fe;
    if (col >= columns_.size())
      throw FormatError(fmt::format("{}: {} fields, expected {} ({})", where, col + 1,
                                    columns_.size(), joinColumns(columns_)));
    double v = 0;
    const char* num = (p < fe && *p == '+') ? p + 1 : p;
    auto [ptr, ec] = std::from_chars(num, fe, v);
    if (p == fe || ec != std::errc() || ptr != fe) {
      throw FormatError(fmt::format("{}: column '{}': '{}' is not a number", where, columns_[col],
                                    util::quoteInput(std::string_view(p, fe - p))));
    }
    if (!std::isfinite(v))
      throw FormatError(fmt::format("{}: column '{}': value {} is not finite", where, columns_[col],
                                    util::quoteInput(std::string_view(p, fe - p))));
    if (col == 0 && v < 0)  // MRPT's clock would wrap it to ~1.8e12 s
      throw FormatError(
          fmt::format("{}: column '{}': negative timestamp {} (times are seconds >= 0)", where,
                      columns_[col], util::quoteInput(std::string_view(p, fe - p))));
    values_.push_back(v);
    ++col;
    if (field_end == end) break;
    p = field_end + 1;
  }
  if (values_.size() != columns_.size())
    throw FormatError(fmt::format("{}: {} fields, expected {} ({})", where, values_.size(),
                                  columns_.size(), joinColumns(columns_)));
  auto asInt32 = [&](std::size_t i) {
    const double v = values_[i];
    if (v != std::floor(v) || v < -2147483648.0 || v > 2147483647.0)
      throw FormatError(
          fmt::format("{}: column '{}': {} is not a 32-bit integer count", where, columns_[i], v));
    return static_cast<int32_t>(v);
  };
  const auto& x = values_;
  switch (kind_) {
    case StreamKind::Encoders:
      out = EncoderSample{x[0], asInt32(1), asInt32(2)};
      break;
    case StreamKind::Imu: {
      ImuSample s{x[0], x[1], x.size() > 2, {}};
      for (std::size_t i = 2; i < x.size(); ++i) s.extra[i - 2] = x[i];
      out = s;
      break;
    }
    case StreamKind::Motors:
      out = MotorSample{x[0], x[1], x[2], x[3], x[4]};
      break;
    case StreamKind::Sonar:
      if (x[1] < 0) throw FormatError(fmt::format("{}: negative sonar range {}", where, x[1]));
      out = SonarSample{x[0], x[1]};
      break;
    case StreamKind::Pozyx:
      out = PozyxSample{x[0], x[1], x[2], x.size() > 3, x.size() > 3 ? x[3] : 0.0};
      break;
    case StreamKind::Joystick:
      out = JoystickSample{x[0], x[1], x[2]};
      break;
    case StreamKind::GroundTruth:
      out = GroundTruthPoseSample{x[0], x[1], x[2], x[3]};
      break;
    case StreamKind::Landmarks: {
      if (x[1] != std::floor(x[1])) throw FormatError(where + ": landmark_id is not an integer");
      out = LandmarkSample{x[0], static_cast<int>(x[1]), x[2], x[3]};
      break;
    }
  }
  return true;
}

// ---------------------------------------------------------------- TextRecordingReader

struct TextRecordingReader::Source {
  StreamKind kind;
  CsvStreamReader reader;
  AnySample head;
  bool has_head = false;
  std::size_t head_line = 0;  ///< line of `head` in the file
  double last_t = -std::numeric_limits<double>::infinity();
  TimestampIssues issues;
  Source(const std::string& path, StreamKind k) : kind(k), reader(path, k) {}
  void advance() {
    has_head = reader.next(head);
    if (!has_head) return;
    head_line = reader.line();
    const double t = timeOf(head);
    if (t < last_t) {
      if (!issues.out_of_order && !issues.duplicates) issues.first_bad_line = reader.line();
      ++issues.out_of_order;
    } else if (t == last_t) {
      if (!issues.out_of_order && !issues.duplicates) issues.first_bad_line = reader.line();
      ++issues.duplicates;
    }
    last_t = t;
  }
};

TextRecordingReader::TextRecordingReader(const std::string& dir) {
  if (!fs::is_directory(dir)) throw FormatError(fmt::format("{}: not a recording directory", dir));
  for (int k = 0; k < kNumStreams; ++k) {
    const auto kind = static_cast<StreamKind>(k);
    const fs::path path = fs::path(dir) / streamFileName(kind);
    if (!fs::exists(path)) {
      if (layoutOf(kind).required_file)
        throw FormatError(fmt::format("{}: required file is missing", path.string()));
      if (kind != StreamKind::GroundTruth && kind != StreamKind::Landmarks)
        missing_optional_.push_back(streamFileName(kind));
      continue;
    }
    auto src = std::make_unique<Source>(path.string(), kind);
    src->advance();
    sources_.push_back(std::move(src));
  }
  const fs::path meta = fs::path(dir) / "meta.ini";
  if (fs::exists(meta)) {
    std::ifstream in(meta);
    std::string line, section;
    std::size_t meta_line = 0;
    while (util::getBoundedLine(in, line, util::kMaxLineBytes, meta.string(), ++meta_line)) {
      line = trim(line);
      if (line.empty() || line[0] == '#' || line[0] == ';') continue;
      if (line.front() == '[' && line.back() == ']') {
        section = line.substr(1, line.size() - 2);
        continue;
      }
      const auto eq = line.find('=');
      if (section == "recording" && eq != std::string::npos)
        meta_[trim(line.substr(0, eq))] = trim(line.substr(eq + 1));
    }
  }
}

TextRecordingReader::~TextRecordingReader() = default;

bool TextRecordingReader::next(AnySample& out) {
  Source* best = nullptr;
  double best_t = 0;
  for (auto& s : sources_) {
    if (!s->has_head) continue;
    const double t = timeOf(s->head);
    if (!best || t < best_t) {
      best = s.get();
      best_t = t;
    }
  }
  if (!best) return false;
  if (max_gap_s_ > 0 && last_src_ && best_t - last_t_ > max_gap_s_)
    throw FormatError(fmt::format(
        "{}:{}: timestamp {} s jumps {:.3f} s after the previous sample ({} s, {}:{}): more than "
        "the import limit max_gap_s = {:g} s (a clock jump or a logger stall); raise [import] "
        "max_gap_s or --max-gap (0: no limit) to import it anyway",
        best->reader.path(), best->head_line, formatTime(best_t), best_t - last_t_,
        formatTime(last_t_), last_src_->reader.path(), last_line_, max_gap_s_));
  if (!last_src_ || best_t >= last_t_) {  // latest time so far (out-of-order rows kept)
    last_src_ = best;
    last_t_ = best_t;
    last_line_ = best->head_line;
  }
  out = best->head;
  best->advance();
  return true;
}

std::vector<std::string> TextRecordingReader::warnings() const {
  std::vector<std::string> w;
  for (const auto& f : missing_optional_)
    w.push_back(fmt::format("optional file {} not present", f));
  for (const auto& s : sources_) {
    if (s->issues.out_of_order || s->issues.duplicates)
      w.push_back(fmt::format(
          "{}: {} out-of-order and {} duplicated timestamps (first at line {}); kept as recorded",
          s->reader.path(), s->issues.out_of_order, s->issues.duplicates,
          s->issues.first_bad_line));
    if (s->last_t == -std::numeric_limits<double>::infinity() && layoutOf(s->kind).required_file)
      w.push_back(
          fmt::format("{}: header only, no data rows (a required stream: what needs it "
                      "will be not applicable)",
                      s->reader.path()));
  }
  return w;
}

std::map<StreamKind, std::vector<std::string>> TextRecordingReader::columns() const {
  std::map<StreamKind, std::vector<std::string>> c;
  for (const auto& s : sources_) c[s->kind] = s->reader.columns();
  return c;
}

Recording readTextRecording(const std::string& dir, std::vector<std::string>* warnings) {
  TextRecordingReader in(dir);
  Recording rec;
  AnySample s;
  while (in.next(s)) append(rec, s);
  rec.meta = in.meta();
  if (warnings) *warnings = in.warnings();
  return rec;
}

// ---------------------------------------------------------------- TextRecordingWriter

namespace {
/// Throws unless `dir` is absent, an empty directory or a recording directory of ours.
void checkExportTarget(const std::string& dir) {
  std::error_code ec;
  const auto st = fs::symlink_status(dir, ec);
  if (!fs::exists(st)) return;
  if (fs::is_symlink(st))
    throw std::runtime_error(
        fmt::format("{}: is a symbolic link; refusing to replace it with a directory", dir));
  if (!fs::is_directory(st))
    throw std::runtime_error(
        fmt::format("{}: exists and is not a directory; not overwriting", dir));
  // Replace only a directory that holds a recording of ours (never an unrelated folder).
  if (!fs::is_empty(dir, ec) && !fs::exists(fs::path(dir) / "encoders.csv"))
    throw std::runtime_error(
        fmt::format("{}: exists and is not a recording directory; not overwriting", dir));
}
}  // namespace

TextRecordingWriter::TextRecordingWriter(const std::string& dir)
    : dir_(dir), tmp_dir_(dir + ".tmp-export") {
  checkExportTarget(dir_);
  std::error_code ec;
  fs::remove_all(tmp_dir_, ec);
  fs::create_directories(tmp_dir_, ec);
  if (ec)
    throw std::runtime_error(
        fmt::format("{}: cannot create directory: {}", tmp_dir_, ec.message()));
}

TextRecordingWriter::~TextRecordingWriter() {
  if (!committed_) {
    files_.clear();  // each AtomicFile removes its temporary
    std::error_code ec;
    fs::remove_all(tmp_dir_, ec);
  }
}

std::ostream& TextRecordingWriter::fileFor(StreamKind k, const AnySample& first) {
  auto it = files_.find(k);
  if (it != files_.end()) return it->second->stream();
  const std::string path = (fs::path(tmp_dir_) / streamFileName(k)).string();
  auto& file = files_[k];
  file = std::make_unique<util::AtomicFile>(path);
  std::ostream& f = file->stream();
  const Layout& lay = layoutOf(k);
  std::vector<std::string> cols = lay.required;
  const bool with_optional = (k == StreamKind::Imu && std::get<ImuSample>(first).has_extra) ||
                             (k == StreamKind::Pozyx && std::get<PozyxSample>(first).has_z);
  if (with_optional) cols.insert(cols.end(), lay.optional.begin(), lay.optional.end());
  f << joinColumns(cols) << '\n';
  return f;
}

void TextRecordingWriter::write(const AnySample& s) {
  std::ostream& f = fileFor(kindOf(s), s);
  files_[kindOf(s)]->check();  // a full disk stops the export here, not at the end
  const std::string t = formatTime(timeOf(s));
  std::visit(
      [&](const auto& x) {
        using T = std::decay_t<decltype(x)>;
        if constexpr (std::is_same_v<T, EncoderSample>) {
          f << t << ',' << x.right_ticks << ',' << x.left_ticks << '\n';
        } else if constexpr (std::is_same_v<T, ImuSample>) {
          f << t << ',' << formatNumber(x.gyro_z_rad_s);
          if (x.has_extra)
            for (double e : x.extra) f << ',' << formatNumber(e);
          f << '\n';
        } else if constexpr (std::is_same_v<T, MotorSample>) {
          f << t << ',' << formatNumber(x.current_right_A) << ',' << formatNumber(x.current_left_A)
            << ',' << formatNumber(x.vrc_right_V) << ',' << formatNumber(x.vrc_left_V) << '\n';
        } else if constexpr (std::is_same_v<T, SonarSample>) {
          f << t << ',' << formatNumber(x.range_m) << '\n';
        } else if constexpr (std::is_same_v<T, PozyxSample>) {
          f << t << ',' << formatNumber(x.x_m) << ',' << formatNumber(x.y_m);
          if (x.has_z) f << ',' << formatNumber(x.z_m);
          f << '\n';
        } else if constexpr (std::is_same_v<T, JoystickSample>) {
          f << t << ',' << formatNumber(x.v_cmd_m_s) << ',' << formatNumber(x.omega_cmd_rad_s)
            << '\n';
        } else if constexpr (std::is_same_v<T, GroundTruthPoseSample>) {
          f << t << ',' << formatNumber(x.x_m) << ',' << formatNumber(x.y_m) << ','
            << formatNumber(x.phi_rad) << '\n';
        } else if constexpr (std::is_same_v<T, LandmarkSample>) {
          f << t << ',' << x.landmark_id << ',' << formatNumber(x.range_m) << ','
            << formatNumber(x.bearing_rad) << '\n';
        }
      },
      s);
}

void TextRecordingWriter::commit() {
  // Required files exist even when empty (header only), so the directory reads back.
  for (StreamKind k : {StreamKind::Encoders, StreamKind::Imu, StreamKind::Motors}) {
    if (!files_.count(k)) {
      AnySample first;
      if (k == StreamKind::Encoders) first = EncoderSample{};
      if (k == StreamKind::Imu) first = ImuSample{};
      if (k == StreamKind::Motors) first = MotorSample{};
      fileFor(k, first);
    }
  }
  for (auto& [k, f] : files_) f->commit();  // each checked: flush, fsync, close, rename
  if (!meta_.empty()) {
    util::writeFileAtomically((fs::path(tmp_dir_) / "meta.ini").string(), [&](std::ostream& m) {
      m << "[recording]\n";
      for (const auto& [k, v] : meta_) m << k << " = " << v << '\n';
    });
  }
  std::error_code ec;
  checkExportTarget(dir_);
  if (fs::exists(dir_)) fs::remove_all(dir_, ec);
  fs::rename(tmp_dir_, dir_, ec);
  if (ec)
    throw std::runtime_error(fmt::format("{}: cannot rename into place: {}", dir_, ec.message()));
  committed_ = true;
}

void writeTextRecording(const Recording& rec, const std::string& dir) {
  TextRecordingWriter w(dir);
  forEachInTimeOrder(rec, [&](const AnySample& s) { w.write(s); });
  w.setMeta(rec.meta);
  w.commit();
}

config::Options ImportOptions::options(const std::string& sec) {
  return config::Options(sec, "wheelchair import (plain-text recordings)")
      .real("max_gap_s", max_gap_s,
            "largest forward jump of the merged timeline accepted at import (s; 0: no check)",
            config::Range::atLeast(0));
}

namespace {
[[maybe_unused]] const bool kImportRegistered = config::registerOptionsOf<ImportOptions>("import");
}  // namespace

}  // namespace wheelchair::io
