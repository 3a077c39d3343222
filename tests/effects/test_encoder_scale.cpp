#include "EffectTestUtil.h"

#include "libwheelchair/sensors/Encoders.h"

namespace wheelchair::effects::test {

TEST(EncoderScaleEffect, InverseUndoesTheForwardActionWithinOneTick) {
  const auto clean = drive({});
  const auto with = drive({"encoder_scale:side=left,scale=0.95"});
  const auto fixed = corrected(with, "encoder_scale:side=left,scale=0.95");
  const auto uc = sensors::unwrapTicks(clean.encoders), uw = sensors::unwrapTicks(with.encoders),
             uf = sensors::unwrapTicks(fixed.encoders);
  ASSERT_EQ(uc.left.size(), uf.left.size());
  const std::size_t last = uc.left.size() - 1;
  EXPECT_GT(std::abs(double(uw.left[last] - uc.left[last])), 100);  // the effect is visible
  for (std::size_t i = 0; i <= last; ++i) {
    EXPECT_LE(std::abs(double(uf.left[i] - uc.left[i])), 1.0) << i;
    EXPECT_EQ(uf.right[i], uc.right[i]);  // the other side untouched
  }
}

TEST(EncoderScaleEffect, ResidualColumnsMatchFiniteDifference) {
  for (const std::string side : {"right", "left"}) {
    const TermCheck c =
        kinematicTermCheck("encoder_scale:side=" + side + ",scale=1.03", "encoder_scale/" + side);
    EXPECT_GT(c.change_rms, 1e-4) << side;
    EXPECT_LT(c.relative_error, 0.1) << side;  // tick quantisation differs between the drives
  }
}

}  // namespace wheelchair::effects::test
