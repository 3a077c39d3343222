// A small stand-alone drive generator for the identification tests (test_identification links
// only wc_identification and what it depends on, not the simulator): model::DriveTrain
// integrated by RK4 at 1 ms, a PI rim-speed loop per wheel tracking a demand, and the sensor
// forward models of sensors/ (encoder ticks at 50 Hz, gyro and currents at 100 Hz, the
// differential V_RC of each motor from the voltage circuit with its Zener knee), with
// Gaussian noise of the configured size and +-2 ms jitter on every sampling instant.
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/io/Recording.h"
#include "libwheelchair/model/DriveDynamics.h"
#include "libwheelchair/sensors/Encoders.h"
#include "libwheelchair/sensors/VoltageCircuit.h"

#include <cmath>
#include <functional>
#include <random>

namespace wheelchair::test {

struct Demand {
  double v = 0, omega = 0;
};

/// Persistently exciting demand: multisines in v and omega plus steps, brief stops.
inline std::function<Demand(double)> excitingDemand(uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> ph(0, 2 * M_PI);
  const double p[6] = {ph(rng), ph(rng), ph(rng), ph(rng), ph(rng), ph(rng)};
  return [=](double t) {
    if (t < 1.0) return Demand{};
    const double v = 0.35 + 0.25 * std::sin(0.31 * t + p[0]) + 0.15 * std::sin(1.3 * t + p[1]) +
                     0.1 * (std::fmod(t, 7.0) < 3.5 ? 1 : -1) + 0.05 * std::sin(2.9 * t + p[2]);
    const double w = 0.4 * std::sin(0.23 * t + p[3]) + 0.25 * std::sin(1.1 * t + p[4]) +
                     0.15 * (std::fmod(t + 2.0, 5.0) < 2.5 ? 1 : -1) +
                     0.08 * std::sin(2.3 * t + p[5]);
    return Demand{v, w};
  };
}

/// Straight only: wait, accelerate to 0.8 m/s, cruise, stop, wait, go again.
inline std::function<Demand(double)> straightDemand() {
  return [](double t) {
    const double tt = std::fmod(t, 20.0);
    return Demand{(tt > 1.0 && tt < 14.0) ? 0.8 : 0.0, 0.0};
  };
}

struct GeneratorOptions {
  double duration_s = 120;
  uint64_t seed = 1;
  double accel_limit_m_s2 = 0.8;  ///< rate limit of the rim-speed references
  double kp_A_s_m = 60, ki_A_m = 150;
};

inline io::Recording generateDrive(const config::WheelchairConfig& cfg, const model::DriveTrain& dt,
                                   const std::function<Demand(double)>& demand,
                                   const GeneratorOptions& o) {
  std::mt19937_64 rng(o.seed * 7919 + 13);
  std::normal_distribution<double> N(0, 1);
  std::uniform_real_distribution<double> J(-0.002, 0.002);
  const double h = 0.001, lw = dt.geom.track_width_m, r = dt.geom.wheel_radius_m;
  const double rG = dt.geom.gear_ratio, Rm = cfg.vehicle.armature_resistance_ohm;
  const auto& vc = cfg.motors.circuit;
  io::Recording rec;
  model::MotionState s;
  double psi[2] = {0, 0}, ref[2] = {0, 0}, integ[2] = {0, 0};
  double next_enc = 0.02 + J(rng), next_imu = 0.01 + J(rng), next_mot = 0.005 + J(rng);
  const long n = static_cast<long>(o.duration_s / h);
  for (long k = 0; k < n; ++k) {
    const double t = k * h;
    const Demand d = demand(t);
    const double u[2] = {s.v_m_s + lw * s.omega_rad_s / 2, s.v_m_s - lw * s.omega_rad_s / 2};
    Eigen::Vector2d I;
    for (int i = 0; i < 2; ++i) {
      const double target = d.v + (i == 0 ? 1 : -1) * lw * d.omega / 2;
      ref[i] += std::clamp(target - ref[i], -o.accel_limit_m_s2 * h, o.accel_limit_m_s2 * h);
      const double e = ref[i] - u[i];
      integ[i] += e * h;
      I(i) = std::clamp(o.kp_A_s_m * e + o.ki_A_m * integ[i], -30.0, 30.0);
    }
    // Sensors sampled at their (jittered) instants within this step (state held).
    auto Uof = [&](int i) { return Rm * I(i) + dt.side[i].torque_constant_Nm_A * rG * u[i] / r; };
    while (next_enc <= t) {
      rec.encoders.push_back(
          {next_enc, static_cast<int32_t>(sensors::wheelAngleToTicks(psi[0], cfg.encoders.params)),
           static_cast<int32_t>(sensors::wheelAngleToTicks(psi[1], cfg.encoders.params))});
      next_enc = std::max(next_enc + 0.02 + J(rng), next_enc + 0.015);
    }
    while (next_imu <= t) {
      rec.imu.push_back({next_imu, s.omega_rad_s + cfg.imu.gyro_noise_rad_s * N(rng)});
      next_imu = std::max(next_imu + 0.01 + J(rng), next_imu + 0.006);
    }
    while (next_mot <= t) {
      io::MotorSample m;
      m.t_s = next_mot;
      m.current_right_A = I(0) + cfg.motors.current_noise_A * N(rng);
      m.current_left_A = I(1) + cfg.motors.current_noise_A * N(rng);
      double vrc[2];
      for (int i = 0; i < 2; ++i) {
        const double U = Uof(i);  // RC time constant 0.17 ms << 1 ms: steady state per wire
        vrc[i] = sensors::steadyStateVrc(std::max(U, 0.0), vc) -
                 sensors::steadyStateVrc(std::max(-U, 0.0), vc);
      }
      m.vrc_right_V = vrc[0] + cfg.motors.vrc_noise_V * N(rng);
      m.vrc_left_V = vrc[1] + cfg.motors.vrc_noise_V * N(rng);
      rec.motors.push_back(m);
      next_mot = std::max(next_mot + 0.01 + J(rng), next_mot + 0.006);
    }
    // RK4 of (v, omega, phi) and the wheel angles with the currents held.
    auto f = [&](const Eigen::Vector3d& x) {
      const Eigen::Vector2d a = dt.acceleration({x(0), x(1), x(2)}, I);
      return Eigen::Vector3d(a(0), a(1), x(1));
    };
    const Eigen::Vector3d x0(s.v_m_s, s.omega_rad_s, s.phi_rad);
    const Eigen::Vector3d k1 = f(x0), k2 = f(x0 + h / 2 * k1), k3 = f(x0 + h / 2 * k2),
                          k4 = f(x0 + h * k3);
    const Eigen::Vector3d x1 = x0 + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
    for (int i = 0; i < 2; ++i) {
      const double sg = i == 0 ? 1 : -1;
      psi[i] += h / 2 * ((x0(0) + sg * lw * x0(1) / 2) + (x1(0) + sg * lw * x1(1) / 2)) / r;
    }
    s = {x1(0), x1(1), x1(2)};
  }
  return rec;
}

}  // namespace wheelchair::test
