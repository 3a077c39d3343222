#include "libwheelchair/estimation/CommandDrivenEkf.h"

#include "libwheelchair/estimation/ChiSquare.h"

#include <mrpt/config/CConfigFile.h>

#include <Eigen/Dense>

#include <cmath>
#include <filesystem>
#include <map>
#include <stdexcept>

namespace wheelchair::estimation {

namespace {
constexpr double kPi = 3.14159265358979323846;
double wrap(double a) {
  return std::remainder(a, 2 * kPi);
}
}  // namespace

CommandDrivenEkfOptions loadCommandDrivenEkfOptions(const std::string& path) {
  if (!std::filesystem::exists(path)) throw std::runtime_error(path + ": no such file");
  mrpt::config::CConfigFile ini(path);
  CommandDrivenEkfOptions o;
  const std::string f = "mrclam_filter", r = "mrclam_response";
  o.dt_s = ini.read_double(f, "dt_s", o.dt_s);
  o.output_every_s = ini.read_double(f, "output_every_s", o.output_every_s);
  o.q_v = std::pow(ini.read_double(f, "v_noise_m_s_sqrt_s", std::sqrt(o.q_v)), 2);
  o.q_omega = std::pow(ini.read_double(f, "omega_noise_rad_s_sqrt_s", std::sqrt(o.q_omega)), 2);
  o.range_sigma_m = ini.read_double(f, "range_sigma_m", o.range_sigma_m);
  o.bearing_sigma_rad = ini.read_double(f, "bearing_sigma_rad", o.bearing_sigma_rad);
  o.gate_probability = ini.read_double(f, "gate_probability", o.gate_probability);
  o.init_window_s = ini.read_double(f, "init_window_s", o.init_window_s);
  o.init_min_separation_m = ini.read_double(f, "init_min_separation_m", o.init_min_separation_m);
  o.init_sigma_xy_m = ini.read_double(f, "init_sigma_xy_m", o.init_sigma_xy_m);
  o.init_sigma_phi_rad = ini.read_double(f, "init_sigma_phi_rad", o.init_sigma_phi_rad);
  auto& p = o.response;
  p.v.delay_s = ini.read_double(r, "v_delay_s", 0);
  p.v.time_constant_s = ini.read_double(r, "v_time_constant_s", 0);
  p.v.deadband = ini.read_double(r, "v_deadband_m_s", 0);
  p.omega.delay_s = ini.read_double(r, "omega_delay_s", 0);
  p.omega.time_constant_s = ini.read_double(r, "omega_time_constant_s", 0);
  p.omega.deadband = ini.read_double(r, "omega_deadband_rad_s", 0);
  using K = model::CommandKind;
  p.v_gain[static_cast<int>(K::Straight)] = ini.read_double(r, "v_gain_straight", 1);
  p.v_gain[static_cast<int>(K::Arc)] = ini.read_double(r, "v_gain_arc", 1);
  p.v_gain_backward = ini.read_double(r, "v_gain_backward", 1);
  p.omega_gain[static_cast<int>(K::TurnInPlace)] =
      ini.read_double(r, "omega_gain_turn_in_place", 1);
  p.omega_gain[static_cast<int>(K::Arc)] = ini.read_double(r, "omega_gain_arc", 1);
  o.ignore_zero_runs = ini.read_bool(r, "ignore_zero_runs", false);
  o.max_zero_run_s = ini.read_double(r, "max_zero_run_s", o.max_zero_run_s);
  return o;
}

Eigen::Vector2d rangeBearing(const model::CommandState& x, const Eigen::Vector2d& L,
                             Eigen::Matrix<double, 2, 5>* H) {
  const double dx = L(0) - x(0), dy = L(1) - x(1);
  const double q = dx * dx + dy * dy, r = std::sqrt(q);
  if (H) {
    H->setZero();
    (*H)(0, 0) = -dx / r;
    (*H)(0, 1) = -dy / r;
    (*H)(1, 0) = dy / q;
    (*H)(1, 1) = -dx / q;
    (*H)(1, 2) = -1;
  }
  return {r, wrap(std::atan2(dy, dx) - x(2))};
}

CommandDrivenEkfResult runCommandDrivenEkf(const io::Recording& rec,
                                           const std::vector<io::LandmarkPosition>& map,
                                           const CommandDrivenEkfOptions& o) {
  using model::CommandState;
  CommandDrivenEkfResult res;
  std::map<int, Eigen::Vector2d> L;
  for (const auto& m : map) L[m.id] = {m.x_m, m.y_m};
  if (L.empty()) throw std::invalid_argument("runCommandDrivenEkf: empty landmark map");
  std::vector<io::LandmarkSample> z;
  for (const auto& s : rec.landmarks) {
    if (L.count(s.landmark_id))
      z.push_back(s);
    else
      ++res.unmapped;
  }
  // Initialisation from two sightings of well separated landmarks.
  std::size_t start = z.size();
  CommandState x = CommandState::Zero();
  for (std::size_t i = 0; i < z.size() && start == z.size(); ++i)
    for (std::size_t j = i + 1; j < z.size() && z[j].t_s - z[i].t_s <= o.init_window_s; ++j) {
      const Eigen::Vector2d Li = L[z[i].landmark_id], Lj = L[z[j].landmark_id];
      if ((Lj - Li).norm() < o.init_min_separation_m) continue;
      const Eigen::Vector2d bi =
          z[i].range_m * Eigen::Vector2d(std::cos(z[i].bearing_rad), std::sin(z[i].bearing_rad));
      const Eigen::Vector2d bj =
          z[j].range_m * Eigen::Vector2d(std::cos(z[j].bearing_rad), std::sin(z[j].bearing_rad));
      const double phi =
          wrap(std::atan2(Lj(1) - Li(1), Lj(0) - Li(0)) - std::atan2(bj(1) - bi(1), bj(0) - bi(0)));
      const Eigen::Vector2d p = Lj - Eigen::Vector2d(std::cos(phi) * bj(0) - std::sin(phi) * bj(1),
                                                     std::sin(phi) * bj(0) + std::cos(phi) * bj(1));
      x << p(0), p(1), phi, 0, 0;
      start = j + 1;
      res.t_start_s = z[j].t_s;
      break;
    }
  if (start >= z.size()) return res;
  res.initialised = true;
  Eigen::Matrix<double, 5, 5> P = Eigen::Matrix<double, 5, 5>::Zero();
  P(0, 0) = P(1, 1) = o.init_sigma_xy_m * o.init_sigma_xy_m;
  P(2, 2) = o.init_sigma_phi_rad * o.init_sigma_phi_rad;
  P(3, 3) = 0.05 * 0.05;
  P(4, 4) = 0.2 * 0.2;

  std::vector<io::JoystickSample> js = rec.joystick;
  std::vector<model::CommandSample> rows;
  for (const auto& j : js) rows.push_back({j.t_s, j.v_cmd_m_s, j.omega_cmd_rad_s});
  model::CommandSignalOptions so;
  so.drop_short_zero_runs = o.ignore_zero_runs;
  so.max_zero_run_s = o.max_zero_run_s;
  const model::CommandSignal sig(rows, so);
  const model::CommandDrivenModel mdl(o.response);
  const bool lag_v = o.response.v.time_constant_s > 0, lag_w = o.response.omega.time_constant_s > 0;
  // Velocity states: start at the model's response (integrated from the first command).
  {
    double yv = 0, yw = 0;
    for (double t = sig.startTime(); t < res.t_start_s; t += o.dt_s) {
      const Eigen::Vector2d u = mdl.target(sig, t + o.dt_s / 2);
      yv = model::lagStep(yv, u(0), o.dt_s, o.response.v.time_constant_s).y_next;
      yw = model::lagStep(yw, u(1), o.dt_s, o.response.omega.time_constant_s).y_next;
    }
    x(3) = yv;
    x(4) = yw;
  }
  const double gate = o.gate_probability > 0 ? chi2Quantile(o.gate_probability, 2) : 0.0;
  Eigen::Matrix2d R =
      Eigen::Vector2d(o.range_sigma_m * o.range_sigma_m, o.bearing_sigma_rad * o.bearing_sigma_rad)
          .asDiagonal();
  double t = res.t_start_s, next_out = t;
  const double t_end = std::max(sig.endTime(), z.empty() ? t : z.back().t_s);
  double nis_sum = 0;
  const auto emit = [&] {
    res.trajectory.push_back({t, x(0), x(1), wrap(x(2)), P(0, 0), P(1, 1), P(0, 1), P(2, 2)});
  };
  emit();
  next_out += o.output_every_s;
  std::size_t k = start;
  const auto propagateTo = [&](double t1) {
    while (t < t1 - 1e-12) {
      const double h = std::min(o.dt_s, t1 - t);
      const Eigen::Vector2d u = mdl.target(sig, t + h / 2);
      const auto Fc = mdl.F(x, u);
      const Eigen::Matrix<double, 5, 5> A = Fc * h;
      const Eigen::Matrix<double, 5, 5> Phi =
          Eigen::Matrix<double, 5, 5>::Identity() + A + 0.5 * A * A;
      // Noise input: on the pose rates (unmodelled velocity error, both forms) and, for a
      // lagged channel, also on its velocity state.
      Eigen::Matrix<double, 5, 4> Gw = Eigen::Matrix<double, 5, 4>::Zero();
      const double c = std::cos(x(2)), s = std::sin(x(2));
      Gw(0, 0) = c;
      Gw(1, 0) = s;
      Gw(2, 1) = 1;
      if (lag_v) Gw(3, 2) = 1;
      if (lag_w) Gw(4, 3) = 1;
      const Eigen::Matrix4d Qc = Eigen::Vector4d(o.q_v, o.q_omega, o.q_v, o.q_omega).asDiagonal();
      x = mdl.step(x, u, h);
      P = Phi * P * Phi.transpose() + Gw * Qc * Gw.transpose() * h;
      P = 0.5 * (P + P.transpose());
      t += h;
      if (t >= next_out - 1e-9) {
        emit();
        next_out += o.output_every_s;
      }
    }
  };
  for (; k < z.size(); ++k) {
    propagateTo(z[k].t_s);
    Eigen::Matrix<double, 2, 5> H;
    const Eigen::Vector2d h = rangeBearing(x, L[z[k].landmark_id], &H);
    Eigen::Vector2d y(z[k].range_m - h(0), wrap(z[k].bearing_rad - h(1)));
    const Eigen::Matrix2d S = H * P * H.transpose() + R;
    const double nis = y.dot(S.ldlt().solve(y));
    if (gate > 0 && nis > gate) {
      ++res.rejected;
      continue;
    }
    const Eigen::Matrix<double, 5, 2> K = P * H.transpose() * S.inverse();
    x += K * y;
    const Eigen::Matrix<double, 5, 5> IKH = Eigen::Matrix<double, 5, 5>::Identity() - K * H;
    P = IKH * P * IKH.transpose() + K * R * K.transpose();
    ++res.accepted;
    nis_sum += nis;
  }
  propagateTo(t_end);
  res.mean_nis = res.accepted ? nis_sum / res.accepted : 0;
  return res;
}

}  // namespace wheelchair::estimation
