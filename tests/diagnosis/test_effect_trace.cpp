// The trace of an out-of-catalogue effect (diagnosis::effectTrace, docs/discovery.md "Out of
// catalogue: traces, realised laws, where excited"): what it changes in each sensor stream's
// relation to the true motion, and the law the engine realised.
#include "libwheelchair/diagnosis/Campaign.h"
#include "libwheelchair/effects/Effect.h"
#include "libwheelchair/simulation/UnknownEffects.h"

#include <gtest/gtest.h>

using namespace wheelchair;

namespace {
nlohmann::json traceOf(const std::string& effect, const std::string& scenario, uint64_t seed,
                       const std::string& engine = "model") {
  const config::WheelchairConfig cfg;
  diagnosis::DiagnosisOptions dopt;
  dopt.loadFromConfig(cfg.ini());
  std::vector<effects::EffectSpec> fx;
  if (!effect.empty()) fx.push_back(effects::parseEffect(effect));
  return diagnosis::effectTrace(cfg, scenario, seed, 60, fx, dopt, engine);
}
double rmsRatio(const nlohmann::json& t, const char* stream) {
  return t["streams"][stream]["rms_ratio"].get<double>();
}
}  // namespace

TEST(EffectTrace, ForwardViscousDragChangesBothCurrentsAsARate) {
  const auto t = traceOf("forward_viscous_drag:c_N_s_m=8", "excite", 653027);
  EXPECT_TRUE(t["traced"].get<bool>()) << t.dump();
  EXPECT_GT(rmsRatio(t, "current_right"), 1.0);
  EXPECT_NEAR(rmsRatio(t, "current_right"), rmsRatio(t, "current_left"), 0.05);
  // A load: the gyro and the encoders keep their relation to the motion.
  EXPECT_LT(rmsRatio(t, "gyro"), 0.05);
  EXPECT_LT(rmsRatio(t, "encoder_right"), 0.05);
  ASSERT_FALSE(t["realised"].is_null());
  EXPECT_EQ(t["realised"]["channel"], "forward");
  EXPECT_EQ(t["realised"]["dependence"], "rate");
  EXPECT_GT(t["realised"]["r2"]["rate"].get<double>(), 0.95);
}

TEST(EffectTrace, CurrentOffsetChangesOneCurrentOnly) {
  const auto t = traceOf("current_offset:side=left,offset_A=0.3", "square", 264628);
  EXPECT_TRUE(t["traced"].get<bool>());
  EXPECT_NEAR(rmsRatio(t, "current_left"), 3.0, 0.1);  // 0.3 A against 0.1 A noise
  EXPECT_LT(rmsRatio(t, "current_right"), 0.02);
  EXPECT_EQ(t["strongest"], "current_left");
}

TEST(EffectTrace, NoEffectLeavesNoTrace) {
  const auto t = traceOf("", "excite", 11);
  EXPECT_FALSE(t["traced"].get<bool>()) << t.dump();
  for (const char* s : {"current_right", "current_left", "gyro", "encoder_right", "encoder_left"})
    EXPECT_LT(rmsRatio(t, s), 1e-9) << s;
}

TEST(EffectTrace, MujocoRealisedLawTellsDryFromViscous) {
  // The measurement's calibration on the same multibody: a yaw moment injected as
  // -M0 tanh(omega / 0.02) is realised as dry, -c omega as viscous.
  const auto dry = traceOf("yaw_dry_friction:torque_Nm=1.5", "excite", 505502, "mujoco");
  const auto visc = traceOf("yaw_viscous_friction:c_N_m_s_rad=4", "excite", 505502, "mujoco");
  ASSERT_FALSE(dry["realised"].is_null());
  ASSERT_FALSE(visc["realised"].is_null());
  EXPECT_EQ(dry["realised"]["channel"], "yaw");
  EXPECT_EQ(dry["realised"]["dependence"], "sign_of_rate");
  EXPECT_EQ(visc["realised"]["channel"], "yaw");
  EXPECT_EQ(visc["realised"]["dependence"], "rate");
}

TEST(EffectTrace, MujocoContactEffectsRealisedLaws) {
  // The generator's truth for MuJoCo's own contact effects is the law the multibody REALISES
  // (simulation::unknownEffectTruth), measured here: the contact laws are dry (torsional
  // friction, rolling friction, swivel friction), but MuJoCo's soft contact regularises dry
  // friction, which at these rates acts as viscous, and the castors' swivel friction acts
  // while they turn round at the start of a turn (castor_swivel: diagnosis::castorSwivelMoment
  // of the true motion; it read as acceleration before that class existed).
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"tyre_scrub:torsion_m=0.005", "yaw rate"},
      {"tyre_scrub:torsion_m=0.02", "yaw rate"},
      {"rolling_resistance:coefficient_m=0.004", "forward rate"},
      {"castor_friction:swivel_friction_Nm=1.5", "yaw castor_swivel"}};
  for (const auto& [e, law] : cases) {
    const auto t = traceOf(e, "excite", 505502, "mujoco");
    ASSERT_FALSE(t["realised"].is_null()) << e;
    EXPECT_TRUE(t["traced"].get<bool>()) << e;
    const auto& r = t["realised"];
    EXPECT_EQ(r["channel"].get<std::string>() + " " + r["dependence"].get<std::string>(), law)
        << e << " " << r.dump();
    const auto truth = simulation::unknownEffectTruth(effects::parseEffect(e));
    EXPECT_EQ(truth.channel + " " + truth.dependence, law) << e;
  }
}
