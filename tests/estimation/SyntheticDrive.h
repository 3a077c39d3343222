// A small, self-contained generator of synthetic recordings FROM THE FILTER'S OWN MODEL, with
// known noise, for consistency tests (the project simulator in libwheelchair/simulation is a
// richer "reality" on purpose, so NEES/NIS checks need this one).
//
// Truth: (6) with white process noise of densities (q_v, q_omega) on vdot, omegadot
// (Euler-Maruyama, 1 ms), pose (1) by the arc formula, wheel angles from the rim speeds plus a
// white rim-speed noise (encoder "slip", density chosen so that its interval mean has 1 sigma
// `encoder_extra_noise_m_s` at 50 Hz), a static obstacle in the start frame.
// Sensors on the 1 ms grid with their own phases: motors 100 Hz (current + N(0, sigma_i)),
// gyro 100 Hz, encoders 50 Hz (floor of the wheel angle in ticks), sonar 10 Hz (range from the
// sonar mount + N(0, sigma_s); 0 outside [min, max] or when forced), optional Pozyx 10 Hz.
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/estimation/EkfOptions.h"
#include "libwheelchair/io/Recording.h"
#include "libwheelchair/model/Kinematics.h"
#include "libwheelchair/model/VehicleParams.h"
#include "libwheelchair/sensors/Encoders.h"

#include <Eigen/Core>

#include <cmath>
#include <cstdint>
#include <functional>
#include <random>
#include <set>
#include <vector>

namespace wheelchair::estimation::test {

struct SynthOptions {
  double duration_s = 20.0;
  double q_v = 0.01, q_omega = 0.02;  ///< process-noise densities of the truth
  double current_noise_A = 0.1;
  double gyro_noise_rad_s = 0.005;
  double sonar_noise_m = 0.02;
  double pozyx_noise_m = 0.1;
  double encoder_extra_noise_m_s = 0.005;  ///< 1 sigma of the interval mean at 50 Hz, per wheel
  double left_encoder_scale = 1.0;         ///< fault: left ticks scaled
  double right_encoder_scale = 1.0;        ///< right ticks scaled (a rolling-radius error)
  /// A slowly varying yaw-acceleration error of the model (rad/s^2, amplitude) while moving:
  /// omegadot += a sin(0.23 t + yaw_error_phase), the kind of sustained yaw moment (6) leaves
  /// out (one gearbox stiffer, the centre of mass ahead of the axle); 0 = none.
  double yaw_accel_error_rad_s2 = 0.0;
  double yaw_error_phase = 0.0;
  /// A yaw-acceleration error that follows the manoeuvre (1/m): omegadot += -kappa v omega,
  /// the centre of mass a distance d ahead of the axle (kappa = m d / I_z); 0 = none.
  double yaw_accel_per_v_omega_1_m = 0.0;
  Eigen::Vector2d obstacle_world{3.0, 0.6};
  bool sonar_cone = false;           ///< only see the obstacle inside the 15 deg cone
  std::set<int> forced_sonar_zeros;  ///< indices of sonar samples that read 0
  bool pozyx = false;
  double start_pause_s = 1.0;
  /// Motor currents (A) as a function of time since the start (after the pause).
  std::function<Eigen::Vector2d(double)> currents;
};

struct TruthPoint {
  double t_s;
  double v, omega, x, y, phi;
};

struct SynthRun {
  io::Recording rec;
  std::vector<TruthPoint> truth;  ///< every 1 ms
  double t_start = 0;
  /// Truth at a grid time.
  const TruthPoint& at(double t) const {
    long k = std::lround((t - t_start) / 1e-3);
    if (k < 0) k = 0;
    if (k >= static_cast<long>(truth.size())) k = static_cast<long>(truth.size()) - 1;
    return truth[static_cast<std::size_t>(k)];
  }
  /// Canonical truth [v, omega, x, y, phi, px, py] (obstacle in the base frame).
  Eigen::Matrix<double, 7, 1> canonical(double t, const Eigen::Vector2d& obst) const {
    const TruthPoint& p = at(t);
    const double c = std::cos(p.phi), s = std::sin(p.phi);
    const Eigen::Vector2d d = obst - Eigen::Vector2d(p.x, p.y);
    Eigen::Matrix<double, 7, 1> x;
    x << p.v, p.omega, p.x, p.y, p.phi, c * d.x() + s * d.y(), -s * d.x() + c * d.y();
    return x;
  }
};

/// A curvy drive: i_R + i_L = sum_mean (1 + 0.3 sin), i_R - i_L = two sines. With the nominal
/// vehicle sum_mean = 2.4 A gives v ~ 0.45 m/s, diff_amp = 0.55 A gives omega ~ +-0.35 rad/s.
inline std::function<Eigen::Vector2d(double)> curvyCurrents(double phase, double sum_mean = 2.4,
                                                            double diff_amp = 0.55) {
  return [=](double t) {
    const double sum = sum_mean * (1.0 + 0.33 * std::sin(0.31 * t + phase));
    const double diff =
        diff_amp * std::sin(0.45 * t + 0.7 * phase) + 0.36 * diff_amp * std::sin(1.3 * t);
    return Eigen::Vector2d(0.5 * (sum + diff), 0.5 * (sum - diff));
  };
}

/// The nominal vehicle, built once for all tests.
inline const config::WheelchairConfig& nominal() {
  static const config::WheelchairConfig cfg;
  return cfg;
}

/// The filter's priors as the synthetic truth has them: the obstacle at obstacle_world (m, start
/// frame) with 0.1 m / 2 deg of prior sd. The pose starts exactly at the start frame's origin
/// (the frame IS the initial pose), which the shipped initial_sigma_xy_m / _phi_rad (1e-6: P
/// stays invertible) already say: kept as configured, so the Monte-Carlo tests check them.
inline void setPriorsOfTheTruth(EkfOptions& o, const Eigen::Vector2d& obstacle_world) {
  o.initial_obstacle = ObstacleInit::Config;
  o.initial_obstacle_x_m = obstacle_world.x();
  o.initial_obstacle_y_m = obstacle_world.y();
  o.initial_obstacle_range_sigma_m = 0.1;
  o.initial_obstacle_bearing_sigma_deg = 2.0;
}

/// A curvy drive of duration_s (curvyCurrents(0.3, 1.6, 0.4)) past an obstacle at (2.5, 0.2) m
/// that the sonar sees only inside its cone.
inline SynthOptions curvyDrive(double duration_s) {
  SynthOptions so;
  so.duration_s = duration_s;
  so.currents = curvyCurrents(0.3, 1.6, 0.4);
  so.obstacle_world = Eigen::Vector2d(2.5, 0.2);
  so.sonar_cone = true;
  return so;
}

inline SynthRun synthesize(const config::WheelchairConfig& cfg, const SynthOptions& o,
                           uint64_t seed) {
  const model::OdeCoefficients a =
      model::odeCoefficients(cfg.vehicle.geom, model::lumpedTheta(cfg.vehicle));
  const double r = cfg.vehicle.geom.wheel_radius_m, lw = cfg.vehicle.geom.track_width_m;
  const double rad_per_tick = cfg.encoders.params.wheelRadPerTick();
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> N01(0.0, 1.0);
  const double dt = 1e-3;
  const long steps = std::lround(o.duration_s / dt);
  SynthRun run;
  run.t_start = 100.0;  // recording clock does not start at 0
  auto cur = [&](double t) -> Eigen::Vector2d {
    if (t < o.start_pause_s) return Eigen::Vector2d::Zero();
    const double ramp = std::min(1.0, (t - o.start_pause_s) / 1.0);
    return ramp * o.currents(t - o.start_pause_s);
  };
  // Encoder slip noise density per wheel: sigma^2 of the 20 ms mean = q / 0.02.
  const double q_slip = o.encoder_extra_noise_m_s * o.encoder_extra_noise_m_s * 0.02;
  double v = 0, om = 0;
  Eigen::Vector3d pose = Eigen::Vector3d::Zero();
  double psiR = 0, psiL = 0;
  int sonar_index = 0;
  const Eigen::Vector2d sonar_mount(cfg.sonar.x_m, cfg.sonar.y_m);
  for (long k = 0; k <= steps; ++k) {
    const double tr = k * dt, t = run.t_start + tr;
    run.truth.push_back({t, v, om, pose(0), pose(1), pose(2)});
    const Eigen::Vector2d i_true = cur(tr);
    // Sensors at this grid time.
    if (k % 10 == 5) {
      io::MotorSample m;
      m.t_s = t;
      m.current_right_A = i_true(0) + o.current_noise_A * N01(rng);
      m.current_left_A = i_true(1) + o.current_noise_A * N01(rng);
      run.rec.motors.push_back(m);
    }
    if (k % 10 == 1) run.rec.imu.push_back({t, om + o.gyro_noise_rad_s * N01(rng)});
    if (k % 20 == 3) {
      const auto ticks = [&](double psi) {
        return sensors::toHardwareCounter(static_cast<int64_t>(std::floor(psi / rad_per_tick)));
      };
      run.rec.encoders.push_back(
          {t, ticks(o.right_encoder_scale * psiR), ticks(o.left_encoder_scale * psiL)});
    }
    if (k % 100 == 7) {
      const double c = std::cos(pose(2)), s = std::sin(pose(2));
      const Eigen::Vector2d d = o.obstacle_world - pose.head<2>();
      const Eigen::Vector2d pb(c * d.x() + s * d.y(), -s * d.x() + c * d.y());
      const Eigen::Vector2d rel = pb - sonar_mount;
      double range = rel.norm() + o.sonar_noise_m * N01(rng);
      const bool in_cone =
          std::fabs(std::atan2(rel.y(), rel.x())) <= cfg.sonar.cone_half_angle_deg * M_PI / 180;
      if (range < cfg.sonar.min_range_m || range > cfg.sonar.max_range_m ||
          (o.sonar_cone && !in_cone) || o.forced_sonar_zeros.count(sonar_index))
        range = 0.0;
      run.rec.sonar.push_back({t, range});
      ++sonar_index;
    }
    if (o.pozyx && k % 100 == 9) {
      const double c = std::cos(pose(2)), s = std::sin(pose(2));
      const Eigen::Vector2d l(cfg.pozyx.lever_x_m, cfg.pozyx.lever_y_m);
      io::PozyxSample p;
      p.t_s = t;
      p.x_m = pose(0) + c * l.x() - s * l.y() + o.pozyx_noise_m * N01(rng);
      p.y_m = pose(1) + s * l.x() + c * l.y() + o.pozyx_noise_m * N01(rng);
      run.rec.pozyx.push_back(p);
    }
    if (k == steps) break;
    // Truth step: (6) with white noise (Euler-Maruyama), input at the midpoint.
    const Eigen::Vector2d im = cur(tr + 0.5 * dt);
    const bool moving = tr >= o.start_pause_s;
    const double v1 = v + dt * (a.a3 * v + a.a1 * (im(0) + im(1))) +
                      (moving ? std::sqrt(o.q_v * dt) * N01(rng) : 0.0);
    const double yaw_err =
        moving ? o.yaw_accel_error_rad_s2 * std::sin(0.23 * tr + o.yaw_error_phase) -
                     o.yaw_accel_per_v_omega_1_m * v * om
               : 0.0;
    const double om1 = om + dt * (a.a4 * om + a.a2 * (im(0) - im(1)) + yaw_err) +
                       (moving ? std::sqrt(o.q_omega * dt) * N01(rng) : 0.0);
    const double vm = 0.5 * (v + v1), omm = 0.5 * (om + om1);
    pose = model::integratePoseArc(pose, vm, omm, dt);
    // Wheel angles (continuous phi is not needed: only increments).
    const double slipR = moving ? std::sqrt(q_slip / dt) * N01(rng) : 0.0;
    const double slipL = moving ? std::sqrt(q_slip / dt) * N01(rng) : 0.0;
    psiR += dt * (vm + 0.5 * lw * omm + slipR) / r;
    psiL += dt * (vm - 0.5 * lw * omm + slipL) / r;
    v = v1;
    om = om1;
  }
  return run;
}

}  // namespace wheelchair::estimation::test
