// The wheelchair's power module as the simulator models it: joystick demand (v, omega) ->
// pure delay -> acceleration limits (rate limiter) -> first-order lag -> wheel rim-speed
// references u_ref = v_ref +- l_w omega_ref / 2 -> one PI speed loop per wheel -> motor
// current demands, saturated at the current limit and at what the battery voltage allows
// (|R_m i + k_m omega_m| <= V_batt). Motor inductance is neglected (the current loop is
// much faster than the mechanics), so the motor current equals the saturated demand.
//
// Units: m/s, rad/s, A, s. Index 0 right, 1 left.
//
// Example:
//   PowerModule pm(PowerModuleParams{}, 0.55, 0.001);
//   Eigen::Vector2d i = pm.step({0.5, 0.0}, {uR, uL}, {-30, -30}, {30, 30});
#pragma once

#include "libwheelchair/simulation/Scenarios.h"

#include <Eigen/Core>

#include <deque>

namespace wheelchair::simulation {

struct PowerModuleParams {
  double max_accel_m_s2 = 0.8;            ///< |dv_ref/dt| when speeding up
  double max_decel_m_s2 = 1.2;            ///< |dv_ref/dt| when slowing down
  double max_angular_accel_rad_s2 = 1.5;  ///< |domega_ref/dt|
  double delay_s = 0.0;                   ///< pure delay of the demand
  double time_constant_s = 0.1;           ///< first-order lag of the references
  double speed_kp_A_s_m = 60.0;           ///< PI proportional gain, A per m/s of rim speed error
  double speed_ki_A_m = 150.0;            ///< PI integral gain, A per m of integrated error
  double current_limit_A = 30.0;          ///< per motor
  double battery_voltage_V = 24.0;
};

class PowerModule {
 public:
  PowerModule(const PowerModuleParams& p, double track_width_m, double dt_s);

  /// One control period. rim_speed_m_s: measured (true) u_R, u_L; i_lo/i_hi: the current
  /// bounds of each motor (current limit and battery voltage). Returns (i_R, i_L) in A.
  Eigen::Vector2d step(const JoystickDemand& demand, const Eigen::Vector2d& rim_speed_m_s,
                       const Eigen::Vector2d& i_lo_A, const Eigen::Vector2d& i_hi_A);

  /// The references after delay, limits and lag (what the speed loops track).
  double vRef() const { return v_ref_; }
  double omegaRef() const { return om_ref_; }

 private:
  PowerModuleParams p_;
  double lw_, dt_;
  std::deque<JoystickDemand> delay_line_;
  std::size_t delay_steps_ = 0;
  double v_lim_ = 0, om_lim_ = 0;  // after the rate limiter
  double v_ref_ = 0, om_ref_ = 0;  // after the first-order lag
  double integ_[2] = {0, 0};
};

}  // namespace wheelchair::simulation
