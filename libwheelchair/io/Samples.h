// One sample of any stream, for code that handles all streams alike (streaming import and
// export, merging in time order). See Recording.h for the per-stream structs and units.
#pragma once

#include "libwheelchair/io/Recording.h"

#include <functional>
#include <string>
#include <variant>

namespace wheelchair::io {

/// The streams, in the fixed priority order used to break timestamp ties when merging.
enum class StreamKind { Encoders, Imu, Motors, Sonar, Pozyx, Joystick, GroundTruth, Landmarks };
constexpr int kNumStreams = 8;

using AnySample = std::variant<EncoderSample, ImuSample, MotorSample, SonarSample, PozyxSample,
                               JoystickSample, GroundTruthPoseSample, LandmarkSample>;

inline StreamKind kindOf(const AnySample& s) { return static_cast<StreamKind>(s.index()); }
inline double timeOf(const AnySample& s) {
  return std::visit([](const auto& x) { return x.t_s; }, s);
}

/// Rawlog sensorLabel of each stream (ENCODERS, IMU, MOTORS, SONAR, POZYX, JOYSTICK,
/// GROUND_TRUTH, LANDMARKS) and the plain-text file name (encoders.csv, ...).
const char* streamLabel(StreamKind k);
const char* streamFileName(StreamKind k);

/// Appends a sample to the matching vector of a recording.
void append(Recording& rec, AnySample s);

/// Calls f(AnySample) for every sample of `rec`, merged over streams in time order (file
/// order kept within a stream; ties broken by StreamKind order).
void forEachInTimeOrder(const Recording& rec, const std::function<void(const AnySample&)>& f);

}  // namespace wheelchair::io
