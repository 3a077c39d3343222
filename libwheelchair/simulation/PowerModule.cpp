#include "libwheelchair/simulation/PowerModule.h"

#include <algorithm>
#include <cmath>

namespace wheelchair::simulation {

PowerModule::PowerModule(const PowerModuleParams& p, double track_width_m, double dt_s)
    : p_(p), lw_(track_width_m), dt_(dt_s) {
  delay_steps_ = static_cast<std::size_t>(std::llround(std::max(0.0, p.delay_s) / dt_s));
}

Eigen::Vector2d PowerModule::step(const JoystickDemand& demand, const Eigen::Vector2d& rim,
                                  const Eigen::Vector2d& i_lo, const Eigen::Vector2d& i_hi) {
  // Pure delay: a FIFO of delay_steps_ control periods (zero demand before the start).
  JoystickDemand d = demand;
  if (delay_steps_ > 0) {
    if (delay_line_.empty()) delay_line_.assign(delay_steps_, JoystickDemand{});
    delay_line_.push_back(demand);
    d = delay_line_.front();
    delay_line_.pop_front();
  }
  // Acceleration limits.
  const bool speeding_up = std::abs(d.v_m_s) > std::abs(v_lim_) && d.v_m_s * v_lim_ >= 0;
  const double dv_max = (speeding_up ? p_.max_accel_m_s2 : p_.max_decel_m_s2) * dt_;
  v_lim_ += std::clamp(d.v_m_s - v_lim_, -dv_max, dv_max);
  const double dw_max = p_.max_angular_accel_rad_s2 * dt_;
  om_lim_ += std::clamp(d.omega_rad_s - om_lim_, -dw_max, dw_max);
  // First-order lag (exact discretisation; bypassed for a zero time constant).
  if (p_.time_constant_s > 0) {
    const double a = 1.0 - std::exp(-dt_ / p_.time_constant_s);
    v_ref_ += a * (v_lim_ - v_ref_);
    om_ref_ += a * (om_lim_ - om_ref_);
  } else {
    v_ref_ = v_lim_;
    om_ref_ = om_lim_;
  }
  // PI per wheel with conditional integration (anti-windup).
  Eigen::Vector2d i;
  for (int k = 0; k < 2; ++k) {
    const double s = k == 0 ? 1.0 : -1.0;
    const double u_ref = v_ref_ + s * lw_ * om_ref_ / 2;
    const double e = u_ref - rim(k);
    const double raw = p_.speed_kp_A_s_m * e + p_.speed_ki_A_m * (integ_[k] + e * dt_);
    const double lo = std::max(i_lo(k), -p_.current_limit_A);
    const double hi = std::min(i_hi(k), p_.current_limit_A);
    const double sat = std::clamp(raw, std::min(lo, hi), std::max(lo, hi));
    if (sat == raw || (raw > sat && e < 0) || (raw < sat && e > 0)) integ_[k] += e * dt_;
    i(k) = sat;
  }
  return i;
}

}  // namespace wheelchair::simulation
