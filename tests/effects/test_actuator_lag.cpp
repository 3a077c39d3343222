#include "EffectTestUtil.h"

namespace wheelchair::effects::test {

namespace {
/// First time the true speed exceeds 0.05 m/s.
double startTime(const simulation::SimulationResult& r) {
  for (const auto& s : r.truth.samples)
    if (s.v_m_s > 0.05) return s.t_s;
  return -1;
}
}  // namespace

TEST(ActuatorLagEffect, DelaysTheResponseAndHasNoInverseOnData) {
  simulation::SimulationResult clean, lag;
  drive({}, "three_task", 15, &clean);
  const auto rec = drive({"actuator_lag:delay_s=0.4"}, "three_task", 15, &lag);
  const double extra = startTime(lag) - startTime(clean);
  const double nominal_delay = simulation::SimulationOptions{}.power.delay_s;
  EXPECT_NEAR(extra, 0.4 - nominal_delay, 0.05);
  EXPECT_EQ(findEffect("actuator_lag")->correctionPhase(), CorrectionPhase::none);
  EXPECT_EQ(currents(corrected(rec, "actuator_lag:delay_s=0.4"), 0), currents(rec, 0));
  EXPECT_THROW(parseValidEffect("actuator_lag"), std::invalid_argument);
}

}  // namespace wheelchair::effects::test
