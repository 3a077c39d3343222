#include "libwheelchair/model/CommandDriven.h"

#include <algorithm>
#include <cmath>

namespace wheelchair::model {

const char* toString(CommandKind k) {
  switch (k) {
    case CommandKind::Stop:
      return "stop";
    case CommandKind::Straight:
      return "straight";
    case CommandKind::TurnInPlace:
      return "turn_in_place";
    case CommandKind::Arc:
      return "arc";
  }
  return "?";
}

bool CommandResponseParams::isNominal() const {
  const auto zero = [](const ChannelResponse& c) {
    return c.delay_s == 0 && c.time_constant_s == 0 && c.deadband == 0;
  };
  const auto ones = [](const std::array<double, kNumCommandKinds>& g) {
    return std::all_of(g.begin(), g.end(), [](double x) { return x == 1.0; });
  };
  return zero(v) && zero(omega) && ones(v_gain) && ones(omega_gain) && v_gain_backward == 1.0;
}

CommandKind classifyCommand(double v, double w, const CommandResponseParams& p) {
  const bool mv = std::abs(v) > p.kind_eps_v_m_s, mw = std::abs(w) > p.kind_eps_omega_rad_s;
  if (mv && mw) return CommandKind::Arc;
  if (mv) return CommandKind::Straight;
  if (mw) return CommandKind::TurnInPlace;
  return CommandKind::Stop;
}

CommandSignal::CommandSignal(const std::vector<CommandSample>& rows,
                             const CommandSignalOptions& opt) {
  // Last row of equal timestamps wins.
  s_.reserve(rows.size());
  for (const auto& r : rows) {
    if (!s_.empty() && r.t_s == s_.back().t_s) {
      s_.back() = r;
      ++dropped_dups_;
    } else {
      s_.push_back(r);
    }
  }
  if (!opt.drop_short_zero_runs) return;
  const auto isZero = [](const CommandSample& c) { return c.v_m_s == 0 && c.omega_rad_s == 0; };
  std::vector<CommandSample> out;
  out.reserve(s_.size());
  std::size_t i = 0;
  while (i < s_.size()) {
    if (!isZero(s_[i]) || out.empty() || isZero(out.back())) {
      out.push_back(s_[i++]);
      continue;
    }
    std::size_t j = i;
    while (j < s_.size() && isZero(s_[j])) ++j;
    // Run [i, j) of zeros after a moving command; short and followed by a moving one: drop.
    if (j < s_.size() && s_[j].t_s - s_[i].t_s < opt.max_zero_run_s) {
      ++dropped_runs_;
    } else {
      for (std::size_t k = i; k < j; ++k) out.push_back(s_[k]);
    }
    i = j;
  }
  s_.swap(out);
}

Eigen::Vector2d CommandSignal::at(double t) const {
  if (s_.empty() || t < s_.front().t_s) return Eigen::Vector2d::Zero();
  const auto it = std::upper_bound(s_.begin(), s_.end(), t,
                                   [](double tt, const CommandSample& c) { return tt < c.t_s; });
  const auto& c = *(it - 1);
  return {c.v_m_s, c.omega_rad_s};
}

Eigen::Vector2d CommandDrivenModel::target(const Eigen::Vector2d& cv,
                                           const Eigen::Vector2d& cw) const {
  Eigen::Vector2d u;
  {
    const double v = std::abs(cv(0)) <= p_.v.deadband && p_.v.deadband > 0 ? 0.0 : cv(0);
    double g = p_.v_gain[static_cast<int>(classifyCommand(cv(0), cv(1), p_))];
    if (v < 0) g *= p_.v_gain_backward;
    u(0) = g * v;
  }
  {
    const double w = std::abs(cw(1)) <= p_.omega.deadband && p_.omega.deadband > 0 ? 0.0 : cw(1);
    u(1) = p_.omega_gain[static_cast<int>(classifyCommand(cw(0), cw(1), p_))] * w;
  }
  return u;
}

Eigen::Vector2d CommandDrivenModel::target(const CommandSignal& s, double t) const {
  return target(s.at(t - p_.v.delay_s), s.at(t - p_.omega.delay_s));
}

Eigen::Vector2d CommandDrivenModel::effectiveVelocity(const CommandState& x,
                                                      const Eigen::Vector2d& u) const {
  return {p_.v.time_constant_s > 0 ? x(kCmdV) : u(0),
          p_.omega.time_constant_s > 0 ? x(kCmdOmega) : u(1)};
}

CommandState CommandDrivenModel::f(const CommandState& x, const Eigen::Vector2d& u) const {
  const Eigen::Vector2d ve = effectiveVelocity(x, u);
  CommandState xd;
  xd(kCmdX) = ve(0) * std::cos(x(kCmdPhi));
  xd(kCmdY) = ve(0) * std::sin(x(kCmdPhi));
  xd(kCmdPhi) = ve(1);
  const double tv = p_.v.time_constant_s, tw = p_.omega.time_constant_s;
  xd(kCmdV) = tv > 0 ? (u(0) - x(kCmdV)) / tv : 0.0;
  xd(kCmdOmega) = tw > 0 ? (u(1) - x(kCmdOmega)) / tw : 0.0;
  return xd;
}

CommandStateJacobian CommandDrivenModel::F(const CommandState& x, const Eigen::Vector2d& u) const {
  const Eigen::Vector2d ve = effectiveVelocity(x, u);
  const double c = std::cos(x(kCmdPhi)), s = std::sin(x(kCmdPhi));
  const double tv = p_.v.time_constant_s, tw = p_.omega.time_constant_s;
  CommandStateJacobian J = CommandStateJacobian::Zero();
  J(kCmdX, kCmdPhi) = -ve(0) * s;
  J(kCmdY, kCmdPhi) = ve(0) * c;
  if (tv > 0) {
    J(kCmdX, kCmdV) = c;
    J(kCmdY, kCmdV) = s;
    J(kCmdV, kCmdV) = -1.0 / tv;
  }
  if (tw > 0) {
    J(kCmdPhi, kCmdOmega) = 1.0;
    J(kCmdOmega, kCmdOmega) = -1.0 / tw;
  }
  return J;
}

CommandInputJacobian CommandDrivenModel::G(const CommandState& x, const Eigen::Vector2d&) const {
  const double c = std::cos(x(kCmdPhi)), s = std::sin(x(kCmdPhi));
  const double tv = p_.v.time_constant_s, tw = p_.omega.time_constant_s;
  CommandInputJacobian J = CommandInputJacobian::Zero();
  if (tv > 0) {
    J(kCmdV, 0) = 1.0 / tv;
  } else {
    J(kCmdX, 0) = c;
    J(kCmdY, 0) = s;
  }
  if (tw > 0)
    J(kCmdOmega, 1) = 1.0 / tw;
  else
    J(kCmdPhi, 1) = 1.0;
  return J;
}

LagStep lagStep(double y, double c, double dt, double tau) {
  if (tau <= 0) return {c, c * dt};
  const double a = std::exp(-dt / tau);
  return {c + (y - c) * a, c * dt + (y - c) * tau * (1 - a)};
}

CommandState CommandDrivenModel::step(const CommandState& x, const Eigen::Vector2d& u,
                                      double dt) const {
  // Velocities: exact for constant u. Pose: RK4 with the exact velocity at the stage times.
  const double tv = p_.v.time_constant_s, tw = p_.omega.time_constant_s;
  const double v0 = tv > 0 ? x(kCmdV) : u(0), w0 = tw > 0 ? x(kCmdOmega) : u(1);
  const auto vel = [&](double h) -> Eigen::Vector2d {
    return {tv > 0 ? u(0) + (v0 - u(0)) * std::exp(-h / tv) : u(0),
            tw > 0 ? u(1) + (w0 - u(1)) * std::exp(-h / tw) : u(1)};
  };
  // Heading: exact integral of omega.
  const auto phiAt = [&](double h) {
    return x(kCmdPhi) + (tw > 0 ? u(1) * h + (w0 - u(1)) * tw * (1 - std::exp(-h / tw)) : u(1) * h);
  };
  const auto pd = [&](double h) -> Eigen::Vector2d {
    const double v = vel(h)(0), p = phiAt(h);
    return {v * std::cos(p), v * std::sin(p)};
  };
  const Eigen::Vector2d k1 = pd(0), k2 = pd(dt / 2), k4 = pd(dt);
  CommandState out = x;
  out.head<2>() += dt / 6 * (k1 + 4 * k2 + k4);
  out(kCmdPhi) = phiAt(dt);
  const Eigen::Vector2d v1 = vel(dt);
  out(kCmdV) = tv > 0 ? v1(0) : u(0);
  out(kCmdOmega) = tw > 0 ? v1(1) : u(1);
  return out;
}

const std::array<const char*, kNumCommandFeatures>& commandFeatureNames() {
  static const std::array<const char*, kNumCommandFeatures> n = {
      "1", "v_cmd", "omega_cmd", "|omega_cmd|", "v_cmd*|omega_cmd|"};
  return n;
}

Eigen::Matrix<double, kNumCommandFeatures, 1> commandFeatures(const Eigen::Vector2d& c) {
  return (Eigen::Matrix<double, kNumCommandFeatures, 1>() << 1, c(0), c(1), std::abs(c(1)),
          c(0) * std::abs(c(1)))
      .finished();
}

}  // namespace wheelchair::model
