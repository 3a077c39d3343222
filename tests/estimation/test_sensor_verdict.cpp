// sensorConsistency / sensorVerdict (estimation/SensorVerdict.h): the thresholds are the
// chi-square statistics (mean-NIS band, Poisson tail of the gate rejections), checked here
// against values computed by hand.
#include "libwheelchair/estimation/SensorVerdict.h"

#include <gtest/gtest.h>

namespace wheelchair::estimation {
namespace {

SensorStats stats(long used, long rejected, double mean_nis, int dof) {
  SensorStats st;
  st.used = used;
  st.rejected = rejected;
  st.nis_count = used;
  st.nis_sum = mean_nis * double(used);
  st.dof = dof;
  return st;
}

TEST(SensorVerdict, RejectionTailIsPoisson) {
  // lambda = 2000 * 0.001 = 2: P(X >= 5) = 1 - e^-2 (1 + 2 + 2 + 4/3 + 2/3) = 0.0527,
  // P(X >= 6) = 0.0166.
  EXPECT_NEAR(rejectionPValue(stats(1995, 5, 1.0, 1), 0.999), 0.0527, 5e-4);
  EXPECT_NEAR(rejectionPValue(stats(1994, 6, 1.0, 1), 0.999), 0.0166, 5e-4);
  EXPECT_EQ(sensorConsistency(stats(1995, 5, 1.0, 1), 0.999), SensorConsistency::Consistent);
  EXPECT_EQ(sensorConsistency(stats(1994, 6, 1.0, 1), 0.999), SensorConsistency::Inconsistent);
  EXPECT_EQ(rejectionPValue(stats(1000, 0, 1.0, 1), 0.999), 1.0);
}

TEST(SensorVerdict, MeanNisAgainstItsBand) {
  // 1000 chi2(2): band of the mean ~ 2 +- 1.96 * sqrt(4 / 1000) = 1.88..2.12.
  EXPECT_EQ(sensorConsistency(stats(1000, 0, 2.0, 2), 0.999), SensorConsistency::Consistent);
  EXPECT_EQ(sensorConsistency(stats(1000, 0, 2.2, 2), 0.999), SensorConsistency::Inconsistent);
  EXPECT_EQ(sensorConsistency(stats(1000, 0, 1.8, 2), 0.999),
            SensorConsistency::NoiseOverestimated);
  EXPECT_EQ(sensorConsistency(SensorStats{}, 0.999), SensorConsistency::NotUsed);
}

TEST(SensorVerdict, LineNamesSensorShareAndCause) {
  const auto v = sensorVerdict(Sensor::Encoders, stats(1042, 1107, 2.0, 2), 0.999);
  EXPECT_EQ(v.rfind("encoders: 52 % of updates rejected (1107 of 2149; 0.1 % expected", 0), 0u)
      << v;
  EXPECT_NE(v.find("inconsistent"), std::string::npos) << v;
  const auto g = sensorVerdict(Sensor::Gyro, stats(4300, 0, 1.0, 1), 0.999);
  EXPECT_EQ(g.rfind("gyro: consistent (NIS mean 1.00, expected 0.96..1.04; 0 % rejected)", 0), 0u)
      << g;
}

}  // namespace
}  // namespace wheelchair::estimation
