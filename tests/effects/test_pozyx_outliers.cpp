#include "EffectTestUtil.h"

namespace wheelchair::effects::test {

TEST(PozyxOutliersEffect, DisplacesTheExpectedShareOfFixes) {
  const auto clean = drive({});
  const auto with = drive({"pozyx_outliers:rate=0.2,magnitude_m=2"});
  ASSERT_EQ(clean.pozyx.size(), with.pozyx.size());
  int moved = 0;
  for (std::size_t i = 0; i < clean.pozyx.size(); ++i) {
    const double d =
        std::hypot(with.pozyx[i].x_m - clean.pozyx[i].x_m, with.pozyx[i].y_m - clean.pozyx[i].y_m);
    if (d > 0) {
      ++moved;
      EXPECT_GE(d, 0.99) << i;  // 2 m x U(0.5, 1.5)
      EXPECT_LE(d, 3.01) << i;
    }
  }
  EXPECT_NEAR(double(moved) / clean.pozyx.size(), 0.2, 0.07);
  EXPECT_EQ(findEffect("pozyx_outliers")->correctionPhase(), CorrectionPhase::none);
}

}  // namespace wheelchair::effects::test
