#include "libwheelchair/util/NumberFormat.h"

#include <fmt/compile.h>
#include <fmt/format.h>

#include <cmath>
#include <cstdint>
#include <cstring>

// The fast path reproduces fmt 9's float writer (format.h: write(out, T value) and
// do_write_float for a Dragonbox decimal with default specs); other fmt versions use fmt itself.
#if FMT_VERSION >= 90000 && FMT_VERSION < 100000
#define WHEELCHAIR_FAST_DOUBLE_TEXT 1
#else
#define WHEELCHAIR_FAST_DOUBLE_TEXT 0
#endif

namespace wheelchair::util {

namespace {

constexpr std::uint64_t kExponentMask = 0x7ff0000000000000ULL;

// "00" "01" ... "99".
struct Digits2 {
  char d[200];
  constexpr Digits2() : d() {
    for (int i = 0; i < 100; ++i) {
      d[2 * i] = static_cast<char>('0' + i / 10);
      d[2 * i + 1] = static_cast<char>('0' + i % 10);
    }
  }
};
constexpr Digits2 kDigits2{};

/// The 8 decimal digits of `x` < 10^8 at p[0, 8) (leading zeros), in 32-bit arithmetic.
inline void writeDigits8(char* p, std::uint32_t x) {
  const std::uint32_t hi = x / 10000, lo = x % 10000;
  std::memcpy(p, &kDigits2.d[(hi / 100) * 2], 2);
  std::memcpy(p + 2, &kDigits2.d[(hi % 100) * 2], 2);
  std::memcpy(p + 4, &kDigits2.d[(lo / 100) * 2], 2);
  std::memcpy(p + 6, &kDigits2.d[(lo % 100) * 2], 2);
}

/// The `n` decimal digits of `v` at p[0, n) (n >= number of digits of v; leading zeros).
inline void writeDigits(char* p, std::uint64_t v, int n) {
  for (; n > 8; n -= 8) {  // the last 8 digits, from a 64-bit division by 10^8
    writeDigits8(p + n - 8, static_cast<std::uint32_t>(v % 100000000));
    v /= 100000000;
  }
  auto x = static_cast<std::uint32_t>(v);  // n <= 8 digits left
  char* end = p + n;
  while (end - p >= 2) {
    end -= 2;
    std::memcpy(end, &kDigits2.d[(x % 100) * 2], 2);
    x /= 100;
  }
  if (end != p) *--end = static_cast<char>('0' + x % 10);
}

/// Decimal digits of v (1 for 0): floor(bits log10 2) from the bit length, corrected by one
/// comparison (v | 1 has the digits of v: v + 1 = 10^k only for odd v).
inline int countDigits(std::uint64_t v) {
  static constexpr std::uint64_t kPow10[20] = {1ULL,
                                               10ULL,
                                               100ULL,
                                               1000ULL,
                                               10000ULL,
                                               100000ULL,
                                               1000000ULL,
                                               10000000ULL,
                                               100000000ULL,
                                               1000000000ULL,
                                               10000000000ULL,
                                               100000000000ULL,
                                               1000000000000ULL,
                                               10000000000000ULL,
                                               100000000000000ULL,
                                               1000000000000000ULL,
                                               10000000000000000ULL,
                                               100000000000000000ULL,
                                               1000000000000000000ULL,
                                               10000000000000000000ULL};
  v |= 1;
  const int t = ((64 - __builtin_clzll(v)) * 1233) >> 12;  // 1233 / 4096 ~ log10 2
  return t + 1 - (v < kPow10[t] ? 1 : 0);
}

char* viaFmt(char* p, double x) {
  return fmt::format_to(p, FMT_COMPILE("{}"), x);
}

/// "e+XX", "e-XX" or "e+XXX" (|e| <= 324 for a double) at p; returns the end.
char* writeExponent(char* p, int e) {
  *p++ = 'e';
  if (e < 0) {
    *p++ = '-';
    e = -e;
  } else {
    *p++ = '+';
  }
  if (e >= 100) {
    *p++ = static_cast<char>('0' + e / 100);
    e %= 100;
  }
  std::memcpy(p, &kDigits2.d[e * 2], 2);
  return p + 2;
}

/// x = sig 10^exp10 (sig > 0, the sign already written) in fmt's "{}" layout: fixed notation
/// when the exponent of the first digit is in [-4, 16), d[.ddd]e+XX otherwise.
char* writeDecimal(char* p, std::uint64_t sig, int exp10) {
  const int n = countDigits(sig);
  const int out_exp = exp10 + n - 1;  // exponent of the first digit
  // The digits are written one place to the right and the leading ones moved left by one
  // to make room for the point (no variable-length copies: they were library calls).
  if (out_exp < -4 || out_exp >= 16) {  // d[.ddd]e+XX
    writeDigits(p + 1, sig, n);
    p[0] = p[1];
    if (n > 1) {
      p[1] = '.';
      p += n + 1;
    } else {
      p += 1;
    }
    return writeExponent(p, out_exp);
  }
  if (exp10 >= 0) {  // ddd000
    writeDigits(p, sig, n);
    p += n;
    std::memset(p, '0', static_cast<std::size_t>(exp10));
    return p + exp10;
  }
  const int int_digits = n + exp10;
  if (int_digits > 0) {  // dd.ddd (int_digits < n <= 17)
    writeDigits(p + 1, sig, n);
    for (int i = 0; i < int_digits; ++i) p[i] = p[i + 1];
    p[int_digits] = '.';
    return p + n + 1;
  }
  *p++ = '0';  // 0.000ddd
  *p++ = '.';
  std::memset(p, '0', static_cast<std::size_t>(-int_digits));
  p += -int_digits;
  writeDigits(p, sig, n);
  return p + n;
}

/// q 10^exp10 (10^9 <= q < 10^10, the sign already written) with q's trailing zeros dropped,
/// in writeDecimal's layout. The digits go through a local buffer and fixed 16-byte copies
/// (no variable-length library calls): it writes up to kMaxDoubleChars characters at p,
/// beyond the returned end too.
char* writeTenDigits(char* p, std::uint64_t q, int exp10) {
  // Furthest byte written: sign, up to 11 characters before the last copy, 16 copied.
  static_assert(kMaxDoubleChars >= 1 + 11 + 16, "room for the fixed-size copies");
  char d[32] = {};
  std::memcpy(d, &kDigits2.d[(q / 100000000) * 2], 2);  // 10..99
  writeDigits8(d + 2, static_cast<std::uint32_t>(q % 100000000));
  int n = 10;
  while (d[n - 1] == '0') --n;          // d[0] != '0'
  const int out_exp = exp10 + 9;        // exponent of the first digit
  if (out_exp < -4 || out_exp >= 16) {  // d[.ddd]e+XX
    p[0] = d[0];
    if (n > 1) {
      p[1] = '.';
      std::memcpy(p + 2, d + 1, 16);
      p += n + 1;
    } else {
      p += 1;
    }
    return writeExponent(p, out_exp);
  }
  if (out_exp >= n - 1) {  // ddd000 (out_exp <= 15)
    std::memcpy(p, d, 16);
    std::memset(p + n, '0', 16);
    return p + out_exp + 1;
  }
  if (out_exp >= 0) {  // dd.ddd
    const int int_digits = out_exp + 1;
    std::memcpy(p, d, 16);
    p[int_digits] = '.';
    std::memcpy(p + int_digits + 1, d + int_digits, 16);
    return p + n + 1;
  }
  std::memcpy(p, "0.000", 6);  // 0.000ddd (-4 <= out_exp < 0)
  p += 1 - out_exp;
  std::memcpy(p, d, 16);
  return p + n;
}

/// |x| rounded to 10 significant digits by fmt's "{:.9e}" (exact decimal conversion), as
/// q 10^exp10 with 10^9 <= q < 10^10. The fallback of write10Significant.
void round10ViaFmt(double x, std::uint64_t& q, int& exp10) {
  char buf[40];
  const char* end = fmt::format_to(buf, FMT_COMPILE("{:.9e}"), std::fabs(x));
  // "d.ddddddddde[+-]XX[X]"
  q = static_cast<std::uint64_t>(buf[0] - '0');
  for (int i = 2; i < 11; ++i) q = q * 10 + static_cast<std::uint64_t>(buf[i] - '0');
  int e = 0;
  for (const char* c = buf + 13; c < end; ++c) e = e * 10 + (*c - '0');
  exp10 = (buf[12] == '-' ? -e : e) - 9;
}

// 5^k for k <= 27 (5^27 < 2^63).
constexpr std::uint64_t kPow5[28] = {1ULL,
                                     5ULL,
                                     25ULL,
                                     125ULL,
                                     625ULL,
                                     3125ULL,
                                     15625ULL,
                                     78125ULL,
                                     390625ULL,
                                     1953125ULL,
                                     9765625ULL,
                                     48828125ULL,
                                     244140625ULL,
                                     1220703125ULL,
                                     6103515625ULL,
                                     30517578125ULL,
                                     152587890625ULL,
                                     762939453125ULL,
                                     3814697265625ULL,
                                     19073486328125ULL,
                                     95367431640625ULL,
                                     476837158203125ULL,
                                     2384185791015625ULL,
                                     11920928955078125ULL,
                                     59604644775390625ULL,
                                     298023223876953125ULL,
                                     1490116119384765625ULL,
                                     7450580596923828125ULL};

/// round(|x| 10^(9 - e)) for the normal |x| = M 2^e2 (M = 2^52 + mantissa, biased exponent
/// `biased`), e = floor(log10 |x|), half to even on the exact binary value, in integer
/// arithmetic: q 10^exp10 with 10^9 <= q < 10^10. False outside 1e-18 <~ |x| < 1e29 (then
/// round10ViaFmt).
bool round10Exact(std::uint64_t M, int biased, std::uint64_t& q, int& exp10) {
  // |x| = M 2^e2 exactly; e = floor(log10 |x|) is estimated from the binary exponent
  // (log10 2 ~ 78913 / 2^18) as e or e - 1, corrected by comparing q with 10^10 below.
  using u128 = unsigned __int128;
  const int e2 = biased - 1075;
  int e = ((biased - 1023) * 78913) >> 18;
  // round(v / d) half to even (d > 0); only for |x| >= 10^10.
  const auto roundDiv = [](u128 v, u128 d) -> std::uint64_t {
    const u128 quo = v / d, rest = v % d;
    auto r = static_cast<std::uint64_t>(quo);
    if (2 * rest > d || (2 * rest == d && (r & 1))) ++r;
    return r;
  };
  bool fast = true;
  for (int attempt = 0; attempt < 2; ++attempt) {
    const int k = 9 - e;
    if (k >= 0 && k <= 27) {    // |x| 10^k = M 5^k 2^(e2 + k), M 5^k < 2^116, e2 + k < 0
      const int s = -(e2 + k);  // 19 <= s <= ~85 for the k of this branch
      const u128 v = static_cast<u128>(M) * kPow5[k];
      if (s > 0 && s < 127) {  // round(v / 2^s), half to even
        const u128 rest = v & ((static_cast<u128>(1) << s) - 1);
        const u128 half = static_cast<u128>(1) << (s - 1);
        q = static_cast<std::uint64_t>(v >> s);
        if (rest > half || (rest == half && (q & 1))) ++q;
      } else {
        q = 0;  // (not reached) to the fallback
      }
    } else if (k < 0 && k >= -19 && e2 <= 127 - 53) {  // |x| / 10^-k, 10^10 <= |x| < 2^127
      std::uint64_t p10 = 1;
      for (int i = 0; i < -k; ++i) p10 *= 10;  // 10^19 < 2^64
      q = e2 >= 0 ? roundDiv(static_cast<u128>(M) << e2, p10)
                  : roundDiv(M, static_cast<u128>(p10) << -e2);
    } else {
      fast = false;
      break;
    }
    exp10 = -k;
    if (q < 10000000000ULL) break;
    if (q == 10000000000ULL) {  // rounded up to 10^10 = 1.000000000 10^(e + 1)
      q = 1000000000ULL;
      exp10 = -k + 1;
      break;
    }
    ++e;  // the estimate of e was one too low: round again at one digit less
  }
  return fast && q >= 1000000000ULL && q < 10000000000ULL;
}

}  // namespace

char* writeShortest(char* p, double x) {
#if WHEELCHAIR_FAST_DOUBLE_TEXT
  std::uint64_t bits;
  std::memcpy(&bits, &x, sizeof bits);
  if ((bits & kExponentMask) == kExponentMask) return viaFmt(p, x);  // nan, inf
  if (bits >> 63) {
    *p++ = '-';
    x = -x;
  }
  const auto dec = fmt::detail::dragonbox::to_decimal(x);
  return writeDecimal(p, dec.significand, dec.exponent);
#else
  return viaFmt(p, x);
#endif
}

char* write10Significant(char* p, double x) {
  std::uint64_t bits;
  std::memcpy(&bits, &x, sizeof bits);
  if ((bits & kExponentMask) == kExponentMask) return viaFmt(p, x);  // nan, inf
  // |x| >= 2^1023: 10 digits may round above the largest double (reads back as inf).
  if ((bits & kExponentMask) == 0x7fe0000000000000ULL) return writeShortest(p, x);
  if (bits >> 63) *p++ = '-';
  const int biased = static_cast<int>((bits >> 52) & 0x7ff);
  const std::uint64_t m = bits & 0x000fffffffffffffULL;
  if (biased == 0 && m == 0) {  // +-0
    *p++ = '0';
    return p;
  }
  std::uint64_t q = 0;
  int exp10 = 0;
  // Subnormals (not a filter's value) and very large or small |x| through fmt.
  if (biased == 0 || !round10Exact(m | (1ULL << 52), biased, q, exp10)) round10ViaFmt(x, q, exp10);
  return writeTenDigits(p, q, exp10);
}

char* writeFixed6(char* p, double x) {
  std::uint64_t bits;
  std::memcpy(&bits, &x, sizeof bits);
  const int biased = static_cast<int>((bits >> 52) & 0x7ff);
  // Exact for |x| < 2^40 (the integer part and the 6 decimals fit 64 bits); larger values,
  // nan and inf go to fmt.
  if (biased >= 1023 + 40) return fmt::format_to(p, FMT_COMPILE("{:.6f}"), x);
  // |x| = m 2^-s exactly; |x| 10^6 = m 10^6 2^-s, rounded to the nearest integer q.
  const std::uint64_t m = (bits & 0x000fffffffffffffULL) | (biased ? (1ULL << 52) : 0);
  const int s = 1075 - (biased ? biased : 1);  // >= 1075 - 1062 = 13
  std::uint64_t q = 0;
  if (s < 100) {  // otherwise |x| 10^6 < 2^(53 + 20 - 100): q = 0, no tie
    using u128 = unsigned __int128;
    const u128 scaled = static_cast<u128>(m) * 1000000u;
    const u128 rest = scaled & ((static_cast<u128>(1) << s) - 1);
    const u128 half = static_cast<u128>(1) << (s - 1);
    q = static_cast<std::uint64_t>(scaled >> s);
    if (rest > half) {
      ++q;
    } else if (rest == half) {  // exactly halfway: fmt's own rounding decides
      return fmt::format_to(p, FMT_COMPILE("{:.6f}"), x);
    }
  }
  if (bits >> 63) *p++ = '-';
  const std::uint64_t ip = q / 1000000, frac = q % 1000000;
  const int n = countDigits(ip);
  writeDigits(p, ip, n);
  p += n;
  *p++ = '.';
  writeDigits(p, frac, 6);
  return p + 6;
}

}  // namespace wheelchair::util
