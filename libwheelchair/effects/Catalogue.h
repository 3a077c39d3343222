// The effects of the catalogue, one file each (docs/effects.md); effectRegistry() lists them.
#pragma once

#include "libwheelchair/effects/Effect.h"

namespace wheelchair::effects {

const Effect& gyroBiasEffect();         ///< GyroBias.cpp
const Effect& gyroScaleEffect();        ///< GyroScale.cpp
const Effect& encoderScaleEffect();     ///< EncoderScale.cpp
const Effect& motorAsymmetryEffect();   ///< MotorAsymmetry.cpp
const Effect& coulombFrictionEffect();  ///< CoulombFriction.cpp
const Effect& payloadMassEffect();      ///< PayloadMass.cpp
const Effect& groundSlopeEffect();      ///< GroundSlope.cpp
const Effect& sensorDelayEffect();      ///< SensorDelay.cpp
const Effect& actuatorLagEffect();      ///< ActuatorLag.cpp
const Effect& sonarDropoutEffect();     ///< SonarDropout.cpp
const Effect& pozyxOutliersEffect();    ///< PozyxOutliers.cpp

/// A term's single-coefficient selection of one column.
inline std::vector<std::vector<std::string>> oneColumn(const std::string& name) {
  return {{name}};
}

/// A term with one coefficient on the column of its own name.
inline ResidualTerm oneColumnTerm(
    const std::string& name, Stage stage, std::function<bool(const Eigen::VectorXd&)> plausible,
    std::function<double(const EffectSpec&, const config::WheelchairConfig&)> coefficient) {
  ResidualTerm t;
  t.name = name;
  t.stage = stage;
  t.coefficients = oneColumn(name);
  t.plausible = std::move(plausible);
  t.coefficientOf = [coefficient](const EffectSpec& e, const config::WheelchairConfig& c) {
    return Eigen::VectorXd::Constant(1, coefficient(e, c));
  };
  return t;
}

/// The terms `prefix/right` and `prefix/left` of a sided effect (parameter `side`): one
/// coefficient each, coefficient(e) on the sides the spec names and 0 on the other.
inline std::vector<ResidualTerm> sidedTerms(const std::string& prefix, Stage stage,
                                            std::function<bool(const Eigen::VectorXd&)> plausible,
                                            std::function<double(const EffectSpec&)> coefficient) {
  std::vector<ResidualTerm> out;
  for (int side = 0; side < 2; ++side)
    out.push_back(
        oneColumnTerm(prefix + "/" + sideChoices()[side], stage, plausible,
                      [side, coefficient](const EffectSpec& e, const config::WheelchairConfig&) {
                        for (int s : effectSides(e))
                          if (s == side) return coefficient(e);
                        return 0.0;
                      }));
  return out;
}

}  // namespace wheelchair::effects
