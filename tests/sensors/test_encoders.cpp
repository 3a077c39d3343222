// Encoders: eq. (9), counter unwrapping, interval-mean wheel speeds (docs/sensors.md).
#include "libwheelchair/sensors/Encoders.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

using namespace wheelchair;
using namespace wheelchair::sensors;

namespace {
constexpr double kPi = 3.141592653589793238462643383279;
}

TEST(Encoders, OneWheelRevolutionIsNecNmpOverNepTicks) {
  EncoderParams p;  // Table I
  EXPECT_EQ(p.encoder_pulley_teeth, 30);
  EXPECT_EQ(p.wheel_pulley_teeth, 110);
  EXPECT_EQ(p.counts_per_rev, 2000);
  EXPECT_NEAR(p.ticksPerWheelRev(), 2000.0 * 110.0 / 30.0, 1e-9);
  EXPECT_NEAR(p.ticksPerWheelRev(), 7333.333333, 1e-6);
  EXPECT_NEAR(p.wheelRadPerTick(), 2 * kPi * 30 / (2000.0 * 110.0), 1e-15);
  EXPECT_NEAR(wheelAngleToTicks(2 * kPi, p), 7333.333333, 1e-6);
  // 7333 whole counts fall one third of a count short of a full turn.
  EXPECT_NEAR(ticksToWheelAngle(7333, p), 2 * kPi - p.wheelRadPerTick() / 3.0, 1e-12);
  EXPECT_LT(ticksToWheelAngle(7333, p), 2 * kPi);
  EXPECT_GT(ticksToWheelAngle(7334, p), 2 * kPi);
  // Three turns are exactly 22000 counts.
  EXPECT_NEAR(ticksToWheelAngle(22000, p), 6 * kPi, 1e-12);
}

TEST(Encoders, InverseRoundTrip) {
  EncoderParams p;
  for (int64_t n :
       {int64_t(0), int64_t(1), int64_t(-1), int64_t(7333), int64_t(-123456), int64_t(1) << 40}) {
    EXPECT_NEAR(wheelAngleToTicks(ticksToWheelAngle(n, p), p), double(n),
                1e-9 * std::max(1.0, std::abs(double(n))));
  }
  for (double psi : {0.0, 0.3, -2.5, 100.0}) {
    EXPECT_NEAR(ticksToWheelAngle(0, p) + wheelAngleToTicks(psi, p) * p.wheelRadPerTick(), psi,
                1e-12);
  }
  // Not rounded: half a count is half a count.
  EXPECT_NEAR(wheelAngleToTicks(0.5 * p.wheelRadPerTick(), p), 0.5, 1e-12);
  // A different pulley ratio changes the scale (the paper's injected encoder fault).
  EncoderParams q = p;
  q.encoder_pulley_teeth = 33;
  EXPECT_NEAR(ticksToWheelAngle(1000, q) / ticksToWheelAngle(1000, p), 1.1, 1e-12);
}

TEST(Encoders, HardwareCounterWraps) {
  const int64_t max32 = std::numeric_limits<int32_t>::max();
  EXPECT_EQ(toHardwareCounter(5), 5);
  EXPECT_EQ(toHardwareCounter(-5), -5);
  EXPECT_EQ(toHardwareCounter(max32), std::numeric_limits<int32_t>::max());
  EXPECT_EQ(toHardwareCounter(max32 + 1), std::numeric_limits<int32_t>::min());
  EXPECT_EQ(toHardwareCounter(max32 + 50), std::numeric_limits<int32_t>::min() + 49);
  EXPECT_EQ(toHardwareCounter(-max32 - 2), std::numeric_limits<int32_t>::max());
  EXPECT_EQ(toHardwareCounter((int64_t(1) << 32) + 7), 7);
}

TEST(Encoders, UnwrapHandComputed) {
  TickUnwrapper u;
  EXPECT_FALSE(u.initialized());
  EXPECT_EQ(u.unwrap(2147483600), 2147483600);
  EXPECT_EQ(u.unwrap(2147483647), 2147483647);
  // -2147483600 - 2147483647 = 49 (mod 2^32): 49 more counts forward.
  EXPECT_EQ(u.unwrap(-2147483600), int64_t(2147483647) + 49);
  EXPECT_EQ(u.wraps(), 1);
  // And back again.
  EXPECT_EQ(u.unwrap(2147483640), int64_t(2147483640));
  EXPECT_EQ(u.wraps(), 0);
  u.reset();
  EXPECT_FALSE(u.initialized());
  EXPECT_EQ(u.unwrap(-17), -17);  // first reading after reset taken as-is
  EXPECT_EQ(u.unwrap(-20), -20);
}

TEST(Encoders, UnwrapForwardAcrossWrap) {
  const int64_t start = int64_t(std::numeric_limits<int32_t>::max()) - 1000;
  TickUnwrapper u;
  int64_t truth = start;
  bool saw_negative_raw = false;
  for (int k = 0; k < 200; ++k) {
    const int32_t raw = toHardwareCounter(truth);
    saw_negative_raw |= raw < 0;
    ASSERT_EQ(u.unwrap(raw), truth) << "sample " << k;
    truth += 37 + (k % 5);  // rolling forward, uneven steps
  }
  EXPECT_TRUE(saw_negative_raw);  // the raw counter really wrapped
  EXPECT_EQ(u.wraps(), 1);
  EXPECT_GT(u.count(), int64_t(std::numeric_limits<int32_t>::max()));
}

TEST(Encoders, UnwrapBackwardAcrossWrap) {
  const int64_t start = int64_t(std::numeric_limits<int32_t>::min()) + 500;
  TickUnwrapper u;
  int64_t truth = start;
  bool saw_positive_raw = false;
  for (int k = 0; k < 200; ++k) {
    const int32_t raw = toHardwareCounter(truth);
    saw_positive_raw |= raw > 0;
    ASSERT_EQ(u.unwrap(raw), truth) << "sample " << k;
    truth -= 23 + (k % 3);  // rolling backward
  }
  EXPECT_TRUE(saw_positive_raw);
  EXPECT_EQ(u.wraps(), -1);
  EXPECT_LT(u.count(), int64_t(std::numeric_limits<int32_t>::min()));
}

namespace {
// Cumulative counts of a wheel whose rim speed is u(t) = u0 + a t (psi(0) = 0), quantised down
// like a counter (floor), through the 32-bit hardware counter starting at offset.
int32_t countsAt(double t, double u0, double a, double r, const EncoderParams& p, int64_t offset) {
  const double psi = (u0 * t + 0.5 * a * t * t) / r;
  return toHardwareCounter(offset + int64_t(std::floor(wheelAngleToTicks(psi, p))));
}

std::vector<double> unevenTimes(int n) {
  std::vector<double> t{0.0};
  for (int k = 1; k < n; ++k) t.push_back(t.back() + 0.02 + 0.04 * std::abs(std::sin(1.7 * k)));
  return t;
}
}  // namespace

TEST(Encoders, CountsIncreaseWhenRollingForward) {
  EncoderParams p;
  const double r = 0.17, lw = 0.55;
  EXPECT_GT(wheelAngleToTicks(0.1, p), 0);
  std::vector<io::EncoderSample> enc;
  for (int k = 0; k <= 10; ++k) {
    const double t = 0.02 * k;
    enc.push_back({t, countsAt(t, 0.5, 0, r, p, 0), countsAt(t, 0.5, 0, r, p, 0)});
  }
  for (std::size_t k = 1; k < enc.size(); ++k) {
    EXPECT_GE(enc[k].right_ticks, enc[k - 1].right_ticks);
  }
  EXPECT_GT(enc.back().right_ticks, enc.front().right_ticks);
  const auto iv = wheelSpeedsFromTicks(enc, p, r, lw);
  ASSERT_EQ(iv.size(), 10u);
  for (const auto& s : iv) {
    EXPECT_GT(s.u_right_m_s, 0);
    EXPECT_GT(s.v_m_s, 0);
  }
}

// The interval value is the closed-form MEAN speed over [t0, t1], not the speed at t1.
TEST(Encoders, ConstantAccelerationUnevenSamplingGivesIntervalMean) {
  const double r = 0.17, lw = 0.55;
  const double u0R = 0.2, aR = 1.5, u0L = 0.1, aL = 0.9;  // right faster: turning left
  const std::vector<double> t = unevenTimes(60);

  for (int variant = 0; variant < 2; ++variant) {
    EncoderParams p;
    if (variant == 1) p.counts_per_rev = 2000000;  // fine resolution: quantisation negligible
    const double m_per_tick = r * p.wheelRadPerTick();
    // Start near the wrap so the speeds are computed across it.
    const int64_t off = int64_t(std::numeric_limits<int32_t>::max()) - 3000;
    std::vector<io::EncoderSample> enc;
    for (double tk : t) {
      enc.push_back({tk, countsAt(tk, u0R, aR, r, p, off), countsAt(tk, u0L, aL, r, p, -off)});
    }
    WheelSpeedStats st;
    const auto iv = wheelSpeedsFromTicks(enc, p, r, lw, &st);
    ASSERT_EQ(iv.size(), t.size() - 1);
    EXPECT_EQ(st.intervals, iv.size());
    EXPECT_EQ(st.skipped_nonpositive_dt, 0u);
    int end_speed_would_fail = 0;
    for (std::size_t k = 0; k < iv.size(); ++k) {
      const auto& s = iv[k];
      EXPECT_DOUBLE_EQ(s.t0_s, t[k]);
      EXPECT_DOUBLE_EQ(s.t1_s, t[k + 1]);
      const double dt = s.t1_s - s.t0_s;
      const double meanR = u0R + aR * s.tMid();  // (1/dt) * integral of u = u(t_mid) for linear u
      const double meanL = u0L + aL * s.tMid();
      const double tol = m_per_tick / dt + 1e-12;  // floor quantisation: < 1 count per interval
      EXPECT_NEAR(s.u_right_m_s, meanR, tol) << "interval " << k;
      EXPECT_NEAR(s.u_left_m_s, meanL, tol) << "interval " << k;
      EXPECT_NEAR(s.v_m_s, 0.5 * (s.u_right_m_s + s.u_left_m_s), 1e-12);
      EXPECT_NEAR(s.omega_rad_s, (s.u_right_m_s - s.u_left_m_s) / lw, 1e-12);
      EXPECT_GT(s.omega_rad_s, 0);  // right wheel faster: turning left
      const double endR = u0R + aR * s.t1_s;
      if (std::abs(endR - meanR) > tol) ++end_speed_would_fail;
    }
    // The test discriminates: the end speed differs from the measurement by a dt / 2 >> tol.
    EXPECT_EQ(end_speed_would_fail, int(iv.size())) << "variant " << variant;
  }
}

TEST(Encoders, StraightTurningAndReverseSigns) {
  EncoderParams p;
  const double r = 0.17, lw = 0.55;
  auto run = [&](double uR, double uL) {
    std::vector<io::EncoderSample> enc;
    for (double tk : unevenTimes(20))
      enc.push_back({tk, countsAt(tk, uR, 0, r, p, 100), countsAt(tk, uL, 0, r, p, -100)});
    return wheelSpeedsFromTicks(enc, p, model::Geometry{}).back();
  };
  const auto straight = run(0.5, 0.5);
  EXPECT_NEAR(straight.v_m_s, 0.5, 0.01);
  EXPECT_NEAR(straight.omega_rad_s, 0.0, 1e-12);  // identical counts
  const auto left = run(0.6, 0.4);
  EXPECT_GT(left.omega_rad_s, 0);
  EXPECT_NEAR(left.omega_rad_s, 0.2 / lw, 0.05);
  EXPECT_NEAR(left.v_m_s, 0.5, 0.01);
  const auto right = run(0.4, 0.6);
  EXPECT_LT(right.omega_rad_s, 0);
  const auto spin = run(0.3, -0.3);  // on the spot, counter-clockwise
  EXPECT_NEAR(spin.v_m_s, 0.0, 0.01);
  EXPECT_NEAR(spin.omega_rad_s, 0.6 / lw, 0.05);
  const auto back = run(-0.4, -0.4);
  EXPECT_NEAR(back.v_m_s, -0.4, 0.01);
}

TEST(Encoders, SkipsAndCountsNonPositiveDt) {
  EncoderParams p;
  const double r = 0.17, lw = 0.55;
  const double m_per_tick = r * p.wheelRadPerTick();
  // 100 counts per 0.02 s, then a duplicate time stamp and an out-of-order sample.
  std::vector<io::EncoderSample> enc = {
      {0.00, 0, 0}, {0.02, 100, 50}, {0.02, 105, 52}, {0.01, 60, 30}, {0.04, 200, 100}};
  WheelSpeedStats st;
  const auto iv = wheelSpeedsFromTicks(enc, p, r, lw, &st);
  ASSERT_EQ(iv.size(), 2u);
  EXPECT_EQ(st.skipped_nonpositive_dt, 2u);
  EXPECT_EQ(st.intervals, 2u);
  EXPECT_DOUBLE_EQ(iv[0].t0_s, 0.00);
  EXPECT_DOUBLE_EQ(iv[0].t1_s, 0.02);
  EXPECT_DOUBLE_EQ(iv[1].t0_s, 0.02);  // from the last accepted sample
  EXPECT_DOUBLE_EQ(iv[1].t1_s, 0.04);
  EXPECT_NEAR(iv[0].u_right_m_s, 100 * m_per_tick / 0.02, 1e-12);
  EXPECT_NEAR(iv[1].u_right_m_s, 100 * m_per_tick / 0.02, 1e-12);
  EXPECT_NEAR(iv[1].u_left_m_s, 50 * m_per_tick / 0.02, 1e-12);
  EXPECT_NEAR(iv[1].tMid(), 0.03, 1e-15);

  EXPECT_TRUE(wheelSpeedsFromTicks({}, p, r, lw).empty());
  EXPECT_TRUE(wheelSpeedsFromTicks({{0.0, 1, 1}}, p, r, lw).empty());
}

TEST(Encoders, UnwrapTicksPerSample) {
  const int32_t hi = std::numeric_limits<int32_t>::max();
  std::vector<io::EncoderSample> enc = {{0.0, hi - 1, 0},
                                        {0.1, toHardwareCounter(int64_t(hi) + 9), -5}};
  const auto u = unwrapTicks(enc);
  ASSERT_EQ(u.right.size(), 2u);
  EXPECT_EQ(u.right[1], int64_t(hi) + 9);
  EXPECT_EQ(u.left[1], -5);
  EXPECT_DOUBLE_EQ(u.t_s[1], 0.1);
}
