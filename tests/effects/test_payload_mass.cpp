#include "EffectTestUtil.h"

namespace wheelchair::effects::test {

TEST(PayloadMassEffect, CorrectedConfigurationExplainsTheCurrents) {
  // No inverse on the data: the mass goes into [vehicle] (adjustConfig).
  const auto with = drive({"payload_mass:body_mass_kg=170"});
  EXPECT_EQ(currents(corrected(with, "payload_mass:body_mass_kg=170"), 0), currents(with, 0));
  estimation::ModelExtensions ext;
  ext.effects = {parseValidEffect("payload_mass:body_mass_kg=170")};
  const config::WheelchairConfig adj = ext.adjustConfig(nominal());
  EXPECT_DOUBLE_EQ(adj.vehicle.geom.body_mass_kg, 170);
  diagnosis::DiagnosisOptions opt;
  const auto s = diagnosis::makeStreams(with, nominal());
  const double nominal_rms = diagnosis::dynamicRows({s}, {}, nominal(), opt).y.norm();
  const double adjusted_rms = diagnosis::dynamicRows({s}, {}, adj, opt).y.norm();
  EXPECT_LT(adjusted_rms, 0.5 * nominal_rms);
}

TEST(PayloadMassEffect, ResidualColumnMatchesFiniteDifference) {
  const double m = nominal().vehicle.geom.body_mass_kg;
  const TermCheck c =
      driveTermCheck("payload_mass:body_mass_kg=" + std::to_string(m + 10), "payload_mass");
  EXPECT_GT(c.change_rms, 0.01);
  EXPECT_LT(c.relative_error, 0.35);
}

}  // namespace wheelchair::effects::test
