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

}  // namespace wheelchair::effects
