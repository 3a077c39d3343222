#include "EffectTestUtil.h"

namespace wheelchair::effects::test {

TEST(CoulombFrictionEffect, InverseRemovesTheDryFrictionCurrent) {
  const auto clean = drive({});
  const auto with = drive({"coulomb_friction:current_A=0.6"});
  const auto fixed = corrected(with, "coulomb_friction:current_A=0.6");
  for (int side = 0; side < 2; ++side) {
    const double before = rmsDiff(currents(with, side), currents(clean, side));
    const double after = rmsDiff(currents(fixed, side), currents(clean, side));
    EXPECT_GT(before, 0.3) << side;
    EXPECT_LT(after, 0.35 * before) << side;
  }
}

TEST(CoulombFrictionEffect, ResidualColumnsMatchFiniteDifference) {
  for (const std::string side : {"both", "right", "left"}) {
    const TermCheck c =
        driveTermCheck("coulomb_friction:current_A=0.2,side=" + side, "coulomb_friction/" + side);
    EXPECT_GT(c.change_rms, 0.05) << side;
    EXPECT_LT(c.relative_error, 0.35) << side;
  }
}

}  // namespace wheelchair::effects::test
