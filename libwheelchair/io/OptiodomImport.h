// Import of the OptiOdom odometry-calibration runs (R. B. Sousa, M. R. Petry, P. G. Costa,
// A. P. Moreira, "OptiOdom: a Generic Approach for Odometry Calibration of Wheeled Mobile
// Robots", J. Intell. Robot. Syst. 105, 39, 2022): a real differential-drive robot without a
// gyro, wheel encoders and OptiTrack ground truth (docs/real-data.md, "OptiOdom").
//
// An experiment directory `<ID>/` holds
//   <ID>_metadata.csv  type, ngear, encRes (counts per motor turn), Li (track, m), Di (wheel
//                      diameters, m), N (runs), L (square side, m; empty for other paths)
//   <ID>.csv           the robot's whole log: header (method, dL0/dR0/b0, speed limits), then
//                      per run `Run:,N` and per 50 ms cycle t, odoL, odoR, x, y, th,
//                      vlin (ticks/cycle), omega (rad/cycle), flag
//   <ID>_run-NN.csv    the authors' synchronised run: t, x_gt, y_gt, th_gt (OptiTrack, robot
//                      start frame, m / rad), odoR, odoL (ticks PER CYCLE)
// and becomes one recording per run:
//   ENCODERS      absolute counts (the per-cycle ticks accumulated from 0), right / left
//   GROUND_TRUTH  the OptiTrack pose of the same row
//   JOYSTICK      the commands of that run in <ID>.csv, in physical units:
//                 v = vlin * pi D / (ngear encRes) / 0.05 s (m/s), omega = omega / 0.05 s (rad/s)
// all on the run file's clock t (s; robot cycles x 50 ms, the commands re-based to the first
// cycle of their run). The geometry of the metadata is returned in `OptiodomGeometry` and
// goes into the recording's configuration (applyOptiodomGeometry): [vehicle] wheel_radius_m =
// mean D / 2, wheel_radius_right_m / wheel_radius_left_m = D_R / 2, D_L / 2, track_width_m =
// Li, [encoders] counts_per_rev = encRes and wheel/encoder pulley teeth whose ratio is ngear.
// Meta keys: experiment, run, path (square / other), direction (cw / ccw from the ticks),
// square_side_m, method.
//
// Example:
//   io::OptiodomImportReport rep;
//   io::Recording rec = io::importOptiodom("square/230620202042", 1, &rep);
//   config::WheelchairConfig cfg;  io::applyOptiodomGeometry(rep.geometry, cfg);
//   io::writeRawlog(rec, "run1.rawlog", cfg);
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/io/Recording.h"

#include <string>
#include <vector>

namespace wheelchair::io {

/// The nominal geometry an experiment was driven with (its metadata).
struct OptiodomGeometry {
  double wheel_diameter_right_m = 0, wheel_diameter_left_m = 0;
  double track_m = 0;
  double gear_ratio = 0;         ///< ngear, motor turns per wheel turn
  int counts_per_motor_rev = 0;  ///< encRes
  double ticksPerWheelRev() const { return gear_ratio * counts_per_motor_rev; }
};

struct OptiodomImportReport {
  OptiodomGeometry geometry;
  std::string experiment, path_kind, direction, method;
  int run = 0;  ///< the run read (1..runs_in_metadata)
  int runs_in_metadata = 0;
  std::size_t cycles = 0, commands = 0;
  double duration_s = 0;
  double square_side_m = 0;  ///< 0 when not a square path
  std::string summary() const;
};

/// Reads run `run` (1..N) of the experiment in `dir`. Throws FormatError naming file:line on a
/// bad row, a missing file or inconsistent metadata.
Recording importOptiodom(const std::string& dir, int run, OptiodomImportReport* report = nullptr);

/// One run of an experiment and its import report.
struct OptiodomRun {
  Recording rec;
  OptiodomImportReport report;
};

/// Every run (1..N) of every experiment folder directly under `root` (e.g. the dataset's
/// `square/` or `circular/`), experiments in name order. Each run is read once.
std::vector<OptiodomRun> importOptiodomFolder(const std::string& root);

/// Writes the geometry into the configuration's [vehicle] and [encoders] keys (see above).
void applyOptiodomGeometry(const OptiodomGeometry& g, config::WheelchairConfig& cfg);

}  // namespace wheelchair::io
