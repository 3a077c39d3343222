// Fast text forms of doubles for the large CSV writers (docs/benchmarks.md, "Fifth round").
//
// writeShortest(p, x) writes exactly the characters fmt's "{}" writes for a double: the
// shortest decimal that reads back (strtod, std::from_chars) to the same double (fmt's
// Dragonbox digits), in fixed notation when the decimal exponent e of the first digit is in
// [-4, 16) and as d.ddde+XX otherwise; "-" for a set sign bit (also "-0"), "nan"/"inf" as fmt.
// write10Significant(p, x) writes x rounded to 10 significant digits (exact, half to even) in
// the same layout, trailing zeros dropped: ~2/3 of the characters and a cheaper conversion (no
// shortest-digit search) for writers whose numbers need no exact read-back.
// writeFixed6(p, x) writes what fmt's "{:.6f}" writes: x rounded to 6 decimals (exactly, from
// the double's binary value), e.g. 12.5 -> "12.500000".
// Both write into a caller's buffer (room for kMaxDoubleChars / kMaxFixed6Chars characters)
// and return the end; no allocation, no locale. They exist because the estimates CSV writes ~10 M
// numbers per recorded hour (26 ns a number against fmt's 30, of which ~20 ns are Dragonbox's
// digits); the characters are identical (tests/util/test_number_format.cpp compares them with fmt
// on random bit patterns and on the values a filter writes).
//
// Example:
//   char buf[kMaxFixed6Chars + 1 + kMaxDoubleChars];
//   char* p = writeFixed6(buf, 1.25);  *p++ = ',';  p = writeShortest(p, 0.1);   // "1.250000,0.1"
#pragma once

#include <cstddef>

namespace wheelchair::util {

/// Longest output of writeShortest / writeFixed6 for |x| < 1e300 (writeFixed6 of a larger
/// value falls back to fmt and may write up to ~310 characters: size buffers for
/// kMaxFixed6Chars there).
constexpr std::size_t kMaxDoubleChars = 32;
constexpr std::size_t kMaxFixed6Chars = 320;

/// fmt's "{}" of `x` (shortest round-trip form) at `p`; returns the end.
char* writeShortest(char* p, double x);

/// `x` rounded to 10 significant digits (exactly, from its binary value, half to even: the
/// digits of printf's "%.9e"), trailing zeros dropped, in writeShortest's layout (fixed for a
/// first-digit exponent in [-4, 16), d.ddde+XX otherwise); "0" / "-0", nan and inf as fmt;
/// |x| >= 2^1023 (could round above the largest double) in writeShortest's form.
/// Relative error <= 5e-10. E.g. 0.1 -> "0.1", 1.0 / 3 -> "0.3333333333", 2.0 / 3 ->
/// "0.6666666667", 1e-5 -> "1e-05", 123456789012.5 -> "123456789000" (up to kMaxDoubleChars).
char* write10Significant(char* p, double x);

/// fmt's "{:.6f}" of `x` at `p`; returns the end (up to kMaxFixed6Chars characters).
char* writeFixed6(char* p, double x);

}  // namespace wheelchair::util
