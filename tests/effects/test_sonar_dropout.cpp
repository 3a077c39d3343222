#include "EffectTestUtil.h"

namespace wheelchair::effects::test {

TEST(SonarDropoutEffect, FailsTheExpectedShareOfEchoes) {
  const auto clean = drive({}, "three_task");
  const auto with = drive({"sonar_dropout:probability=0.3,burst_length=2"}, "three_task");
  ASSERT_EQ(clean.sonar.size(), with.sonar.size());
  int echoes = 0, lost = 0;
  for (std::size_t i = 0; i < clean.sonar.size(); ++i)
    if (clean.sonar[i].range_m > 0) {
      ++echoes;
      lost += with.sonar[i].range_m == 0;
    }
  ASSERT_GT(echoes, 30);
  EXPECT_NEAR(double(lost) / echoes, 0.3, 0.15);
  // A fault, not physics: no inverse on the data (diagnosis/SensorFaults detects it).
  EXPECT_EQ(findEffect("sonar_dropout")->correctionPhase(), CorrectionPhase::none);
  EXPECT_THROW(parseValidEffect("sonar_dropout:probability=1"), std::invalid_argument);
}

}  // namespace wheelchair::effects::test
