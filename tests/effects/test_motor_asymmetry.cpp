#include "EffectTestUtil.h"

namespace wheelchair::effects::test {

TEST(MotorAsymmetryEffect, InverseRemovesTheExtraCurrent) {
  const auto clean = drive({});
  const auto with = drive({"motor_asymmetry:side=right,friction_ratio=1.3"});
  const auto fixed = corrected(with, "motor_asymmetry:side=right,friction_ratio=1.3");
  const double before = rmsDiff(currents(with, 0), currents(clean, 0));
  const double after = rmsDiff(currents(fixed, 0), currents(clean, 0));
  EXPECT_GT(before, 0.2);           // A: the right drive needs more current
  EXPECT_LT(after, 0.25 * before);  // the inverse takes most of it out
  EXPECT_EQ(currents(fixed, 1), currents(with, 1));
}

TEST(MotorAsymmetryEffect, ResidualColumnsMatchFiniteDifference) {
  for (const std::string side : {"right", "left"}) {
    const TermCheck c = driveTermCheck("motor_asymmetry:side=" + side + ",friction_ratio=1.1",
                                       "motor_asymmetry/" + side);
    EXPECT_GT(c.change_rms, 0.02) << side;
    EXPECT_LT(c.relative_error, 0.3) << side;
  }
}

}  // namespace wheelchair::effects::test
