// util::writeShortest / writeFixed6 write exactly fmt's "{}" / "{:.6f}" characters (the
// estimates CSV's documented format), and the shortest form reads back to the same double.
#include "libwheelchair/util/NumberFormat.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

using namespace wheelchair::util;

namespace {

std::string shortest(double x) {
  char buf[kMaxDoubleChars];
  return std::string(buf, writeShortest(buf, x));
}

std::string sig10(double x) {
  char buf[kMaxDoubleChars];
  return std::string(buf, write10Significant(buf, x));
}

// The reference for write10Significant: printf's "%.9e" digits (exact, half to even), read
// back and written in the shortest form, which for a normal double is those digits without
// trailing zeros (two decimals of <= 10 digits differ by far more than one ulp).
std::string sig10Reference(double x) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9e", x);
  return fmt::format("{}", std::strtod(buf, nullptr));
}

// Normal and below 2^1023 (above, the shortest form: 10 digits may read back as inf;
// subnormals have fewer digits than 10).
bool hasReference(double x) {
  return x == 0.0 ||
         (std::fabs(x) >= std::numeric_limits<double>::min() && std::fabs(x) < 0x1p1023);
}

std::string fixed6(double x) {
  char buf[kMaxFixed6Chars];
  return std::string(buf, writeFixed6(buf, x));
}

double fromBits(std::uint64_t b) {
  double x;
  std::memcpy(&x, &b, sizeof x);
  return x;
}

// Values of the kinds a filter writes and the format's edge cases.
std::vector<double> edgeValues() {
  std::vector<double> v = {0.0,
                           -0.0,
                           1.0,
                           -1.0,
                           0.1,
                           0.3,
                           1e-4,
                           9.9999e-5,
                           1e-5,
                           1.5e-5,
                           123456789012345.0,
                           1234567890123456.0,
                           1e15,
                           9999999999999998.0,
                           1e16,
                           1.7976931348623157e308,
                           std::numeric_limits<double>::min(),
                           std::numeric_limits<double>::denorm_min(),
                           -std::numeric_limits<double>::denorm_min(),
                           5e-324,
                           1e-100,
                           1e100,
                           2.5e-310,
                           std::numeric_limits<double>::quiet_NaN(),
                           -std::numeric_limits<double>::quiet_NaN(),
                           std::numeric_limits<double>::infinity(),
                           -std::numeric_limits<double>::infinity(),
                           3600.0,
                           0.0078125,
                           1.0 / 128,
                           3.0078125,
                           0.0000005,
                           0.0000015,
                           -0.0000004,
                           1099511627775.5,
                           1099511627776.0,
                           -1099511627777.25,
                           4503599627370496.5};
  for (int e = -330; e <= 310; ++e) {
    const double p = std::pow(10.0, e);
    for (double x : {p, std::nextafter(p, 0.0),
                     std::nextafter(p, std::numeric_limits<double>::infinity()), 3 * p, -7.25 * p})
      v.push_back(x);
  }
  return v;
}

}  // namespace

TEST(NumberFormat, ShortestIsFmtsFormOnEdgeCasesAndRandomBitPatterns) {
  for (double x : edgeValues()) ASSERT_EQ(shortest(x), fmt::format("{}", x)) << x;
  std::mt19937_64 rng(17);
  for (int i = 0; i < 300000; ++i) {
    const double x = fromBits(rng());
    ASSERT_EQ(shortest(x), fmt::format("{}", x)) << i;
  }
}

TEST(NumberFormat, ShortestIsFmtsFormOnFilterLikeValuesAndReadsBackExactly) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> state(-200.0, 200.0), logsd(-12.0, 3.0);
  std::uniform_int_distribution<int> cents(-100000, 100000);
  for (int i = 0; i < 200000; ++i) {
    for (double x : {state(rng), std::pow(10.0, logsd(rng)), cents(rng) * 0.01,
                     static_cast<double>(static_cast<float>(state(rng)))}) {
      const std::string s = shortest(x);
      ASSERT_EQ(s, fmt::format("{}", x)) << i;
      ASSERT_EQ(std::strtod(s.c_str(), nullptr), x) << s;  // round trip, bit for bit
    }
  }
}

TEST(NumberFormat, Fixed6IsFmtsFormIncludingTiesNegativeZeroAndLargeValues) {
  for (double x : edgeValues()) ASSERT_EQ(fixed6(x), fmt::format("{:.6f}", x)) << x;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> t(0.0, 40000.0), wide(-2e12, 2e12);
  std::uniform_int_distribution<std::int64_t> micros(0, 40000000000LL);
  for (int i = 0; i < 100000; ++i) {
    const std::int64_t us = micros(rng);
    for (double x : {t(rng), wide(rng), us * 1e-6, static_cast<double>(us) / 1e6,
                     (us | 1) / 128.0 / 1024.0, -t(rng) * 1e-7}) {
      ASSERT_EQ(fixed6(x), fmt::format("{:.6f}", x)) << i << " " << x;
    }
  }
  for (int i = 0; i < 20000; ++i) {  // any double (fmt's slow path beyond 2^40)
    const double x = fromBits(rng());
    ASSERT_EQ(fixed6(x), fmt::format("{:.6f}", x)) << i << " " << x;
  }
  for (int j = -5000; j < 5000; ++j) {  // j / 128: exact ties at the 7th decimal for odd j
    const double x = 3600.0 + j / 128.0;
    ASSERT_EQ(fixed6(x), fmt::format("{:.6f}", x)) << x;
  }
  EXPECT_EQ(fixed6(12.5), "12.500000");
  EXPECT_EQ(fixed6(-0.0), "-0.000000");
}

TEST(NumberFormat, TenSignificantDigitsAreExactlyRoundedAndInTheShortestLayout) {
  for (double x : edgeValues()) {
    if (std::isnan(x) || std::isinf(x)) {
      ASSERT_EQ(sig10(x), fmt::format("{}", x));
    } else if (hasReference(x)) {
      ASSERT_EQ(sig10(x), sig10Reference(x)) << x;
    }
  }
  std::mt19937_64 rng(11);
  for (int i = 0; i < 300000; ++i) {  // every normal exponent (fast path and fmt fallback)
    const double x = fromBits(rng());
    if (hasReference(x)) {
      ASSERT_EQ(sig10(x), sig10Reference(x)) << i << " " << x;
    }
  }
  std::uniform_real_distribution<double> state(-200.0, 200.0), logsd(-12.0, 3.0);
  for (int i = 0; i < 200000; ++i) {  // a filter's values: within 5e-10 relative
    for (double x : {state(rng), std::pow(10.0, logsd(rng)), 1.7e9 + state(rng)}) {
      const std::string s = sig10(x);
      ASSERT_EQ(s, sig10Reference(x)) << i;
      ASSERT_LE(std::fabs(std::strtod(s.c_str(), nullptr) - x), 5e-10 * std::fabs(x)) << s;
    }
  }
  // Exact ties go to the even digit, as printf; rounding up to the next power of ten.
  for (std::int64_t j = 1000000000; j < 1000200000; ++j) {
    const double x = static_cast<double>(j * 10 + 5);  // d...d5: a tie at the 10th digit
    ASSERT_EQ(sig10(x), sig10Reference(x)) << j;
    ASSERT_EQ(sig10(x / 1024), sig10Reference(x / 1024)) << j;
  }
  EXPECT_EQ(sig10(12345678905.0), "12345678900");
  EXPECT_EQ(sig10(12345678915.0), "12345678920");
  EXPECT_EQ(sig10(9999999999.5), "10000000000");
  EXPECT_EQ(sig10(0.99999999996), "1");
  EXPECT_EQ(sig10(1.0 / 3), "0.3333333333");
  EXPECT_EQ(sig10(-2.0 / 3), "-0.6666666667");
  EXPECT_EQ(sig10(1e-5), "1e-05");
  EXPECT_EQ(sig10(0.1), "0.1");
  EXPECT_EQ(sig10(-0.0), "-0");
  EXPECT_EQ(sig10(3600.0), "3600");
  EXPECT_EQ(sig10(-1.7976931348623157e308), "-1.7976931348623157e+308");  // not -inf
  EXPECT_EQ(sig10(8e307), "8e+307");
  EXPECT_EQ(sig10(5e-324), "4.940656458e-324");
}
