// A recording in memory: one vector of samples per sensor stream, in the units of
// ../docs/recording-format.md (SI, the vehicle.md conventions). Plain data, no MRPT types:
// the simulator produces it, the estimator and identification consume it, and io/ converts
// it to and from rawlogs and the plain-text directory format.
//
// Timestamps `t_s` are seconds on the recording's single clock (not necessarily from 0).
// Samples of one stream are kept in the order they were recorded; a healthy recording is
// time-ordered, but nothing here enforces it (see io/RecordingStats.h for the checks).
//
// Example:
//   Recording rec;
//   rec.encoders.push_back({0.02, 15, 14});
//   rec.imu.push_back({0.01, 0.001});
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace wheelchair::io {

/// Cumulative counts from the hardware counter (int32: they may wrap at 2^31).
struct EncoderSample {
  double t_s = 0;
  int32_t right_ticks = 0;
  int32_t left_ticks = 0;
};

/// Gyro z (rad/s), optionally the other IMU channels (imu.csv's optional columns).
struct ImuSample {
  double t_s = 0;
  double gyro_z_rad_s = 0;
  bool has_extra = false;
  /// gyro_x, gyro_y (rad/s), acc_x, acc_y, acc_z (m/s^2), valid when has_extra.
  std::array<double, 5> extra{};
};

/// Motor currents (A, positive driving forward) and RC-filtered lead voltages V_RC (V).
struct MotorSample {
  double t_s = 0;
  double current_right_A = 0;
  double current_left_A = 0;
  double vrc_right_V = 0;
  double vrc_left_V = 0;
};

/// Sonar range (m); 0 means no echo or a failed reading and is kept as recorded.
struct SonarSample {
  double t_s = 0;
  double range_m = 0;
};

/// Pozyx tag position in the anchor frame (m).
struct PozyxSample {
  double t_s = 0;
  double x_m = 0;
  double y_m = 0;
  bool has_z = false;
  double z_m = 0;
};

/// Joystick demand (or any velocity command): v (m/s), omega (rad/s).
struct JoystickSample {
  double t_s = 0;
  double v_cmd_m_s = 0;
  double omega_cmd_rad_s = 0;
};

/// Vicon / motion-capture pose of the body (ground truth of real datasets such as MRCLAM).
struct GroundTruthPoseSample {
  double t_s = 0;
  double x_m = 0;
  double y_m = 0;
  double phi_rad = 0;
};

/// One landmark sighting: range (m) and bearing (rad, in the body frame) to a landmark id.
struct LandmarkSample {
  double t_s = 0;
  int landmark_id = 0;
  double range_m = 0;
  double bearing_rad = 0;
};

struct Recording {
  std::vector<EncoderSample> encoders;
  std::vector<ImuSample> imu;
  std::vector<MotorSample> motors;
  std::vector<SonarSample> sonar;
  std::vector<PozyxSample> pozyx;
  std::vector<JoystickSample> joystick;
  std::vector<GroundTruthPoseSample> ground_truth;
  std::vector<LandmarkSample> landmarks;
  /// Free-form `[recording]` keys of meta.ini (operator, date, notes), kept as-is.
  std::map<std::string, std::string> meta;

  /// Earliest and latest timestamp over all streams (0, 0 when empty).
  double startTime() const;
  double endTime() const;
  std::size_t size() const;
};

}  // namespace wheelchair::io
