// util::writeShortest / writeFixed6 write exactly fmt's "{}" / "{:.6f}" characters (the
// estimates CSV's documented format), and the shortest form reads back to the same double.
#include "libwheelchair/util/NumberFormat.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
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
