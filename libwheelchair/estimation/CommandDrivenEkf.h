// Self-contained EKF for command-driven recordings with landmark range-bearing sightings and a
// known map (the UTIAS MRCLAM robots; docs/real-data.md). Ground truth is NOT used.
//
//   process:     model::CommandDrivenModel (state x, y, phi, v, omega), input = the recorded
//                commands (JOYSTICK) through the drive response (delay, lag, gains), propagated
//                on a fixed grid dt: mean by the model's exact step, covariance
//                P <- Phi P Phi' + Qd, Phi = I + F dt + (F dt)^2 / 2, Qd = G_w Qc G_w' dt, with
//                white noise on the pose rates (v along the heading, omega) and, for a lagged
//                channel, the same density on its velocity state;
//   measurement: range-bearing to a mapped landmark, h = (|L - p|, wrap(atan2(L - p) - phi)),
//                analytic H, chi-square gate on the NIS (2 dof); sightings of unmapped subjects
//                (other robots) are skipped and counted;
//   start:       the first two sightings of mapped landmarks at least init_min_separation_m
//                apart within init_window_s: closed-form pose (heading from the landmark pair,
//                position from the first); the filter starts there.
//
// Integration point for `wheelchair filter` on MRCLAM rawlogs: when the recording has
// JOYSTICK + LANDMARKS and a landmark map in its meta keys (io::landmarkMap(rec) non-empty),
// call runCommandDrivenEkf(rec, io::landmarkMap(rec), loadCommandDrivenEkfOptions(ini)) and
// write result.trajectory (t, x, y, phi).
#pragma once

#include "libwheelchair/io/MrclamImport.h"
#include "libwheelchair/io/Recording.h"
#include "libwheelchair/model/CommandDriven.h"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace wheelchair::estimation {

struct CommandDrivenEkfOptions {
  model::CommandResponseParams response;  ///< nominal = velocities equal the commands
  bool ignore_zero_runs = false;          ///< drop the short (0,0) blips from the input
  double max_zero_run_s = 0.1;
  double dt_s = 0.01;            ///< propagation grid
  double output_every_s = 0.05;  ///< trajectory output interval
  double q_v = 0.02 * 0.02;      ///< white-noise density on v, (m/s)^2 s
  double q_omega = 0.1 * 0.1;    ///< white-noise density on omega, (rad/s)^2 s
  double range_sigma_m = 0.15;
  double bearing_sigma_rad = 0.05;
  double gate_probability = 0.999;  ///< chi-square gate of the NIS (2 dof); <= 0: no gate
  double init_window_s = 0.5;
  double init_min_separation_m = 0.5;
  double init_sigma_xy_m = 0.1;
  double init_sigma_phi_rad = 0.1;
};

/// [mrclam_filter] and [mrclam_response] sections of an INI (config/mrclam.ini).
CommandDrivenEkfOptions loadCommandDrivenEkfOptions(const std::string& ini_path);

struct CommandDrivenEstimate {
  double t_s, x_m, y_m, phi_rad;
  double var_x, var_y, cov_xy, var_phi;
};

struct CommandDrivenEkfResult {
  std::vector<CommandDrivenEstimate> trajectory;
  double t_start_s = 0;  ///< time of the landmark initialisation
  bool initialised = false;
  std::size_t accepted = 0, rejected = 0, unmapped = 0;
  double mean_nis = 0;  ///< over accepted updates
};

/// Range-bearing model: h(x) and H = dh/dx (2x5) for landmark L.
Eigen::Vector2d rangeBearing(const model::CommandState& x, const Eigen::Vector2d& L,
                             Eigen::Matrix<double, 2, 5>* H = nullptr);

CommandDrivenEkfResult runCommandDrivenEkf(const io::Recording& rec,
                                           const std::vector<io::LandmarkPosition>& map,
                                           const CommandDrivenEkfOptions& options);

}  // namespace wheelchair::estimation
