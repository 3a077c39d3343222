// Text helpers for error messages that echo input, and bounded line reading.
//
// Every error that quotes input (a CSV field, a config value, a line from a sensor) goes
// through quoteInput(): control bytes and non-ASCII bytes are escaped (`\n`, `\r`, `\t`, `\xNN`, so
// a message stays one line and cannot drive the terminal) and the text is cut to `max_chars`
// characters with
// "..." appended. getBoundedLine() reads one line but never more than `max_bytes`, so a
// 200 MB file without a newline costs at most `max_bytes` of memory, not gigabytes.
//
// Example:
//   quoteInput("1.5\x1b[2J,abc", 80)  -> "1.5\x1b[2J,abc"  (ESC written as the 4 characters \x1b)
//   std::string line; std::size_t n = 0;
//   while (getBoundedLine(in, line, kMaxLineBytes, path, ++n)) ...   // throws on a longer line
#pragma once

#include <cstddef>
#include <istream>
#include <string>
#include <string_view>

namespace wheelchair::util {

/// Longest line the text readers accept (bytes, without the newline).
constexpr std::size_t kMaxLineBytes = 1 << 20;

/// `s` without leading and trailing blanks (space, tab, CR, LF).
std::string trim(std::string_view s);

/// `s` with control bytes escaped and cut to `max_chars` characters (+ "...").
std::string quoteInput(std::string_view s, std::size_t max_chars = 80);

/// Reduces an exception text to one meaningful line: for MRPT's multi-line
/// "==== MRPT exception ====" texts (possibly nested), the innermost "Message:" line; otherwise
/// the first non-empty line. The result is passed through quoteInput(…, 200).
std::string oneLineMessage(const std::string& what);

/// std::getline with a length limit: reads the next line (without '\n'; a trailing '\r' is
/// kept) into `line`; false at end of input. A line longer than `max_bytes` throws one
/// std::runtime_error "FILE:LINE: line longer than N bytes (no newline?)"; `file` and
/// `line_no` only name the place in that message.
bool getBoundedLine(std::istream& in, std::string& line, std::size_t max_bytes,
                    const std::string& file, std::size_t line_no);

}  // namespace wheelchair::util
