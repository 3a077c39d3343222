// Everything the figures and the 3-D viewer show about one recording: the recording, the
// trajectory variants of Fig. 5 (evaluation::estimateVariants), the ground truth, their
// metrics, and the simulator's truth when a `<rawlog>.truth.json` sits next to the file.
//
// Frames: all plotted poses are in the START frame of the estimates (body frame at the first
// encoder sample). The ground truth is brought into it by
//   * the simulator's known Pozyx anchor frame (truth JSON), when available, else
//   * the inverse of the SE(2) least-squares alignment of the EKF to the ground truth
//     (evaluation::computeMetrics with Alignment::SE2) — "aligned to the EKF".
//
// Example:
//   DriveData d = loadDrive("drive.rawlog", cfg, metric_options);
//   const auto& ekf = d.trajectories.at("ekf");
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/evaluation/Batch.h"
#include "libwheelchair/io/RawlogStream.h"
#include "libwheelchair/io/Recording.h"

#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace wheelchair::visualization {

/// The simulator's truth (subset of SimulationResult::writeTruth's JSON).
struct TruthInfo {
  std::vector<double> t_s, x_m, y_m, phi_rad, v_m_s, omega_rad_s;  ///< start frame
  struct Obstacle {
    double x_m = 0, y_m = 0, radius_m = 0.05;  ///< start frame
  };
  std::vector<Obstacle> obstacles;
  double anchor_x_m = 0, anchor_y_m = 0, anchor_yaw_rad = 0;  ///< p_anchor = R p_start + t
  std::string scenario, effects;
  /// True pose at t (linear interpolation, clamped at the ends); false when empty.
  bool poseAt(double t, double& x, double& y, double& phi) const;
};

/// Reads a truth JSON (format libwheelchair-truth-1); nullopt when the file does not exist,
/// throws std::runtime_error when it exists but cannot be parsed.
std::optional<TruthInfo> readTruthJson(const std::string& path);

/// One EKF estimate as the figures draw it (Fig. 6a, 6b, 8 and the default Fig. 7 time): 48 B
/// instead of the ~0.5 kB estimate with its covariance.
struct EkfTracePoint {
  double t_s = 0;
  double v_m_s = 0, omega_rad_s = 0;   ///< x(0), x(1) of the estimate
  bool obstacle = false;               ///< obstacle estimate initialised
  double range_m = 0, range_sd_m = 0;  ///< predictedSonarRange (when `obstacle`), m
};

/// What the figures draw of the recording's gyro (Fig. 6b) and motor currents (Fig. 6c), and
/// how many samples of each stream it has (index.md): a 64 B IMU sample becomes 16 B.
struct GyroPoint {
  double t_s = 0, gyro_z_rad_s = 0;
};
struct CurrentPoint {
  double t_s = 0, current_right_A = 0, current_left_A = 0;
};
/// Speeds of a dead reckoning (Fig. 6a, 6b and the shaded phases): 24 B of its 48 B sample.
struct SpeedPoint {
  double t_s = 0, v_m_s = 0, omega_rad_s = 0;
};
/// Motion phase of a speed sample (report's shaded phases): 2 turning (|omega| >= 0.2 rad/s),
/// 1 driving straight (|v| > 0.08 m/s), 0 standing.
int motionKind(const SpeedPoint& s);
struct SampleCounts {
  std::size_t encoders = 0, imu = 0, motors = 0, sonar = 0, pozyx = 0, ground_truth = 0;
};

/// What loadDrive keeps. `keep_estimates` false (`wheelchair report`; memory bounded by what the
/// figures draw, not by the filters' full output):
///   * the filters stream their estimates (evaluation::estimateVariants with sinks) into the
///     trace and the pose trajectories; of the full estimates only those at the start and at
///     `snapshot_since_start_s` (s after the first estimate, `report --at`; NaN:
///     defaultObstacleTime) are kept in `est.ekf.estimates`: ekfAt() is exact at those times;
///   * `rec` keeps only its sonar stream once the estimates, the ground truth and the figures'
///     series are made; `est.encoders` / `est.encoders_gyro` are empty once their trajectories
///     and speeds are taken;
///   * `trajectories` keep, once their metrics are computed, the points drawn
///     (pathPointsToDraw, Plot.h: every point up to Plot::kDecimateAbove).
/// The figures are the same either way.
struct DriveLoadOptions {
  bool keep_estimates = true;
  double snapshot_since_start_s = std::numeric_limits<double>::quiet_NaN();  ///< s
};

struct DriveData {
  std::string path;
  config::WheelchairConfig cfg;
  io::Recording rec;
  evaluation::RecordingEstimates est;
  std::map<std::string, evaluation::Trajectory> trajectories;  ///< per variant (computed ones)
  evaluation::GroundTruth gt;
  std::vector<evaluation::Position2DStamped> gt_start;  ///< ground truth in the start frame
  std::string gt_frame_note;                            ///< how gt_start was obtained
  std::optional<TruthInfo> truth;
  evaluation::BatchResult metrics;         ///< one row per variant
  double t0_s = 0, t1_s = 0;               ///< time span of the EKF estimates
  std::vector<EkfTracePoint> ekf_trace;    ///< every EKF estimate, as the figures draw it
  std::vector<GyroPoint> gyro;             ///< the recording's IMU yaw rate (time order as read)
  std::vector<CurrentPoint> currents;      ///< the recording's motor currents (time order as read)
  SampleCounts counts;                     ///< samples per stream of the recording
  std::vector<SpeedPoint> encoder_speeds;  ///< of est.encoders (Fig. 6a, 6b)
  /// Of est.encoders_gyro, or est.encoders without it: the drive's phases (straight, turn).
  std::vector<SpeedPoint> phase_speeds;

  /// EKF estimate at (the last sample at or before) t.
  const estimation::EstimateSample* ekfAt(double t_s) const;
};

/// Reads and estimates a recording (throws on an unreadable file). `truth_path` empty:
/// `<path>.truth.json` if it exists.
DriveData loadDrive(const std::string& path, const config::WheelchairConfig& cfg,
                    const evaluation::MetricOptions& metric_options,
                    const std::string& truth_path = "");
/// The same for a recording already in memory (`path` names it and locates the truth file).
DriveData loadDrive(io::Recording rec, const std::string& path, const config::WheelchairConfig& cfg,
                    const evaluation::MetricOptions& metric_options,
                    const std::string& truth_path = "", const DriveLoadOptions& load = {});

/// `wheelchair report`: loadDrive(io::readRawlog(path), ...) with keep_estimates false and the
/// snapshot at `snapshot_since_start_s` (NaN: the default), without loading the recording. The
/// rawlog (`sum` from io::scanRawlogSalvaging, which applied the salvage rule) is read once for
/// the gyro and current series, the sonar and the ground-truth streams, then once per variant
/// as a stream (evaluation::streamVariants); each variant is scored as soon as it has run and
/// then keeps only the points Fig. 5 draws, so at most one full trajectory is held at a time.
/// The same DriveData (figures, metrics) as the loaded path. A configuration with
/// [model_extensions] loads the recording (the corrected copy).
DriveData loadDriveStreamed(
    const std::string& path, const io::RecordingSummary& sum, const config::WheelchairConfig& cfg,
    const evaluation::MetricOptions& metric_options, const std::string& truth_path = "",
    double snapshot_since_start_s = std::numeric_limits<double>::quiet_NaN());

/// A default instant for Fig. 7 / the viewer: the middle of the first run of valid (non-zero)
/// sonar readings; without any, 40 % into the span where the EKF has an obstacle estimate.
double defaultObstacleTime(const DriveData& d);

/// Sonar range predicted by an estimate (distance from the sonar to the obstacle estimate) and
/// its 1 sigma (from the obstacle covariance); false when no obstacle estimate.
bool predictedSonarRange(const DriveData& d, const estimation::EstimateSample& e, double& r_m,
                         double& sd_m);

}  // namespace wheelchair::visualization
