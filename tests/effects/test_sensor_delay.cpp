#include "EffectTestUtil.h"

namespace wheelchair::effects::test {

TEST(SensorDelayEffect, InverseRestoresTheStamps) {
  const auto clean = drive({});
  for (const std::string sensor : {"imu", "motors", "encoders"}) {
    const std::string text = "sensor_delay:sensor=" + sensor + ",delay_s=0.05";
    const auto with = drive({text});
    const auto fixed = corrected(with, text);
    auto stamps = [&](const io::Recording& r) {
      std::vector<double> t;
      if (sensor == "imu")
        for (auto& s : r.imu) t.push_back(s.t_s);
      if (sensor == "motors")
        for (auto& s : r.motors) t.push_back(s.t_s);
      if (sensor == "encoders")
        for (auto& s : r.encoders) t.push_back(s.t_s);
      return t;
    };
    const auto tc = stamps(clean), tw = stamps(with), tf = stamps(fixed);
    ASSERT_EQ(tc.size(), tf.size());
    for (std::size_t i = 0; i < tc.size(); ++i) {
      EXPECT_NEAR(tw[i] - tc[i], 0.05, 1e-9);
      EXPECT_NEAR(tf[i], tc[i], 1e-9);
    }
  }
}

TEST(SensorDelayEffect, ResidualColumnsMatchFiniteDifference) {
  const TermCheck k =
      kinematicTermCheck("sensor_delay:sensor=imu,delay_s=0.01", "sensor_delay/imu");
  EXPECT_GT(k.change_rms, 1e-4);
  EXPECT_LT(k.relative_error, 0.35);
  const TermCheck d =
      driveTermCheck("sensor_delay:sensor=motors,delay_s=0.02", "sensor_delay/motors");
  EXPECT_GT(d.change_rms, 0.01);
  EXPECT_LT(d.relative_error, 0.35);
}

}  // namespace wheelchair::effects::test
