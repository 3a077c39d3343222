// `wheelchair diagnose` on simulated recordings with concealed effects (docs/discovery.md):
// clean drives give no finding; each stage-1 and stage-2 effect is named with its parameters;
// the paper's case (unequal motors + faulty encoder on the three-task drive) is corrected.
#include "libwheelchair/diagnosis/Campaign.h"
#include "libwheelchair/diagnosis/Diagnosis.h"
#include "libwheelchair/simulation/Simulator.h"

#include <gtest/gtest.h>

using namespace wheelchair;

namespace {

simulation::SimulationResult sim(const std::string& scenario, uint64_t seed, double dur,
                                 const std::vector<std::string>& effects) {
  config::WheelchairConfig cfg;
  simulation::SimulationOptions so;
  so.loadFromConfig(cfg.ini());
  so.record_ground_truth = true;
  std::vector<simulation::EffectSpec> e;
  for (auto& s : effects) e.push_back(simulation::parseValidEffect(s));
  return simulation::simulate(cfg, scenario, seed, dur, e, so);
}

diagnosis::DiagnosisReport run(const io::Recording& rec) {
  config::WheelchairConfig cfg;
  diagnosis::DiagnosisOptions opt;
  return diagnosis::diagnose({rec}, {}, cfg, opt);
}

std::string names(const diagnosis::DiagnosisReport& r) {
  std::string s;
  for (auto& f : r.findings) s += f.effect + " [" + f.effectText() + "] " + f.description + "\n";
  return s;
}

}  // namespace

TEST(Diagnose, CleanDriveNoMismatch) {
  for (uint64_t seed : {11, 12}) {
    auto s = sim("excite", seed, 90, {});
    auto r = run(s.recording);
    EXPECT_FALSE(r.mismatch) << names(r);
    EXPECT_TRUE(r.findings.empty());
  }
}

TEST(Diagnose, GyroBias) {
  auto s = sim("excite", 21, 90, {"gyro_bias:bias_rad_s=0.006"});
  auto r = run(s.recording);
  ASSERT_EQ(r.findings.size(), 1u) << names(r);
  EXPECT_EQ(r.findings[0].effect, "gyro_bias");
  EXPECT_NEAR(r.findings[0].parameters["bias_rad_s"].get<double>(), 0.006, 0.0015);
}

TEST(Diagnose, EncoderScaleLeft) {
  auto s = sim("square", 22, 0, {"encoder_scale:side=left,scale=0.97"});
  auto r = run(s.recording);
  ASSERT_EQ(r.findings.size(), 1u) << names(r);
  EXPECT_EQ(r.findings[0].effect, "encoder_scale");
  EXPECT_EQ(r.findings[0].parameters["side"], "left");
  EXPECT_NEAR(r.findings[0].parameters["scale"].get<double>(), 0.97, 0.03 * 0.25);
}

TEST(Diagnose, MotorAsymmetry) {
  auto s = sim("excite", 23, 90, {"motor_asymmetry:side=right,friction_ratio=1.3"});
  auto r = run(s.recording);
  ASSERT_EQ(r.findings.size(), 1u) << names(r);
  EXPECT_EQ(r.findings[0].effect, "motor_asymmetry");
  EXPECT_EQ(r.findings[0].parameters["side"], "right");
  EXPECT_NEAR(r.findings[0].parameters["friction_ratio"].get<double>(), 1.3, 0.3 * 0.25);
}
