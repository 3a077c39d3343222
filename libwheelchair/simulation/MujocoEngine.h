// The second truth engine: the chair as a MuJoCo multibody (`wheelchair simulate --engine
// mujoco`). Its physics is NOT the estimator's model (6): rigid bodies with contacts, whose
// motion MuJoCo integrates; only the power module, the scenarios, the supervisory control and
// the sensor models (noise, timing, quantisation) are shared with the model engine
// (Simulator.cpp), and the sensors read the multibody state (docs/simulation.md, "MuJoCo
// engine").
//
// The multibody (MJCF built from [vehicle] and [mujoco], z up, x forward, y left; the body
// frame origin is the drive-axle midpoint, at height r over the floor):
//   chassis (free joint) with seat and occupant welded to it, each with its own mass, centre
//   of mass and inertia (their sum: m_b and I_zz of [vehicle]);
//   two drive wheels (mass m_w, spin inertia I_w) on hinges at y = -+l_w/2 (index 0 right),
//   driven by a motor of gear eta k_m r_G (control = motor current i, A), with the rotor
//   inertia J_m r_G^2 as joint armature, viscous friction eta B_m r_G^2 as joint damping and
//   dry friction eta k_m r_G c as joint frictionloss (per side);
//   two castor forks swivelling freely about vertical hinges ahead of the axle (trail behind
//   the swivel axis), each carrying a castor wheel on a hinge;
//   sphere tyres on a plane floor with Coulomb friction (soft contacts: slip is possible);
//   a slope tilts gravity in the floor frame (exactly a tilted floor, seen from the floor);
//   obstacles as vertical cylinders the sonar sees by ray casting (mj_ray); they do not
//   collide (collisions are counted from the footprint, as in the model engine).
//
// Catalogue effects become physics: payload_mass = an extra body (mass difference, inertia) at
// an offset ahead of the axle; motor_asymmetry = per-joint damping / motor gear;
// coulomb_friction = per-joint frictionloss; ground_slope = tilted gravity. Sensor effects
// (encoder_scale, gyro_*, sensor_delay, sonar_dropout, pozyx_outliers) and actuator_lag stay in
// the shared sensor / power-module code. Effects only this engine knows (mujocoEffectCatalogue,
// documented in docs/simulation.md and deliberately NOT in the diagnosis): castor_friction,
// tyre_scrub, rolling_resistance, soft_tyre, tyre_grip.
//
// Units SI; angles rad unless named _deg.
//
// Example:
//   MujocoOptions mo;  mo.loadFromConfig(cfg.ini());
//   MujocoChair chair(cfg, mo, {parseEngineEffect("tyre_scrub:torsion_m=0.02", "mujoco")}, {});
//   chair.step({5.0, 5.0}, 0.001);                 // motor currents (A) held for 1 ms
//   ChairState s = chair.state();                  // pose, speeds, wheel angles
#pragma once

#include "libwheelchair/config/Options.h"
#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/effects/Effect.h"
#include "libwheelchair/simulation/Scenarios.h"

#include <mrpt/config/CConfigFileBase.h>
#include <Eigen/Core>

#include <memory>
#include <string>
#include <vector>

namespace wheelchair::simulation {

/// [mujoco] section: the multibody's parts the [vehicle] section does not describe.
struct MujocoOptions {
  double timestep_s = 0.001;  ///< MuJoCo step (sub-steps of [simulation] step_s if smaller)
  double settle_s = 0.5;      ///< standstill before t = 0 so that the tyres settle on the floor
  // Split of m_b (body with user, castors excluded) and the parts' centres of mass (body frame).
  double chassis_fraction = 0.30, seat_fraction = 0.10;  ///< occupant: the rest
  double chassis_com_x_m = 0.10, chassis_com_z_m = 0.05;
  double seat_com_x_m = 0.05, seat_com_z_m = 0.30;
  double occupant_com_x_m = 0.05, occupant_com_z_m = 0.45;
  // Castors.
  double castor_x_m = 0.45, castor_half_spacing_m = 0.22;  ///< swivel axes
  double castor_trail_m = 0.05;                            ///< wheel axle behind the axis
  double castor_wheel_radius_m = 0.075;
  double castor_fork_mass_kg = 0.5, castor_wheel_mass_kg = 0.5;
  double castor_swivel_damping_Nm_s_rad = 0.005;  ///< nominal swivel bearing
  double tyre_friction = 1.0;                     ///< Coulomb coefficient tyre-floor
  // Payload (payload_mass effect): where the mass difference sits.
  double payload_x_m = 0.15, payload_z_m = 0.35;
  double sonar_height_m = 0.30;  ///< height of the sonar over the floor for the rays
  int sonar_rays = 31;           ///< rays across the sonar cone

  /// The key table of the [mujoco] section (config/Options.h: strict numbers, ranges).
  config::Options options(const std::string& section = "mujoco");
  /// Reads the keys present in `section`; throws std::runtime_error naming file, line and key
  /// on a bad value (unknown keys are checked when the file is loaded).
  void loadFromConfig(const mrpt::config::CConfigFileBase& ini,
                      const std::string& section = "mujoco");
};

/// Effects only the MuJoCo engine knows (physics the catalogue and the diagnosis lack).
const std::vector<effects::EffectInfo>& mujocoEffectCatalogue();

/// Engine names: "model" (the default) and "mujoco".
const std::vector<std::string>& engineNames();

/// Parses and validates one effect for an engine: catalogue effects for both, the
/// mujocoEffectCatalogue only for "mujoco". Throws std::invalid_argument with a one-line
/// message (unknown engine, unknown id, key, or value out of range).
effects::EffectSpec parseEngineEffect(const std::string& text, const std::string& engine);
/// Validation part of parseEngineEffect.
void validateEngineEffect(const effects::EffectSpec& e, const std::string& engine);

/// The multibody state the sensors and the driver read (start frame = floor frame at t = 0).
struct ChairState {
  double x_m = 0, y_m = 0, phi_rad = 0;  ///< axle midpoint, heading (unwrapped)
  double v_m_s = 0;                      ///< axle-midpoint velocity along the heading
  double omega_rad_s = 0;                ///< chassis angular velocity about its own z (gyro axis)
  double psi_right_rad = 0, psi_left_rad = 0;            ///< drive wheel hinge angles
  double psidot_right_rad_s = 0, psidot_left_rad_s = 0;  ///< drive wheel hinge speeds
  double lateral_m_s = 0;                                ///< axle-midpoint side slip velocity
  double castor_swivel_right_rad = 0, castor_swivel_left_rad = 0;
};

/// One body (centre of mass, mass) or tyre sphere (centre, radius) of the compiled multibody,
/// in the floor frame at the current state: for pictures of the model (docs/simulation.md).
struct MujocoPart {
  std::string name;
  double x_m = 0, y_m = 0, z_m = 0;
  double mass_kg = 0;   ///< bodies
  double radius_m = 0;  ///< > 0: a tyre sphere (its centre)
};

/// The multibody and its MuJoCo state. Not copyable.
class MujocoChair {
 public:
  /// Builds the MJCF (mujocoXml), compiles it, settles the chair on the floor. Throws
  /// std::runtime_error with MuJoCo's message if the model does not compile.
  MujocoChair(const config::WheelchairConfig& cfg, const MujocoOptions& opt,
              const std::vector<effects::EffectSpec>& effects, const std::vector<Obstacle>& obstacles);
  ~MujocoChair();
  MujocoChair(const MujocoChair&) = delete;
  MujocoChair& operator=(const MujocoChair&) = delete;

  /// Advances by h_s with the motor currents (right, left) held (A).
  void step(const Eigen::Vector2d& current_A, double h_s);
  ChairState state() const;
  /// Distance (m) from the sonar at (x, y) heading yaw (start frame) to the nearest obstacle
  /// surface hit by one of the rays fanned over +-half_angle; +inf when no ray hits.
  double sonarRange(double x_m, double y_m, double yaw_rad, double half_angle_rad) const;
  /// Total mass of the multibody (kg): m_b + 2 m_w (+ a payload).
  double totalMass() const;
  /// The MJCF the chair was compiled from.
  const std::string& xml() const { return xml_; }
  /// Bodies with mass (their centres of mass) and tyre spheres, at the current state.
  std::vector<MujocoPart> parts() const;
  double time() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string xml_;
};

/// The MJCF text of the chair (for docs and tests).
std::string mujocoXml(const config::WheelchairConfig& cfg, const MujocoOptions& opt,
                      const std::vector<effects::EffectSpec>& effects,
                      const std::vector<Obstacle>& obstacles);

}  // namespace wheelchair::simulation
