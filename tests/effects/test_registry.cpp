#include "EffectTestUtil.h"

namespace wheelchair::effects::test {

TEST(EffectRegistry, EveryEffectRoundTripsThroughTextAndJson) {
  const std::vector<std::string> examples = {"gyro_bias:bias_rad_s=0.01",
                                             "gyro_scale:scale=1.02",
                                             "encoder_scale:scale=0.95,side=left",
                                             "motor_asymmetry:friction_ratio=1.3,side=right",
                                             "coulomb_friction:current_A=0.5",
                                             "payload_mass:body_mass_kg=120",
                                             "ground_slope:angle_deg=2",
                                             "sensor_delay:delay_s=0.05,sensor=imu",
                                             "actuator_lag:delay_s=0.2",
                                             "sonar_dropout:probability=0.2",
                                             "pozyx_outliers:rate=0.1"};
  ASSERT_EQ(examples.size(), effectRegistry().size());
  for (const auto& t : examples) {
    const EffectSpec e = parseValidEffect(t);
    EXPECT_EQ(formatEffect(e), t);
    EXPECT_EQ(effectFromJson(effectToJson(e)), e);
    EXPECT_EQ(findEffect(e.id)->id(), e.id);
  }
}

TEST(EffectRegistry, EveryTermNamesColumnsOfItsStage) {
  for (const Effect* e : effectRegistry())
    for (const auto& t : e->residualTerms({90, true}))
      for (const auto& coef : t.coefficients)
        for (const auto& col : coef) EXPECT_NO_THROW(diagnosis::columnIndex(t.stage, col)) << col;
}

TEST(EffectRegistry, RangesAndChoicesAreChecked) {
  EXPECT_THROW(parseValidEffect("gyro_scale:scale=0"), std::invalid_argument);
  EXPECT_THROW(parseValidEffect("encoder_scale:side=middle,scale=1"), std::invalid_argument);
  EXPECT_THROW(parseValidEffect("ground_slope:angle_deg=45"), std::invalid_argument);
  EXPECT_THROW(parseValidEffect("warp_drive"), std::invalid_argument);
}

}  // namespace wheelchair::effects::test
