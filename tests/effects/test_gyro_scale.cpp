#include "EffectTestUtil.h"

namespace wheelchair::effects::test {

TEST(GyroScaleEffect, InverseUndoesTheForwardAction) {
  const auto clean = drive({});
  const auto with = drive({"gyro_scale:scale=1.05"});
  const auto fixed = corrected(with, "gyro_scale:scale=1.05");
  ASSERT_EQ(fixed.imu.size(), clean.imu.size());
  double moved = 0;
  for (std::size_t i = 0; i < clean.imu.size(); ++i) {
    moved = std::max(moved, std::abs(with.imu[i].gyro_z_rad_s - clean.imu[i].gyro_z_rad_s));
    // noise is added after the scale: the inverse leaves noise / scale
    EXPECT_NEAR(fixed.imu[i].gyro_z_rad_s, clean.imu[i].gyro_z_rad_s, 0.01);
  }
  EXPECT_GT(moved, 0.01);
}

TEST(GyroScaleEffect, ResidualColumnMatchesFiniteDifference) {
  const TermCheck c = kinematicTermCheck("gyro_scale:scale=1.01", "gyro_scale");
  EXPECT_GT(c.change_rms, 1e-4);
  EXPECT_LT(c.relative_error, 0.02);
}

}  // namespace wheelchair::effects::test
