// Command-driven vehicle model: the body velocities follow the DEMANDED (v, omega) through the
// drive's response (docs/real-data.md). Serves the MRCLAM robots (commands sent to an iRobot
// Create) and the wheelchair (joystick through the power module) alike. Eigen only.
//
// Nominal form: "the velocities equal the commands" (a unicycle that does exactly what it is
// told). Extended form, per channel c in {v, omega} separately:
//
//   target_c(t) = g_c(kind) * deadband_c(cmd_c(t - delay_c))      (gain per command kind)
//   tau_c dvel_c/dt = target_c - vel_c           (first-order lag; tau_c = 0: vel_c = target_c)
//
// with the command kind decided on the raw (delayed) command pair:
//   Stop         |v| <= eps_v and |omega| <= eps_omega
//   Straight     |v| >  eps_v and |omega| <= eps_omega
//   TurnInPlace  |v| <= eps_v and |omega| >  eps_omega
//   Arc          both above
// The v gain further depends on the direction (forward / backward).
//
// State  x = [x, y, phi, v, omega]' (m, m, rad, m/s, rad/s), pose of the axle midpoint in the
// world frame; input u = target (v, omega) (the gains/deadband are applied by target()).
//   xdot = [v_e cos phi, v_e sin phi, omega_e, (u_v - v)/tau_v, (u_w - omega)/tau_w]'
// where v_e = v (state) when tau_v > 0, else u_v (then the v state is unused and vdot = 0);
// same for omega. F = df/dx (5x5) and G = df/du (5x2) are analytic
// (tests/model/test_command_driven.cpp checks them against central differences).
//
// CommandSignal holds the command stream with the real-file quirks resolved: of rows with
// equal timestamps the LAST is in effect; optionally, short runs of (0,0) lines between moving
// commands (the MRCLAM once-a-second blips the robot does not react to) are dropped; the
// value at time t is the last command at or before t (zero-order hold, also across logging
// gaps: the robot keeps moving).
//
// Example:
//   CommandResponseParams p;                  // nominal
//   p.v.delay_s = 0.1; p.v.time_constant_s = 0.2;
//   CommandDrivenModel m(p);
//   CommandSignal cmd(times, v, w, CommandSignalOptions{});
//   Eigen::Vector2d u = m.target(cmd.at(t - p.v.delay_s), cmd.at(t - p.omega.delay_s));
//   CommandState x1 = m.step(x0, u, 0.01);
#pragma once

#include <Eigen/Core>

#include <array>
#include <string>
#include <vector>

namespace wheelchair::model {

constexpr int kCmdStateDim = 5;
enum CommandStateIndex : int { kCmdX = 0, kCmdY = 1, kCmdPhi = 2, kCmdV = 3, kCmdOmega = 4 };
using CommandState = Eigen::Matrix<double, kCmdStateDim, 1>;
using CommandStateJacobian = Eigen::Matrix<double, kCmdStateDim, kCmdStateDim>;
using CommandInputJacobian = Eigen::Matrix<double, kCmdStateDim, 2>;

enum class CommandKind { Stop = 0, Straight = 1, TurnInPlace = 2, Arc = 3 };
constexpr int kNumCommandKinds = 4;
const char* toString(CommandKind k);

/// Response of one channel (v or omega) to its demand.
struct ChannelResponse {
  double delay_s = 0;          ///< pure (transport) delay
  double time_constant_s = 0;  ///< first-order lag; 0 = none
  double deadband = 0;         ///< |command| <= deadband gives 0 (channel units); 0 = none
};

struct CommandResponseParams {
  ChannelResponse v, omega;
  /// v gain per command kind (index CommandKind; Stop and TurnInPlace have v = 0 anyway).
  std::array<double, kNumCommandKinds> v_gain{1, 1, 1, 1};
  /// Extra v factor when the command is backward (v < 0).
  double v_gain_backward = 1;
  /// omega gain per command kind (Straight: |omega| <= eps, only matters for small commands).
  std::array<double, kNumCommandKinds> omega_gain{1, 1, 1, 1};
  /// Thresholds of the kind classification (m/s, rad/s).
  double kind_eps_v_m_s = 1e-3, kind_eps_omega_rad_s = 1e-3;

  bool isNominal() const;
};

CommandKind classifyCommand(double v_cmd, double omega_cmd, const CommandResponseParams& p);

/// One command row (t, v, omega).
struct CommandSample {
  double t_s = 0, v_m_s = 0, omega_rad_s = 0;
};

struct CommandSignalOptions {
  /// Drop runs of (0,0) lines shorter than max_zero_run_s between non-zero commands.
  bool drop_short_zero_runs = false;
  double max_zero_run_s = 0.1;
};

class CommandSignal {
 public:
  CommandSignal() = default;
  /// `rows` in file order (time non-decreasing).
  CommandSignal(const std::vector<CommandSample>& rows, const CommandSignalOptions& opt);
  /// Command in effect at t (zero-order hold); (0,0) before the first row.
  Eigen::Vector2d at(double t_s) const;
  const std::vector<CommandSample>& samples() const { return s_; }
  std::size_t droppedZeroRuns() const { return dropped_runs_; }
  std::size_t droppedDuplicates() const { return dropped_dups_; }
  double startTime() const { return s_.empty() ? 0.0 : s_.front().t_s; }
  double endTime() const { return s_.empty() ? 0.0 : s_.back().t_s; }

 private:
  std::vector<CommandSample> s_;
  std::size_t dropped_runs_ = 0, dropped_dups_ = 0;
};

class CommandDrivenModel {
 public:
  explicit CommandDrivenModel(const CommandResponseParams& p = {}) : p_(p) {}
  const CommandResponseParams& params() const { return p_; }

  /// Gains and deadbands applied to the (already delayed) demands: the lag's input u.
  /// `v_cmd_delayed` is the pair at t - delay_v (its v is used; both components classify),
  /// `omega_cmd_delayed` the pair at t - delay_omega.
  Eigen::Vector2d target(const Eigen::Vector2d& v_cmd_delayed,
                         const Eigen::Vector2d& omega_cmd_delayed) const;
  /// Same with one pair for both channels (equal delays).
  Eigen::Vector2d target(const Eigen::Vector2d& cmd) const { return target(cmd, cmd); }
  /// target() of a signal at time t (each channel read at t - its delay).
  Eigen::Vector2d target(const CommandSignal& s, double t_s) const;

  /// Velocities in effect for state x and input u: (v_e, omega_e).
  Eigen::Vector2d effectiveVelocity(const CommandState& x, const Eigen::Vector2d& u) const;

  CommandState f(const CommandState& x, const Eigen::Vector2d& u) const;
  CommandStateJacobian F(const CommandState& x, const Eigen::Vector2d& u) const;
  CommandInputJacobian G(const CommandState& x, const Eigen::Vector2d& u) const;

  /// Exact lag over dt for a constant u, pose by RK4 on the resulting velocities (phi not
  /// wrapped). With tau = 0 the velocity state is set to u.
  CommandState step(const CommandState& x, const Eigen::Vector2d& u, double dt_s) const;

 private:
  CommandResponseParams p_;
};

/// Lag response of one channel on a uniform grid: y_{k+1} from y_k for a constant input c
/// over dt (exact), and the integral of y over the step. tau = 0: y = c.
struct LagStep {
  double y_next, integral;
};
LagStep lagStep(double y, double c, double dt_s, double tau_s);

/// Library of command features for terms outside the catalogue (`unmodeled`, found by
/// `wheelchair diagnose`, applied by the command-driven EKF): (1, v_cmd, omega_cmd,
/// |omega_cmd|, v_cmd |omega_cmd|) of the current (undelayed) command (v_cmd, omega_cmd).
constexpr int kNumCommandFeatures = 5;
const std::array<const char*, kNumCommandFeatures>& commandFeatureNames();
Eigen::Matrix<double, kNumCommandFeatures, 1> commandFeatures(const Eigen::Vector2d& cmd);

}  // namespace wheelchair::model
