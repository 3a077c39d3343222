#include "EffectTestUtil.h"

namespace wheelchair::effects::test {

TEST(GyroBiasEffect, InverseUndoesTheForwardAction) {
  const auto clean = drive({});
  const auto with = drive({"gyro_bias:bias_rad_s=0.02"});
  const auto fixed = corrected(with, "gyro_bias:bias_rad_s=0.02");
  ASSERT_EQ(fixed.imu.size(), clean.imu.size());
  for (std::size_t i = 0; i < clean.imu.size(); ++i) {
    EXPECT_NEAR(with.imu[i].gyro_z_rad_s - clean.imu[i].gyro_z_rad_s, 0.02, 1e-12);
    EXPECT_NEAR(fixed.imu[i].gyro_z_rad_s, clean.imu[i].gyro_z_rad_s, 1e-12);
  }
  EXPECT_EQ(currents(fixed, 0), currents(with, 0));  // nothing else touched
}

TEST(GyroBiasEffect, ResidualColumnMatchesFiniteDifference) {
  const TermCheck c = kinematicTermCheck("gyro_bias:bias_rad_s=0.005", "gyro_bias");
  EXPECT_GT(c.change_rms, 5e-4);  // 0.005 rad/s over 0.2 s windows
  EXPECT_LT(c.relative_error, 1e-6);
}

}  // namespace wheelchair::effects::test
