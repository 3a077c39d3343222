// The truth simulator: a chair RICHER than the estimator's model, so that model and
// "reality" can differ the way they do on a real chair (docs/simulation.md, docs/effects.md).
//
//   driver (scenario) -> [supervisory control] -> power module (delay, acceleration limits,
//   lag, PI speed loop per wheel, current/voltage saturation) -> per-wheel torque balance
//   with per-side parameters (model::DriveTrain: Coulomb friction, slope) -> pose by (1),
//   integrated with fixed-step RK4 (default 1 ms) -> sensors sampled asynchronously at
//   their own rates with jitter (encoders, gyro z, currents, V_RC by (11) with the Zener
//   knee, sonar, Pozyx in an anchor frame, joystick) -> io::Recording.
//
// Frames/units: start frame = the body frame at t = 0 (x forward, y left); SI units; index 0
// = right. Recording timestamps are options.start_time_s + time since the start.
// Deterministic: the same (config, scenario, seed, duration, effects, options) gives a
// bit-identical result on one platform (see Random.h for portability).
//
// Example:
//   auto cfg = config::WheelchairConfig();            // nominal vehicle
//   SimulationOptions opt;                            // or opt.loadFromConfig(cfg.ini())
//   auto res = simulate(cfg, "three_task", 42, 0, {effects::parseEffect("gyro_bias:bias_rad_s=0.01")}, opt);
//   io::writeRawlog(res.recording, "sim.rawlog", cfg);
//   res.writeTruth("sim.rawlog.truth.json");
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/io/Recording.h"
#include "libwheelchair/effects/Effect.h"
#include "libwheelchair/io/Samples.h"
#include "libwheelchair/simulation/PowerModule.h"
#include "libwheelchair/simulation/Scenarios.h"
#include "libwheelchair/simulation/Supervisory.h"

#include <mrpt/config/CConfigFileBase.h>

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

namespace wheelchair::simulation {

/// Options of the simulator: [simulation] section of the configuration (units in the names).
struct TruthSample;

/// Where a streamed run's data goes (SimulationOptions::sink): first the recording's meta,
/// then every recorded sample as it is produced (per stream in stream order) instead of into
/// SimulationResult::recording, and every truth sample instead of truth.samples (which then
/// keeps only the last one; with record_ground_truth the sink makes the GROUND_TRUTH stream
/// from the truth samples). A long drive then needs no memory for its data (`wheelchair
/// simulate`, docs/benchmarks.md "Memory").
struct SimulationSink {
  virtual ~SimulationSink() = default;
  virtual void meta(const std::map<std::string, std::string>& meta) = 0;
  virtual void sample(const io::AnySample& s) = 0;
  virtual void truth(const TruthSample& s) = 0;
};

struct SimulationOptions {
  double step_s = 0.001;              ///< RK4 integration and power-module control period
  double truth_rate_hz = 100;         ///< rate of the truth trajectory samples
  double start_time_s = 0;            ///< recording clock at the start of the run
  double timestamp_jitter_s = 0.002;  ///< sampling instants jitter, uniform +-, per sample
  PowerModuleParams power;
  double coulomb_smoothing_m_s = 0.01;  ///< sgn(u) ~ tanh(u / this) for Coulomb friction
  /// Pozyx anchor frame: a random SE(2) per seed (translation up to max offset, any yaw),
  /// or the fixed transform below. p_anchor = R(yaw) p_start + (x, y).
  bool pozyx_anchor_random = true;
  double pozyx_anchor_max_offset_m = 10.0;
  double pozyx_anchor_x_m = 0, pozyx_anchor_y_m = 0, pozyx_anchor_yaw_deg = 0;
  int64_t encoder_initial_ticks_right = 0;  ///< counter value at the start (tests wrap-around)
  int64_t encoder_initial_ticks_left = 0;
  Footprint footprint;
  SupervisoryParams supervisory;
  ScenarioSettings scenario;
  bool record_ground_truth = false;  ///< also put the true pose into recording.ground_truth
  /// Truth engine: "model" (per-wheel torque balance, RK4) or "mujoco" (the chair as a MuJoCo
  /// multibody, MujocoEngine.h; its [mujoco] section is read from the configuration).
  std::string engine = "model";
  /// When set, the run's data goes to the sink as it is produced instead of into the
  /// SimulationResult (see SimulationSink).
  SimulationSink* sink = nullptr;

  /// The key table (config/Options.h), bound to this object.
  config::Options options(const std::string& section = "simulation");
  /// Reads the keys present in `section` (missing keys keep their defaults). Throws
  /// std::runtime_error naming file, line and key on a malformed or out-of-range value.
  void loadFromConfig(const mrpt::config::CConfigFileBase& ini,
                      const std::string& section = "simulation");
};

/// One sample of the true motion (start frame, SI).
struct TruthSample {
  double t_s = 0;  ///< recording clock
  double x_m = 0, y_m = 0, phi_rad = 0;
  double v_m_s = 0, omega_rad_s = 0;
  double wheel_speed_right_rad_s = 0, wheel_speed_left_rad_s = 0;  ///< psidot = u / r
  double wheel_angle_right_rad = 0, wheel_angle_left_rad = 0;      ///< true psi
  double current_right_A = 0, current_left_A = 0;                  ///< true motor currents
  double voltage_right_V = 0, voltage_left_V = 0;                  ///< U = R_m i + k_m omega_m
  double v_demand_m_s = 0, omega_demand_rad_s = 0;                 ///< joystick
  double v_ref_m_s = 0, omega_ref_rad_s = 0;  ///< power-module references (after lag)
  double supervisory_scale = 1;
};

/// The Pozyx anchor frame: p_anchor = R(yaw) p_start + (x, y).
struct AnchorFrame {
  double x_m = 0, y_m = 0, yaw_rad = 0;
};

struct TruthTrajectory {
  std::vector<TruthSample> samples;
  std::vector<Obstacle> obstacles;  ///< start frame
  AnchorFrame pozyx_anchor;
  std::vector<int> collided_obstacles;  ///< indices into obstacles, in order of contact
};

struct SimulationResult {
  io::Recording recording;
  TruthTrajectory truth;
  std::vector<effects::EffectSpec> effects;
  int collisions = 0;
  std::string scenario;
  std::string engine = "model";  ///< truth engine that produced the run
  uint64_t seed = 0;
  double duration_s = 0;
  bool supervisory = false;
  std::string config_text;  ///< the configuration the run used (WheelchairConfig::text())

  /// Writes the truth atomically (temp + rename): `.csv` -> the trajectory table only;
  /// anything else -> JSON with scenario, seed, effects, obstacles, anchor frame,
  /// collisions, configuration and the trajectory (column arrays).
  void writeTruth(const std::string& path) const;
  /// The same file with the trajectory from `replay` (it calls its argument once per truth
  /// sample, in order, each time it is called) instead of truth.samples: for a run whose
  /// samples went to SimulationOptions::truth_sink (e.g. through a scratch file).
  using TruthReplay = std::function<void(const std::function<void(const TruthSample&)>&)>;
  void writeTruth(const std::string& path, const TruthReplay& replay) const;
};

/// Runs a scenario. duration_s <= 0: the scenario's default. Throws std::invalid_argument
/// for an unknown scenario or engine or an invalid effect (validateEngineEffect).
SimulationResult simulate(const config::WheelchairConfig& cfg, const std::string& scenario,
                          uint64_t seed, double duration_s, const std::vector<effects::EffectSpec>& effects,
                          const SimulationOptions& options);

/// Reads a truth JSON written by writeTruth (recording left empty). Throws on a bad file.
SimulationResult readTruth(const std::string& path);

}  // namespace wheelchair::simulation
