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

namespace wheelchair::effects::test {

TEST(EffectRegistry, EveryTermIsDescribedWithItsEffectsParameters) {
  // A finding's parameters must read back as the effect (they become [model_extensions]).
  for (const Effect* e : effectRegistry())
    for (const auto& term : e->residualTerms({nominal().vehicle.geom.body_mass_kg, true})) {
      const int k = static_cast<int>(term.coefficients.size());
      TermFit fit;
      fit.cfg = &nominal();
      fit.coef[term.name] = 0.05;
      fit.sigma[term.name] = 0.001;
      fit.delay_s = 0.02;
      const FindingText t = e->describe(term.name, Eigen::VectorXd::Constant(k, 0.05),
                                        Eigen::MatrixXd::Identity(k, k) * 1e-6, fit);
      EXPECT_FALSE(t.description.empty()) << term.name;
      EffectSpec spec{e->id(), {}};
      for (auto it = t.parameters.begin(); it != t.parameters.end(); ++it) {
        if (it.key() == "friction_ratio_right_left") continue;  // both sides, for the report
        spec.params[it.key()] =
            it->is_string() ? it->get<std::string>() : std::to_string(it->get<double>());
      }
      EXPECT_NO_THROW(validateEffect(spec)) << term.name << ": " << formatEffect(spec);
    }
}

}  // namespace wheelchair::effects::test
