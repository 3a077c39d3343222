// The truth simulator: agreement with the ODE form (6), each effect changing exactly what it
// should, supervisory control, determinism, scenarios, truth files.
#include "SimTestUtil.h"

#include "libwheelchair/model/Kinematics.h"
#include "libwheelchair/model/VehicleParams.h"
#include "libwheelchair/sensors/Encoders.h"
#include "libwheelchair/sensors/VoltageCircuit.h"

#include <gtest/gtest.h>
#include <mrpt/config/CConfigFileMemory.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>

using namespace wheelchair;
using namespace wheelchair::simulation;
using wheelchair::simulation::test::rms;
using wheelchair::simulation::test::run;

namespace {

void expectSameImu(const io::Recording& a, const io::Recording& b) {
  ASSERT_EQ(a.imu.size(), b.imu.size());
  for (std::size_t i = 0; i < a.imu.size(); ++i) {
    EXPECT_EQ(a.imu[i].t_s, b.imu[i].t_s);
    EXPECT_EQ(a.imu[i].gyro_z_rad_s, b.imu[i].gyro_z_rad_s);
  }
}
void expectSameEncoders(const io::Recording& a, const io::Recording& b) {
  ASSERT_EQ(a.encoders.size(), b.encoders.size());
  for (std::size_t i = 0; i < a.encoders.size(); ++i) {
    EXPECT_EQ(a.encoders[i].t_s, b.encoders[i].t_s);
    EXPECT_EQ(a.encoders[i].right_ticks, b.encoders[i].right_ticks);
    EXPECT_EQ(a.encoders[i].left_ticks, b.encoders[i].left_ticks);
  }
}
void expectSameMotors(const io::Recording& a, const io::Recording& b) {
  ASSERT_EQ(a.motors.size(), b.motors.size());
  for (std::size_t i = 0; i < a.motors.size(); ++i) {
    EXPECT_EQ(a.motors[i].t_s, b.motors[i].t_s);
    EXPECT_EQ(a.motors[i].current_right_A, b.motors[i].current_right_A);
    EXPECT_EQ(a.motors[i].current_left_A, b.motors[i].current_left_A);
    EXPECT_EQ(a.motors[i].vrc_right_V, b.motors[i].vrc_right_V);
  }
}
void expectSameSonarPozyx(const io::Recording& a, const io::Recording& b) {
  ASSERT_EQ(a.sonar.size(), b.sonar.size());
  for (std::size_t i = 0; i < a.sonar.size(); ++i) {
    EXPECT_EQ(a.sonar[i].t_s, b.sonar[i].t_s);
    EXPECT_EQ(a.sonar[i].range_m, b.sonar[i].range_m);
  }
  ASSERT_EQ(a.pozyx.size(), b.pozyx.size());
  for (std::size_t i = 0; i < a.pozyx.size(); ++i) {
    EXPECT_EQ(a.pozyx[i].x_m, b.pozyx[i].x_m);
    EXPECT_EQ(a.pozyx[i].y_m, b.pozyx[i].y_m);
  }
}
void expectSameTruth(const TruthTrajectory& a, const TruthTrajectory& b) {
  ASSERT_EQ(a.samples.size(), b.samples.size());
  for (std::size_t i = 0; i < a.samples.size(); ++i) {
    EXPECT_EQ(a.samples[i].x_m, b.samples[i].x_m);
    EXPECT_EQ(a.samples[i].y_m, b.samples[i].y_m);
    EXPECT_EQ(a.samples[i].phi_rad, b.samples[i].phi_rad);
    EXPECT_EQ(a.samples[i].current_right_A, b.samples[i].current_right_A);
  }
}

/// Mean of f over truth samples of the first straight leg of three_task at cruise.
template <class F>
double meanOverCruise(const SimulationResult& r, F f, double x_lo = 2.0, double x_hi = 8.0) {
  double s = 0;
  int n = 0;
  for (const auto& ts : r.truth.samples)
    if (ts.x_m > x_lo && ts.x_m < x_hi && std::abs(ts.phi_rad) < 0.5 &&
        std::abs(ts.v_m_s - 0.8) < 0.02) {
      s += f(ts);
      ++n;
    }
  EXPECT_GT(n, 100);
  return n ? s / n : 0;
}

}  // namespace

// ---------------------------------------------------------------------------------------
TEST(Simulator, NoEffectsAgreesWithOdeForm6) {
  // The nominal vehicle of the simulator (per-wheel DriveTrain, symmetric, flat floor) must
  // move as the paper's ODE (6) says when (6) is fed with the currents that drove it.
  SimulationOptions opt;
  opt.truth_rate_hz = 1.0 / opt.step_s;  // one truth sample per step: the exact ZOH currents
  const auto r = run("excite", 3, {}, 40, opt);
  const config::WheelchairConfig cfg;
  const auto a = model::odeCoefficients(cfg.vehicle.geometry(), model::lumpedTheta(cfg.vehicle));
  const auto& S = r.truth.samples;
  double v = S[0].v_m_s, w = S[0].omega_rad_s, max_dv = 0, max_dw = 0;
  for (std::size_t k = 0; k + 1 < S.size(); ++k) {
    const double h = S[k + 1].t_s - S[k].t_s;
    const double iR = S[k].current_right_A, iL = S[k].current_left_A;
    // (6) is linear: exact step for constant currents.
    const double v_inf = -a.a1 * (iR + iL) / a.a3, w_inf = -a.a2 * (iR - iL) / a.a4;
    v = v_inf + (v - v_inf) * std::exp(a.a3 * h);
    w = w_inf + (w - w_inf) * std::exp(a.a4 * h);
    max_dv = std::max(max_dv, std::abs(v - S[k + 1].v_m_s));
    max_dw = std::max(max_dw, std::abs(w - S[k + 1].omega_rad_s));
  }
  EXPECT_LT(max_dv, 1e-3);
  EXPECT_LT(max_dw, 1e-3);

  // Fed with the MEASURED currents (noise 0.1 A, 100 Hz, zero-order hold) instead: the
  // velocity error stays within what that noise explains.
  std::vector<double> ev, ew;
  v = 0, w = 0;
  std::size_t m = 0;
  const auto& M = r.recording.motors;
  for (std::size_t k = 0; k + 1 < S.size(); ++k) {
    while (m + 1 < M.size() && M[m + 1].t_s <= S[k].t_s) ++m;
    const double iR = S[k].t_s < M[0].t_s ? 0 : M[m].current_right_A;
    const double iL = S[k].t_s < M[0].t_s ? 0 : M[m].current_left_A;
    const double h = S[k + 1].t_s - S[k].t_s;
    v += h * (a.a3 * v + a.a1 * (iR + iL));
    w += h * (a.a4 * w + a.a2 * (iR - iL));
    ev.push_back(v - S[k + 1].v_m_s);
    ew.push_back(w - S[k + 1].omega_rad_s);
  }
  EXPECT_LT(rms(ev), 0.01);
  EXPECT_LT(rms(ew), 0.02);
}

TEST(Simulator, ThreeTaskReturnsNearStart) {
  const auto r = run("three_task", 1);
  EXPECT_EQ(r.collisions, 0);
  double max_x = -1e9, max_abs_y = 0;
  for (const auto& s : r.truth.samples) {
    max_x = std::max(max_x, s.x_m);
    max_abs_y = std::max(max_abs_y, std::abs(s.y_m));
  }
  EXPECT_NEAR(max_x, 10.0, 0.1);
  EXPECT_LT(max_abs_y, 0.05);
  const auto& e = r.truth.samples.back();
  EXPECT_LT(std::hypot(e.x_m, e.y_m), 0.1);
  EXPECT_NEAR(std::abs(model::wrapAngle(e.phi_rad)), M_PI, 0.05);
  EXPECT_NEAR(e.v_m_s, 0.0, 0.01);
  // Sample counts follow the configured rates.
  const double T = r.duration_s;
  EXPECT_NEAR(r.recording.encoders.size(), 50 * T, 2);
  EXPECT_NEAR(r.recording.imu.size(), 100 * T, 2);
  EXPECT_NEAR(r.recording.motors.size(), 100 * T, 2);
  EXPECT_NEAR(r.recording.sonar.size(), 10 * T, 2);
  EXPECT_NEAR(r.recording.pozyx.size(), 10 * T, 2);
  EXPECT_NEAR(r.recording.joystick.size(), 50 * T, 2);
  // Streams are asynchronous and time-ordered, with jitter.
  auto ordered = [](const auto& v) {
    for (std::size_t i = 1; i < v.size(); ++i)
      if (!(v[i].t_s > v[i - 1].t_s)) return false;
    return true;
  };
  EXPECT_TRUE(ordered(r.recording.encoders));
  EXPECT_TRUE(ordered(r.recording.imu));
  EXPECT_TRUE(ordered(r.recording.sonar));
  EXPECT_NE(r.recording.imu[0].t_s, r.recording.motors[0].t_s);
  const double d1 = r.recording.imu[1].t_s - r.recording.imu[0].t_s;
  const double d2 = r.recording.imu[2].t_s - r.recording.imu[1].t_s;
  EXPECT_NE(d1, d2);
}

TEST(Simulator, SonarSeesTheThreeTaskObstacle) {
  const auto r = run("three_task", 1);
  ASSERT_EQ(r.truth.obstacles.size(), 1u);
  const auto& o = r.truth.obstacles[0];
  int seen = 0;
  std::size_t k = 0;
  for (const auto& s : r.recording.sonar) {
    if (s.range_m == 0) continue;
    while (k + 1 < r.truth.samples.size() && r.truth.samples[k + 1].t_s <= s.t_s) ++k;
    const auto& ts = r.truth.samples[k];
    const double sx = ts.x_m + 0.45 * std::cos(ts.phi_rad),
                 sy = ts.y_m + 0.45 * std::sin(ts.phi_rad);
    EXPECT_NEAR(s.range_m, std::hypot(o.x_m - sx, o.y_m - sy) - o.radius_m, 0.1);
    ++seen;
  }
  EXPECT_GT(seen, 20);
  EXPECT_LT(seen, static_cast<int>(r.recording.sonar.size()));  // 0 when nothing in range
}

TEST(Simulator, DeterministicPerSeed) {
  const auto a = run("excite", 7, {"sonar_dropout:probability=0.2"}, 20);
  const auto b = run("excite", 7, {"sonar_dropout:probability=0.2"}, 20);
  expectSameImu(a.recording, b.recording);
  expectSameEncoders(a.recording, b.recording);
  expectSameMotors(a.recording, b.recording);
  expectSameSonarPozyx(a.recording, b.recording);
  expectSameTruth(a.truth, b.truth);
  // A different seed: different noise (same scenario structure).
  const auto c = run("three_task", 8, {}, 10);
  const auto d = run("three_task", 9, {}, 10);
  ASSERT_GT(c.recording.imu.size(), 100u);
  int differ = 0;
  for (std::size_t i = 0; i < 100; ++i)
    differ += c.recording.imu[i].gyro_z_rad_s != d.recording.imu[i].gyro_z_rad_s;
  EXPECT_GT(differ, 95);
  EXPECT_NE(c.truth.pozyx_anchor.yaw_rad, d.truth.pozyx_anchor.yaw_rad);
}

// --- effects: each changes exactly what it should ----------------------------------------
TEST(Effects, EncoderScaleScalesOnlyThatSidesTicks) {
  const auto base = run("three_task", 2);
  const auto eff = run("three_task", 2, {"encoder_scale:side=left,scale=0.95"});
  expectSameImu(base.recording, eff.recording);
  expectSameMotors(base.recording, eff.recording);
  expectSameTruth(base.truth, eff.truth);
  ASSERT_EQ(base.recording.encoders.size(), eff.recording.encoders.size());
  for (std::size_t i = 0; i < base.recording.encoders.size(); ++i) {
    const auto& b = base.recording.encoders[i];
    const auto& e = eff.recording.encoders[i];
    EXPECT_EQ(b.right_ticks, e.right_ticks);
    EXPECT_NEAR(e.left_ticks, 0.95 * b.left_ticks, 1.0 + 0.05 * 1.0);
  }
  EXPECT_GT(base.recording.encoders.back().left_ticks, 100000);
}

TEST(Effects, EncoderCountersWrapAround) {
  SimulationOptions opt;
  opt.encoder_initial_ticks_right = INT32_MAX - 1000;
  const auto base = run("three_task", 2, {}, 20);
  const auto wrap = run("three_task", 2, {}, 20, opt);
  ASSERT_EQ(base.recording.encoders.size(), wrap.recording.encoders.size());
  EXPECT_LT(wrap.recording.encoders.back().right_ticks, 0);  // wrapped past 2^31
  for (std::size_t i = 0; i < base.recording.encoders.size(); ++i) {
    const uint32_t d = static_cast<uint32_t>(wrap.recording.encoders[i].right_ticks) -
                       static_cast<uint32_t>(base.recording.encoders[i].right_ticks);
    EXPECT_EQ(d, static_cast<uint32_t>(INT32_MAX - 1000));
  }
}

TEST(Effects, GyroBiasShiftsOnlyTheGyro) {
  const auto base = run("three_task", 3);
  const auto eff = run("three_task", 3, {"gyro_bias:bias_rad_s=0.02"});
  expectSameEncoders(base.recording, eff.recording);
  expectSameMotors(base.recording, eff.recording);
  expectSameSonarPozyx(base.recording, eff.recording);
  expectSameTruth(base.truth, eff.truth);
  ASSERT_EQ(base.recording.imu.size(), eff.recording.imu.size());
  for (std::size_t i = 0; i < base.recording.imu.size(); ++i)
    EXPECT_NEAR(eff.recording.imu[i].gyro_z_rad_s - base.recording.imu[i].gyro_z_rad_s, 0.02,
                1e-12);
}

TEST(Effects, GyroScaleScalesOnlyTheRate) {
  const auto base = run("three_task", 3);
  const auto eff = run("three_task", 3, {"gyro_scale:scale=1.1"});
  expectSameEncoders(base.recording, eff.recording);
  expectSameTruth(base.truth, eff.truth);
  // eff - base = 0.1 * omega_true: regress it on base (= omega + noise) during the turn.
  double sxy = 0, sxx = 0;
  for (std::size_t i = 0; i < base.recording.imu.size(); ++i) {
    const double x = base.recording.imu[i].gyro_z_rad_s;
    if (std::abs(x) < 0.3) continue;
    sxy += x * (eff.recording.imu[i].gyro_z_rad_s - x);
    sxx += x * x;
  }
  ASSERT_GT(sxx, 1.0);
  EXPECT_NEAR(sxy / sxx, 0.1, 0.005);
}

TEST(Effects, MotorAsymmetryDifferentCurrentsStillStraight) {
  const auto base = run("three_task", 4);
  const auto eff = run("three_task", 4, {"motor_asymmetry:side=right,friction_ratio=1.5"});
  // Same joystick, more friction on the right: the right motor needs more current...
  const double d_base = meanOverCruise(
      base, [](const TruthSample& s) { return s.current_right_A - s.current_left_A; });
  const double d_eff = meanOverCruise(
      eff, [](const TruthSample& s) { return s.current_right_A - s.current_left_A; });
  EXPECT_NEAR(d_base, 0.0, 0.02);
  // B_m/k_m r_G/r u * 0.5 = 2.3e-3/0.09 * 18/0.17 * 0.8 * 0.5 = 1.08 A
  EXPECT_NEAR(d_eff, 1.08, 0.1);
  // ...also in the recorded (noisy) currents,
  double mr = 0, ml = 0;
  int n = 0;
  for (const auto& m : eff.recording.motors)
    if (m.t_s > 4 && m.t_s < 10) mr += m.current_right_A, ml += m.current_left_A, ++n;
  EXPECT_GT((mr - ml) / n, 0.8);
  // ...while the closed loop keeps the chair going straight and back to the start.
  for (const auto& s : eff.truth.samples) EXPECT_LT(std::abs(s.y_m), 0.05);
  const auto& e = eff.truth.samples.back();
  EXPECT_LT(std::hypot(e.x_m, e.y_m), 0.1);
}

TEST(Effects, CoulombFrictionCostsCurrent) {
  const auto base = run("three_task", 5);
  const auto eff = run("three_task", 5, {"coulomb_friction:current_A=1.0"});
  const auto cur = [](const TruthSample& s) { return s.current_right_A + s.current_left_A; };
  EXPECT_NEAR(meanOverCruise(eff, cur) - meanOverCruise(base, cur), 2.0, 0.05);
  const auto eff_l = run("three_task", 5, {"coulomb_friction:current_A=1.0,side=left"});
  EXPECT_NEAR(meanOverCruise(eff_l, [](const TruthSample& s) { return s.current_left_A; }) -
                  meanOverCruise(base, [](const TruthSample& s) { return s.current_left_A; }),
              1.0, 0.05);
  expectSameImu(base.recording, base.recording);
}

TEST(Effects, GroundSlopeDownhillNeedsLessCurrent) {
  const auto base = run("three_task", 6);
  const auto eff = run("three_task", 6, {"ground_slope:angle_deg=2,downhill_heading_deg=0"});
  const auto cur = [](const TruthSample& s) { return s.current_right_A + s.current_left_A; };
  // Downhill on the first leg: gravity (m_b + 2 m_w) g sin(2 deg) / 2 per wheel helps.
  const double fwd = meanOverCruise(eff, cur) - meanOverCruise(base, cur);
  const model::VehicleParams p;
  const double expected = -(p.geom.body_mass_kg + 2 * p.geom.wheel_mass_kg) * 9.81 *
                          std::sin(2 * M_PI / 180) * p.geom.wheel_radius_m / p.geom.gear_ratio /
                          (p.gearbox_efficiency * p.torque_constant_Nm_A);
  EXPECT_NEAR(fwd, expected, 0.05 * std::abs(expected));
  const auto& e = eff.truth.samples.back();
  EXPECT_LT(std::hypot(e.x_m, e.y_m), 0.15);
}

TEST(Effects, PayloadMassNeedsMoreAccelerationCurrent) {
  const auto base = run("three_task", 6, {}, 5);
  const auto eff = run("three_task", 6, {"payload_mass:body_mass_kg=180"}, 5);
  double pb = 0, pe = 0;
  for (const auto& s : base.truth.samples) pb = std::max(pb, s.current_right_A);
  for (const auto& s : eff.truth.samples) pe = std::max(pe, s.current_right_A);
  EXPECT_GT(pe, 1.2 * pb);
}

TEST(Effects, SensorDelayShiftsOnlyThatStreamsTimestamps) {
  const auto base = run("three_task", 7, {}, 10);
  const auto eff = run("three_task", 7, {"sensor_delay:sensor=imu,delay_s=0.05"}, 10);
  ASSERT_EQ(base.recording.imu.size(), eff.recording.imu.size());
  for (std::size_t i = 0; i < base.recording.imu.size(); ++i) {
    EXPECT_NEAR(eff.recording.imu[i].t_s - base.recording.imu[i].t_s, 0.05, 1e-12);
    EXPECT_EQ(eff.recording.imu[i].gyro_z_rad_s, base.recording.imu[i].gyro_z_rad_s);
  }
  expectSameEncoders(base.recording, eff.recording);
  expectSameMotors(base.recording, eff.recording);
}

TEST(Effects, ActuatorLagDelaysTheResponse) {
  auto firstMove = [](const SimulationResult& r) {
    for (const auto& s : r.truth.samples)
      if (s.v_m_s > 0.05) return s.t_s;
    return 1e9;
  };
  const auto base = run("three_task", 8, {}, 6);
  const auto eff = run("three_task", 8, {"actuator_lag:delay_s=0.3"}, 6);
  EXPECT_NEAR(firstMove(eff) - firstMove(base), 0.3, 0.02);
  const auto slow = run("three_task", 8, {"actuator_lag:time_constant_s=0.6"}, 6);
  EXPECT_GT(firstMove(slow) - firstMove(base), 0.1);
  // The joystick stream is the driver's demand: the same in all three.
  ASSERT_EQ(base.recording.joystick.size(), eff.recording.joystick.size());
  for (std::size_t i = 0; i < base.recording.joystick.size(); ++i)
    EXPECT_EQ(base.recording.joystick[i].v_cmd_m_s, eff.recording.joystick[i].v_cmd_m_s);
}

TEST(Effects, SonarDropoutInBursts) {
  // The obstacle field keeps posts in the sonar's view: most readings are valid.
  const auto base = run("obstacles", 9, {}, 30);
  const auto eff = run("obstacles", 9, {"sonar_dropout:probability=0.3,burst_length=3"}, 30);
  expectSameImu(base.recording, eff.recording);
  expectSameTruth(base.truth, eff.truth);
  ASSERT_EQ(base.recording.sonar.size(), eff.recording.sonar.size());
  int valid = 0, dropped = 0, bursts = 0;
  bool prev = false;
  for (std::size_t i = 0; i < eff.recording.sonar.size(); ++i) {
    if (base.recording.sonar[i].range_m == 0) {
      prev = false;
      continue;
    }
    ++valid;
    const bool d = eff.recording.sonar[i].range_m == 0;
    if (!d) {
      EXPECT_EQ(eff.recording.sonar[i].range_m, base.recording.sonar[i].range_m);
    }
    if (d && !prev) ++bursts;
    prev = d;
    dropped += d;
  }
  ASSERT_GT(valid, 200);
  EXPECT_NEAR(static_cast<double>(dropped) / valid, 0.3, 0.1);
  ASSERT_GT(bursts, 0);
  EXPECT_GT(static_cast<double>(dropped) / bursts, 1.8);  // mean burst length ~3
}

TEST(Effects, PozyxOutliersAndAnchorFrame) {
  const auto base = run("three_task", 10);
  const auto eff = run("three_task", 10, {"pozyx_outliers:rate=0.1,magnitude_m=2"});
  ASSERT_EQ(base.recording.pozyx.size(), eff.recording.pozyx.size());
  int out = 0;
  for (std::size_t i = 0; i < base.recording.pozyx.size(); ++i) {
    const double d = std::hypot(eff.recording.pozyx[i].x_m - base.recording.pozyx[i].x_m,
                                eff.recording.pozyx[i].y_m - base.recording.pozyx[i].y_m);
    if (d > 0) {
      ++out;
      EXPECT_GE(d, 0.99);
      EXPECT_LE(d, 3.01);
    }
  }
  const double frac = static_cast<double>(out) / base.recording.pozyx.size();
  EXPECT_NEAR(frac, 0.1, 0.04);
  // Without outliers: the tag (lever arm) in the anchor frame, ~10 cm noise.
  const auto& A = base.truth.pozyx_anchor;
  std::vector<double> err;
  std::size_t k = 0;
  for (const auto& p : base.recording.pozyx) {
    while (k + 1 < base.truth.samples.size() && base.truth.samples[k + 1].t_s <= p.t_s) ++k;
    const auto& s = base.truth.samples[k];
    const double c = std::cos(s.phi_rad), sn = std::sin(s.phi_rad);
    const double tx = s.x_m + c * -0.20 - sn * -0.10, ty = s.y_m + sn * -0.20 + c * -0.10;
    const double ax = A.x_m + std::cos(A.yaw_rad) * tx - std::sin(A.yaw_rad) * ty;
    const double ay = A.y_m + std::sin(A.yaw_rad) * tx + std::cos(A.yaw_rad) * ty;
    err.push_back(p.x_m - ax);
    err.push_back(p.y_m - ay);
  }
  EXPECT_NEAR(rms(err), 0.10, 0.02);
  EXPECT_GT(std::hypot(A.x_m, A.y_m) + std::abs(A.yaw_rad), 0.1);  // not the start frame
}

TEST(Effects, VrcFollowsMotorVoltageThroughEq11) {
  const auto r = run("three_task", 11);
  const config::WheelchairConfig cfg;
  // At cruise U is constant: V_RC is the steady state of (11) (incl. the Zener knee).
  const double U = meanOverCruise(r, [](const TruthSample& s) { return s.voltage_right_V; });
  const double expect = sensors::steadyStateVrc(U, cfg.motors.circuit);
  double m = 0;
  int n = 0;
  for (const auto& s : r.recording.motors)
    if (s.t_s > 4 && s.t_s < 10) m += s.vrc_right_V, ++n;
  EXPECT_NEAR(m / n, expect, 0.01);
  EXPECT_GT(expect, 0.5);
  // U = R_m i + k_m omega_m
  const auto& ts = r.truth.samples[600];
  EXPECT_NEAR(ts.voltage_right_V,
              0.35 * ts.current_right_A + 0.09 * 18 * ts.wheel_speed_right_rad_s, 1e-9);
}

// --- supervisory control --------------------------------------------------------------
TEST(Supervisory, CollisionsOffButNotOn) {
  SimulationOptions off, on;
  on.supervisory.enabled = true;
  const auto a = run("obstacles", 1, {}, 0, off);
  const auto b = run("obstacles", 1, {}, 0, on);
  EXPECT_DOUBLE_EQ(a.duration_s, 10.0);
  EXPECT_GT(a.collisions, 0);
  EXPECT_EQ(b.collisions, 0);
  // The assisted chair travels much less, and slows gradually (no jump to 0).
  auto dist = [](const SimulationResult& r) {
    double d = 0;
    for (std::size_t i = 1; i < r.truth.samples.size(); ++i)
      d += std::hypot(r.truth.samples[i].x_m - r.truth.samples[i - 1].x_m,
                      r.truth.samples[i].y_m - r.truth.samples[i - 1].y_m);
    return d;
  };
  EXPECT_GT(dist(a), 4.0);
  EXPECT_LT(dist(b), 0.5 * dist(a));
  EXPECT_GT(dist(b), 0.3);
  // Joystick held at the paper's position in both runs.
  EXPECT_DOUBLE_EQ(b.recording.joystick[10].v_cmd_m_s, 0.52);
  EXPECT_DOUBLE_EQ(b.recording.joystick[10].omega_cmd_rad_s, 0.27);
}

TEST(Supervisory, ScaleRule) {
  SupervisoryParams p;
  Footprint fp;
  const std::vector<Obstacle> far{{10, 0, 0.05}}, mid{{0.6 + 0.05 + 0.6, 0, 0.05}},
      touching{{0.5, 0, 0.05}};
  EXPECT_DOUBLE_EQ(supervisoryScale(p, fp, 0, 0, 0, 0.5, 0, far), 1.0);
  const double s = supervisoryScale(p, fp, 0, 0, 0, 0.5, 0, mid);
  EXPECT_GT(s, 0.2);
  EXPECT_LT(s, 0.6);
  EXPECT_DOUBLE_EQ(supervisoryScale(p, fp, 0, 0, 0, 0.5, 0, touching), 0.0);
  EXPECT_DOUBLE_EQ(supervisoryScale(p, fp, 0, 0, 0, -0.5, 0, mid), 1.0);  // reversing away
}

// --- options, truth files -----------------------------------------------------------
TEST(SimulationOptions, LoadFromConfig) {
  mrpt::config::CConfigFileMemory ini(
      "[simulation]\nstep_s = 0.0005\nsupervisory = 1\nactuator_delay_s = 0.1\n"
      "obstacle_field_xy_m = 1 2, 3 4\nobstacle_radius_m = 0.1\npozyx_anchor_random = 0\n"
      "pozyx_anchor_yaw_deg = 90\n");
  SimulationOptions o;
  o.loadFromConfig(ini);
  EXPECT_DOUBLE_EQ(o.step_s, 0.0005);
  EXPECT_TRUE(o.supervisory.enabled);
  EXPECT_DOUBLE_EQ(o.power.delay_s, 0.1);
  ASSERT_EQ(o.scenario.field_obstacles.size(), 2u);
  EXPECT_DOUBLE_EQ(o.scenario.field_obstacles[1].y_m, 4.0);
  EXPECT_DOUBLE_EQ(o.scenario.field_obstacles[1].radius_m, 0.1);
  EXPECT_FALSE(o.pozyx_anchor_random);
  mrpt::config::CConfigFileMemory bad("[simulation]\nstep_s = fast\n");
  EXPECT_THROW(o.loadFromConfig(bad), std::runtime_error);
  // The repository's configuration loads (its [simulation] section, when present).
  const auto cfg =
      config::WheelchairConfig::load(std::string(WHEELCHAIR_SOURCE_DIR) + "/config/wheelchair.ini");
  SimulationOptions o2;
  EXPECT_NO_THROW(o2.loadFromConfig(cfg.ini()));
}

TEST(Truth, WriteReadRoundTrip) {
  const auto r =
      run("obstacles", 2, {"gyro_bias:bias_rad_s=0.01", "encoder_scale:side=left,scale=0.9"});
  const auto dir = std::filesystem::temp_directory_path() / "wc-sim-truth-test";
  std::filesystem::create_directories(dir);
  const std::string js = (dir / "t.truth.json").string(), csv = (dir / "t.truth.csv").string();
  r.writeTruth(js);
  r.writeTruth(csv);
  EXPECT_FALSE(std::filesystem::exists(js + ".tmp"));
  const auto back = readTruth(js);
  EXPECT_EQ(back.scenario, "obstacles");
  EXPECT_EQ(back.seed, 2u);
  EXPECT_EQ(back.collisions, r.collisions);
  ASSERT_EQ(back.effects.size(), 2u);
  EXPECT_EQ(back.effects[1], r.effects[1]);
  ASSERT_EQ(back.truth.samples.size(), r.truth.samples.size());
  EXPECT_EQ(back.truth.samples.back().x_m, r.truth.samples.back().x_m);
  EXPECT_EQ(back.truth.obstacles.size(), r.truth.obstacles.size());
  EXPECT_EQ(back.truth.pozyx_anchor.yaw_rad, r.truth.pozyx_anchor.yaw_rad);
  std::ifstream in(csv);
  std::string header;
  std::getline(in, header);
  EXPECT_EQ(header.rfind("t_s,x_m,y_m,phi_rad,v_m_s,omega_rad_s,", 0), 0u);
  std::filesystem::remove_all(dir);
}

TEST(Scenarios, AllRunAndUnknownThrows) {
  for (const auto& name : scenarioNames()) {
    const auto r = run(name, 1, {}, 8);
    EXPECT_DOUBLE_EQ(r.duration_s, 8.0) << name;
    EXPECT_FALSE(r.recording.encoders.empty()) << name;
  }
  EXPECT_THROW(run("moonwalk", 1), std::invalid_argument);
  const auto sq = run("square", 1);
  const auto& e = sq.truth.samples.back();
  EXPECT_LT(std::hypot(e.x_m, e.y_m), 0.1);
  double max_x = 0, max_y = 0;
  for (const auto& s : sq.truth.samples)
    max_x = std::max(max_x, s.x_m), max_y = std::max(max_y, s.y_m);
  EXPECT_NEAR(max_x, 3.0, 0.1);
  EXPECT_NEAR(max_y, 3.0, 0.1);
}
