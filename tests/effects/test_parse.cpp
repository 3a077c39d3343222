// Effect specification parsing and validation (the catalogue is a contract).
#include "libwheelchair/effects/Effect.h"

#include <gtest/gtest.h>

#include <set>

using namespace wheelchair;

TEST(EffectParse, IdAndParams) {
  const effects::EffectSpec e =
      effects::parseEffect("motor_asymmetry:side=right,friction_ratio=1.3");
  EXPECT_EQ(e.id, "motor_asymmetry");
  ASSERT_EQ(e.params.size(), 2u);
  EXPECT_EQ(e.params.at("side"), "right");
  EXPECT_DOUBLE_EQ(e.number("friction_ratio"), 1.3);
  EXPECT_DOUBLE_EQ(e.number("km_ratio"), 1.0);  // catalogue default
  EXPECT_NO_THROW(effects::validateEffect(e));
  EXPECT_EQ(effects::parseEffect(effects::formatEffect(e)), e);
  EXPECT_EQ(effects::parseEffect(" gyro_bias : bias_rad_s = 0.01 ").number("bias_rad_s"), 0.01);
}

TEST(EffectParse, Errors) {
  EXPECT_THROW(effects::parseEffect(""), std::invalid_argument);
  EXPECT_THROW(effects::parseEffect("gyro_bias:bias_rad_s"), std::invalid_argument);
  EXPECT_THROW(effects::parseEffect("gyro_bias:a=1,a=2"), std::invalid_argument);
  EXPECT_THROW(effects::parseValidEffect("warp_drive:x=1"), std::invalid_argument);
  EXPECT_THROW(effects::parseValidEffect("gyro_bias:bias=0.1"),
               std::invalid_argument);                                          // unknown key
  EXPECT_THROW(effects::parseValidEffect("gyro_bias"), std::invalid_argument);  // required
  EXPECT_THROW(effects::parseValidEffect("gyro_scale:scale=abc"),
               std::invalid_argument);  // not a number
  EXPECT_THROW(effects::parseValidEffect("encoder_scale:side=middle,scale=1"),
               std::invalid_argument);
  EXPECT_THROW(effects::parseValidEffect("encoder_scale:side=left,scale=-1"),
               std::invalid_argument);
  EXPECT_THROW(effects::parseValidEffect("sonar_dropout:probability=1"), std::invalid_argument);
  EXPECT_THROW(effects::parseValidEffect("actuator_lag"), std::invalid_argument);
  EXPECT_NO_THROW(effects::parseValidEffect("actuator_lag:delay_s=0.2"));
  EXPECT_NO_THROW(effects::parseValidEffect("sensor_delay:sensor=imu,delay_s=0.05"));
  EXPECT_THROW(effects::parseValidEffect("sensor_delay:sensor=radar,delay_s=0.05"),
               std::invalid_argument);
}

TEST(EffectParse, CatalogueContract) {
  // The ids and parameter names the diagnosis tool relies on.
  const std::map<std::string, std::set<std::string>> contract = {
      {"motor_asymmetry", {"side", "friction_ratio"}},
      {"encoder_scale", {"side", "scale"}},
      {"gyro_bias", {"bias_rad_s"}},
      {"gyro_scale", {"scale"}},
      {"coulomb_friction", {"current_A"}},
      {"ground_slope", {"angle_deg", "downhill_heading_deg"}},
      {"sensor_delay", {"sensor", "delay_s"}},
      {"payload_mass", {"body_mass_kg"}},
      {"actuator_lag", {"delay_s", "time_constant_s"}},
      {"sonar_dropout", {"probability"}},
      {"pozyx_outliers", {"rate"}},
  };
  for (const auto& [id, keys] : contract) {
    const effects::Effect* effect = effects::findEffect(id);
    ASSERT_NE(effect, nullptr) << id;
    std::set<std::string> have;
    for (const auto& p : effect->info().params) have.insert(p.name);
    for (const auto& k : keys) EXPECT_TRUE(have.count(k)) << id << "." << k;
  }
}
