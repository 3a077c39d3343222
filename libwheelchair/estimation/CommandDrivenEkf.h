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
//                analytic H (rangeBearing), through the library's one update path
//                (estimation/Measurement.h: bearing row wrapped, chi-square gate on the NIS
//                (2 dof), Joseph form with the non-positive-definite guard) and its NIS
//                bookkeeping (result.stats(Sensor::Landmarks)); sightings of unmapped subjects
//                (other robots) are skipped and counted;
//   start:       the first two sightings of mapped landmarks at least init_min_separation_m
//                apart within init_window_s: closed-form pose (heading from the landmark pair,
//                position from the second); the filter starts there with covariance
//                init_sigma_xy_m^2, init_sigma_phi_rad^2, plus (init_from_geometry) the
//                range-bearing noise propagated through that closed form (numerical Jacobian),
//                so that a poor geometry (far, nearly aligned landmarks) starts uncertain.
//
// Frame: the estimates are in the MAP frame (the frame of the landmark positions; for MRCLAM
// that is the Vicon frame), not the start frame of the wheelchair filters.
//
// Open-loop reference (`commands` variant of `wheelchair evaluate`, the "encoders only"
// analogue): deadReckoningCommands() propagates the same model's mean on the commands alone,
// from the EKF's landmark initialisation (pose and time; no ground truth), so both cover the
// same span in the same frame.
//
// Used by `wheelchair filter` and `wheelchair evaluate` when isCommandDrivenRecording(rec)
// (landmark sightings or a landmark map present); missingForCommandDrivenEkf() names what a
// recording lacks.
#pragma once

#include "libwheelchair/config/Options.h"
#include "libwheelchair/estimation/EstimationTypes.h"
#include "libwheelchair/io/MrclamImport.h"
#include "libwheelchair/io/Recording.h"
#include "libwheelchair/model/CommandDriven.h"

#include <Eigen/Core>

#include <array>
#include <functional>
#include <map>
#include <string>
#include <vector>

namespace mrpt::config {
class CConfigFileBase;
}

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
  bool init_from_geometry = false;  ///< add the propagated sighting noise to the initial P
  /// Terms outside the catalogue found by `wheelchair diagnose` ([mrclam_response]
  /// unmodeled_v / unmodeled_omega, JSON {feature: coefficient}): added to the velocity in
  /// effect, in m/s and rad/s, as coef . (1, v_cmd, omega_cmd, |omega_cmd|, v_cmd |omega_cmd|)
  /// of the command at t (the feature library of docs/discovery.md). Zero: none.
  std::array<std::array<double, model::kNumCommandFeatures>, 2> unmodeled{};
  bool hasUnmodeled() const;
  /// The key tables of [mrclam_response] and [mrclam_filter] (config/Options.h), bound to
  /// this object (the noise densities are given as their square roots).
  std::vector<config::Options> options();
  /// The extra (v, omega) for command `cmd`.
  Eigen::Vector2d unmodeledVelocity(const Eigen::Vector2d& cmd) const;
};

/// [mrclam_filter] and [mrclam_response] sections of an INI (config/mrclam.ini). Absent keys
/// (or sections) keep the defaults above (nominal response).
CommandDrivenEkfOptions loadCommandDrivenEkfOptions(const std::string& ini_path);
CommandDrivenEkfOptions loadCommandDrivenEkfOptions(const mrpt::config::CConfigFileBase& ini);
/// The options as [mrclam_response] and [mrclam_filter] sections (read back by
/// loadCommandDrivenEkfOptions to the same values): the configuration a result was made with.
std::string toIni(const CommandDrivenEkfOptions& options);
/// The [mrclam_response] keys of `options` (the response model and the unmodeled terms), as
/// written by toIni and by `wheelchair diagnose --write-config`.
std::map<std::string, std::string> responseConfigKeys(const CommandDrivenEkfOptions& options);
/// Whether the INI has an [mrclam_filter] or [mrclam_response] section.
bool hasCommandDrivenSections(const mrpt::config::CConfigFileBase& ini);

/// A recording meant for the command-driven EKF: landmark sightings or a landmark map.
bool isCommandDrivenRecording(const io::Recording& rec);
/// What the command-driven EKF needs and `rec` lacks (empty = nothing): the JOYSTICK command
/// stream, LANDMARKS range-bearing sightings, the landmark map (meta keys landmark.<id>),
/// sightings of mapped landmarks.
std::vector<std::string> missingForCommandDrivenEkf(const io::Recording& rec);

/// Pose (map frame), velocities and their (co)variances.
struct CommandDrivenEstimate {
  double t_s, x_m, y_m, phi_rad;
  double var_x, var_y, cov_xy, var_phi;
  double v_m_s = 0, omega_rad_s = 0, var_v = 0, var_omega = 0;
};

/// The run's result: the common EstimationResult (filter "command"; the sightings' counts, NIS
/// statistics and rejected list under Sensor::Landmarks, booked by Measurement.h bookUpdate
/// like every filter's) with the map-frame trajectory and what the initialisation found.
struct CommandDrivenEkfResult : EstimationResult {
  CommandDrivenEkfResult() { filter = "command"; }
  std::vector<CommandDrivenEstimate> trajectory;
  double t_start_s = 0;  ///< time of the landmark initialisation
  bool initialised = false;
  std::size_t unmapped = 0;      ///< sightings of unmapped subjects (skipped)
  std::size_t before_start = 0;  ///< mapped sightings up to the initialisation (incl. its two)
  double mean_nis_all = 0;       ///< over every update attempt (accepted and gated out)
  std::size_t commands = 0;      ///< command rows in the signal (after the quirk handling)
  std::size_t dropped_zero_runs = 0;
  Eigen::Vector2d start_pose_xy = Eigen::Vector2d::Zero();  ///< initial pose (map frame)
  double start_phi_rad = 0;
  Eigen::Vector2d start_velocity = Eigen::Vector2d::Zero();  ///< (v, omega) at t_start_s
  /// The landmark sightings' counts and NIS statistics (used = accepted updates).
  const SensorStats& landmarks() const { return stats(Sensor::Landmarks); }
};

/// Called with the fraction (0..1) of the recording's time span processed.
using ProgressFunction = std::function<void(double)>;

/// Range-bearing model: h(x) and H = dh/dx (2x5) for landmark L.
Eigen::Vector2d rangeBearing(const model::CommandState& x, const Eigen::Vector2d& L,
                             Eigen::Matrix<double, 2, 5>* H = nullptr);

CommandDrivenEkfResult runCommandDrivenEkf(const io::Recording& rec,
                                           const std::vector<io::LandmarkPosition>& map,
                                           const CommandDrivenEkfOptions& options,
                                           const ProgressFunction& progress = {});

/// Open-loop dead reckoning of the commands: the model's mean (same response, same grid and
/// output interval as the EKF), no measurement. Starts at (x0, y0, phi0) with velocities
/// `vel0` at t0_s (the EKF's initialisation: result.start_*, result.t_start_s); runs to the
/// last command. Variances are 0.
std::vector<CommandDrivenEstimate> deadReckoningCommands(const io::Recording& rec,
                                                         const CommandDrivenEkfOptions& options,
                                                         double t0_s, const Eigen::Vector3d& pose0,
                                                         const Eigen::Vector2d& vel0);

}  // namespace wheelchair::estimation
