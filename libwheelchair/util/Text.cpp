#include "libwheelchair/util/Text.h"

#include <fmt/format.h>

#include <stdexcept>

namespace wheelchair::util {

std::string quoteInput(std::string_view s, std::size_t max_chars) {
  std::string out;
  const bool cut = s.size() > max_chars;
  if (cut) s = s.substr(0, max_chars);
  out.reserve(s.size() + 8);
  for (const char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    if (c == '\n')
      out += "\\n";
    else if (c == '\r')
      out += "\\r";
    else if (c == '\t')
      out += "\\t";
    else if (c < 0x20 || c >= 0x7f)
      out += fmt::format("\\x{:02x}", c);
    else
      out += ch;
  }
  if (cut) out += "...";
  return out;
}

std::string trim(std::string_view s) {
  const auto a = s.find_first_not_of(" \t\r\n");
  if (a == std::string_view::npos) return {};
  const auto b = s.find_last_not_of(" \t\r\n");
  return std::string(s.substr(a, b - a + 1));
}

std::string oneLineMessage(const std::string& what) {
  auto trim = [](std::string_view v) {
    while (!v.empty() && (v.front() == ' ' || v.front() == '\t')) v.remove_prefix(1);
    while (!v.empty() && (v.back() == ' ' || v.back() == '\r' || v.back() == '\t'))
      v.remove_suffix(1);
    return v;
  };
  const std::string_view w(what);
  if (w.find("==== MRPT exception ====") != std::string_view::npos) {
    // Nested MRPT exceptions: the last "Message:" is the innermost, most specific one.
    const auto m = w.rfind("Message:");
    if (m != std::string_view::npos) {
      auto line = w.substr(m + 8);
      line = line.substr(0, line.find('\n'));
      if (!trim(line).empty()) return quoteInput(trim(line), 200);
    }
  }
  std::size_t pos = 0;
  while (pos <= w.size()) {
    const auto nl = w.find('\n', pos);
    const auto line = trim(w.substr(pos, nl == std::string_view::npos ? w.npos : nl - pos));
    if (!line.empty() && line.find("==== MRPT exception ====") == std::string_view::npos)
      return quoteInput(line, 200);
    if (nl == std::string_view::npos) break;
    pos = nl + 1;
  }
  return quoteInput(trim(w), 200);
}

bool getBoundedLine(std::istream& in, std::string& line, std::size_t max_bytes,
                    const std::string& file, std::size_t line_no) {
  line.clear();
  std::streambuf* sb = in.rdbuf();
  if (!sb || !in.good()) {
    in.setstate(std::ios::failbit);
    return false;
  }
  for (;;) {
    const auto c = sb->sbumpc();
    if (c == std::char_traits<char>::eof()) {
      in.setstate(std::ios::eofbit);
      if (line.empty()) {
        in.setstate(std::ios::failbit);
        return false;
      }
      return true;
    }
    if (c == '\n') return true;
    if (line.size() >= max_bytes)
      throw std::runtime_error(
          fmt::format("{}:{}: line longer than {} bytes (no newline?)", file, line_no, max_bytes));
    line.push_back(static_cast<char>(c));
  }
}

}  // namespace wheelchair::util
