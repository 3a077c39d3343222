// Headless report of one recording (docs/visualization.md): PNG figures like the paper's
// Fig. 5-8, a 3-D scene snapshot (offscreen OpenGL, skipped when no context can be made) and
// index.md with the metrics table, the figures and the full configuration used.
//
//   fig5_trajectories.png   trajectories of the variants + ground truth, start/end markers
//   fig6a_velocity.png      v from the encoders vs the EKF (and the true v when simulated)
//   fig6b_angular_velocity.png  omega from the gyro vs the encoders (and the EKF)
//   fig6c_motor_currents.png    motor currents right / left
//   fig7_obstacle.png       obstacle estimate + covariance ellipse in the base frame at a time
//   fig8_distance.png       estimated range +- sigma over the raw sonar (zeros visible)
//   scene3d.png             the viewer's 3-D scene at the same time (optional)
//
// Example:
//   ReportOptions o;  o.out_dir = "report";
//   ReportResult r = writeReport("drive.rawlog", cfg, o);
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/evaluation/Metrics.h"
#include "libwheelchair/visualization/DriveData.h"

#include <cmath>
#include <string>
#include <vector>

namespace wheelchair::visualization {

struct ReportOptions {
  std::string out_dir;
  double at_s = NAN;  ///< Fig. 7 / 3-D snapshot time (recording clock); NaN: defaultObstacleTime
  evaluation::MetricOptions metrics;  ///< alignment of the metrics table
  int width = 1000, height = 620;     ///< figure size (px)
  bool scene3d = true;                ///< try the offscreen 3-D snapshot
  std::string truth_path;             ///< "" = <rawlog>.truth.json when present
};

struct ReportResult {
  std::vector<std::string> figures;  ///< paths of the PNGs written
  std::string index_path;
  std::vector<std::string> notes;  ///< e.g. why the 3-D snapshot was skipped
};

/// Writes the figures and index.md into options.out_dir (created). Throws on an unreadable
/// recording or an unwritable directory.
ReportResult writeReport(const std::string& rawlog, const config::WheelchairConfig& cfg,
                         const ReportOptions& options);
/// The same from already loaded data.
ReportResult writeReport(const DriveData& d, const ReportOptions& options);

// Individual figures (for reuse and tests).
void figureTrajectories(const DriveData& d, const std::string& png, int w, int h);
void figureVelocity(const DriveData& d, const std::string& png, int w, int h);
void figureAngularVelocity(const DriveData& d, const std::string& png, int w, int h);
void figureCurrents(const DriveData& d, const std::string& png, int w, int h);
void figureObstacle(const DriveData& d, double t_s, const std::string& png, int w, int h);
void figureDistance(const DriveData& d, const std::string& png, int w, int h);

}  // namespace wheelchair::visualization
