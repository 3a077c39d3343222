#include "libwheelchair/io/Samples.h"

#include <array>
#include <limits>

namespace wheelchair::io {

const char* streamLabel(StreamKind k) {
  static constexpr const char* kLabels[kNumStreams] = {
      "ENCODERS", "IMU", "MOTORS", "SONAR", "POZYX", "JOYSTICK", "GROUND_TRUTH", "LANDMARKS"};
  return kLabels[static_cast<int>(k)];
}

const char* streamFileName(StreamKind k) {
  static constexpr const char* kFiles[kNumStreams] = {
      "encoders.csv", "imu.csv",      "motors.csv",       "sonar.csv",
      "pozyx.csv",    "joystick.csv", "groundtruth.csv", "landmarks.csv"};
  return kFiles[static_cast<int>(k)];
}

void append(Recording& rec, AnySample s) {
  std::visit(
      [&](auto&& x) {
        using T = std::decay_t<decltype(x)>;
        if constexpr (std::is_same_v<T, EncoderSample>) rec.encoders.push_back(x);
        if constexpr (std::is_same_v<T, ImuSample>) rec.imu.push_back(x);
        if constexpr (std::is_same_v<T, MotorSample>) rec.motors.push_back(x);
        if constexpr (std::is_same_v<T, SonarSample>) rec.sonar.push_back(x);
        if constexpr (std::is_same_v<T, PozyxSample>) rec.pozyx.push_back(x);
        if constexpr (std::is_same_v<T, JoystickSample>) rec.joystick.push_back(x);
        if constexpr (std::is_same_v<T, GroundTruthPoseSample>) rec.ground_truth.push_back(x);
        if constexpr (std::is_same_v<T, LandmarkSample>) rec.landmarks.push_back(x);
      },
      std::move(s));
}

void forEachInTimeOrder(const Recording& rec, const std::function<void(const AnySample&)>& f) {
  std::array<std::size_t, kNumStreams> next{};
  const std::array<std::size_t, kNumStreams> sizes = {
      rec.encoders.size(), rec.imu.size(),      rec.motors.size(),       rec.sonar.size(),
      rec.pozyx.size(),    rec.joystick.size(), rec.ground_truth.size(), rec.landmarks.size()};
  auto at = [&](int k, std::size_t i) -> AnySample {
    switch (static_cast<StreamKind>(k)) {
      case StreamKind::Encoders: return rec.encoders[i];
      case StreamKind::Imu: return rec.imu[i];
      case StreamKind::Motors: return rec.motors[i];
      case StreamKind::Sonar: return rec.sonar[i];
      case StreamKind::Pozyx: return rec.pozyx[i];
      case StreamKind::Joystick: return rec.joystick[i];
      case StreamKind::GroundTruth: return rec.ground_truth[i];
      case StreamKind::Landmarks: return rec.landmarks[i];
    }
    return rec.encoders[i];
  };
  auto timeAt = [&](int k, std::size_t i) { return timeOf(at(k, i)); };
  for (;;) {
    int best = -1;
    double best_t = std::numeric_limits<double>::infinity();
    for (int k = 0; k < kNumStreams; ++k) {
      if (next[k] >= sizes[k]) continue;
      const double t = timeAt(k, next[k]);
      if (best < 0 || t < best_t) {
        best = k;
        best_t = t;
      }
    }
    if (best < 0) return;
    f(at(best, next[best]++));
  }
}

}  // namespace wheelchair::io
