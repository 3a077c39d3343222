// Voltage circuit of Fig. 4b: eq. (10), (11), Table II/III and the Zener soft-knee fit.
#include "libwheelchair/sensors/VoltageCircuit.h"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <vector>

using namespace wheelchair::sensors;

namespace {
// Table II of the paper.
const std::vector<double> kVw = {29.2, 25.6, 22.0, 18.4, 14.8};
const std::vector<double> kVR = {5.119, 4.488, 3.857, 3.225, 2.594};
const std::vector<double> kVRCexp = {5.101, 4.473, 3.840, 3.210, 2.579};
const std::vector<double> kVRCZ = {4.684, 4.331, 3.806, 3.204, 2.578};
const std::vector<double> kEps = {8.2, 3.2, 0.9, 0.2, 0.0004};

// Classical RK4 of dV/dt = vrcRate(V, Vw(t)).
template <class F>
double rk4(double V, double t, double h, const F& Vw, const VoltageCircuitParams& c) {
  const double k1 = vrcRate(V, Vw(t), c);
  const double k2 = vrcRate(V + 0.5 * h * k1, Vw(t + 0.5 * h), c);
  const double k3 = vrcRate(V + 0.5 * h * k2, Vw(t + 0.5 * h), c);
  const double k4 = vrcRate(V + h * k3, Vw(t + h), c);
  return V + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4);
}
}  // namespace

TEST(VoltageCircuit, TableIIIResistances) {
  VoltageCircuitParams c;
  EXPECT_NEAR(c.R24_ohm(), 723.36, 0.01);  // 723.367: the paper truncates
  EXPECT_NEAR(c.R13_ohm(), 3403.13, 0.005);
  EXPECT_NEAR(c.theveninResistance_ohm(), 596.56, 0.005);
  EXPECT_NEAR(c.dividerRatio(), 723.36 / (723.36 + 3403.13), 2e-6);
  // 596.56 ohm * 280 nF = 167.04 us (not 166.9 us); cut-off 952.8 Hz, not the paper's 100 Hz
  // (docs/sensors.md).
  EXPECT_NEAR(c.timeConstant_s(), 596.56 * 280e-9, 0.01e-6);
  EXPECT_NEAR(c.timeConstant_s(), 167.04e-6, 0.01e-6);
  EXPECT_NEAR(c.cutoffFrequency_Hz(), 952.8, 0.1);
}

TEST(VoltageCircuit, ReproducesTableIIDividerColumn) {
  VoltageCircuitParams c;
  for (std::size_t j = 0; j < kVw.size(); ++j) {
    EXPECT_NEAR(dividerVoltage(kVw[j], c), kVR[j], 0.0015) << "V_w = " << kVw[j];
    // In fact within the printed rounding (half a unit of the last digit).
    EXPECT_NEAR(dividerVoltage(kVw[j], c), kVR[j], 0.0005 + 1e-9) << "V_w = " << kVw[j];
  }
  // Without a Zener the steady state is the divider voltage, at any level.
  c.has_zener = false;
  for (double Vw : {-30.0, 0.0, 14.8, 29.2, 60.0}) {
    EXPECT_DOUBLE_EQ(steadyStateVrc(Vw, c), dividerVoltage(Vw, c));
  }
}

TEST(VoltageCircuit, TableIIMeterGainAndEpsilonColumn) {
  VoltageCircuitParams c;
  double mean_ratio = 0;
  for (std::size_t j = 0; j < kVw.size(); ++j) {
    const double ratio = kVRCexp[j] / dividerVoltage(kVw[j], c);
    EXPECT_NEAR(ratio, 0.996, 0.0025) << "V_w = " << kVw[j];
    mean_ratio += ratio / kVw.size();
    // The epsilon column is 100 (V_RC,exp - V_RCZ) / V_RC,exp (the printed formula divides
    // by V_RCZ, which would give 8.9 % in the first row, not 8.2 %).
    const double eps = 100.0 * (kVRCexp[j] - kVRCZ[j]) / kVRCexp[j];
    const double eps_printed = 100.0 * (kVRCexp[j] - kVRCZ[j]) / kVRCZ[j];
    if (j < 4) {
      EXPECT_NEAR(eps, kEps[j], 0.05) << "V_w = " << kVw[j];
    } else {  // the last row is printed as a fraction (0.0004 = 0.04 %)
      EXPECT_NEAR(eps / 100.0, kEps[j], 0.00005);
    }
    if (j == 0) {
      EXPECT_GT(std::abs(eps_printed - kEps[j]), 0.5);
    }
  }
  EXPECT_NEAR(mean_ratio, 0.9960, 0.0010);
}

TEST(VoltageCircuit, ZenerModelReproducesTableII) {
  VoltageCircuitParams c;  // defaults = the fit
  double max_err = 0;
  for (std::size_t j = 0; j < kVw.size(); ++j) {
    const double v = clampedVoltage(kVRCexp[j], c);
    max_err = std::max(max_err, std::abs(v - kVRCZ[j]));
    EXPECT_NEAR(v, kVRCZ[j], 0.01) << "V_RC,exp = " << kVRCexp[j];
    // The Zener only ever lowers the voltage.
    EXPECT_LE(v, kVRCexp[j]);
  }
  std::cout << "Zener model max |error| over Table II: " << max_err << " V\n";
  // Without the Zener the same comparison fails badly at the top of the table.
  VoltageCircuitParams nz = c;
  nz.has_zener = false;
  EXPECT_GT(std::abs(clampedVoltage(kVRCexp[0], nz) - kVRCZ[0]), 0.4);
}

TEST(VoltageCircuit, ZenerFitReproducesDefaults) {
  VoltageCircuitParams c;
  const ZenerFit fit = fitZenerSoftKnee(kVRCexp, kVRCZ, c);
  std::cout << "Zener fit: I_knee = " << fit.current_at_knee_A << " A, V_slope = " << fit.slope_V
            << " V, rms = " << fit.rms_residual_V << " V, max = " << fit.max_abs_residual_V
            << " V, iterations = " << fit.iterations << "\n";
  EXPECT_TRUE(fit.converged);
  EXPECT_LT(fit.max_abs_residual_V, 0.01);
  EXPECT_LT(fit.rms_residual_V, 0.005);
  EXPECT_NEAR(fit.current_at_knee_A, c.zener_current_at_knee_A, 0.005 * c.zener_current_at_knee_A);
  EXPECT_NEAR(fit.slope_V, c.zener_slope_V, 0.005 * c.zener_slope_V);
  // The fit is a minimum: perturbing either parameter makes the residual worse.
  for (double f : {0.9, 1.1}) {
    for (int which = 0; which < 2; ++which) {
      VoltageCircuitParams q = c;
      q.zener_current_at_knee_A = fit.current_at_knee_A * (which == 0 ? f : 1.0);
      q.zener_slope_V = fit.slope_V * (which == 1 ? f : 1.0);
      double ss = 0;
      for (std::size_t j = 0; j < kVw.size(); ++j)
        ss += std::pow(clampedVoltage(kVRCexp[j], q) - kVRCZ[j], 2);
      EXPECT_GT(std::sqrt(ss / kVw.size()), fit.rms_residual_V);
    }
  }
  // The fit recovers known parameters from synthetic data.
  VoltageCircuitParams truth = c;
  truth.zener_current_at_knee_A = 5e-3;
  truth.zener_slope_V = 0.25;
  std::vector<double> vo = {2.0, 3.0, 4.0, 4.5, 5.0, 5.5, 6.0}, vc;
  for (double v : vo) vc.push_back(clampedVoltage(v, truth));
  const ZenerFit f2 = fitZenerSoftKnee(vo, vc, c);
  EXPECT_NEAR(f2.current_at_knee_A, 5e-3, 5e-7);
  EXPECT_NEAR(f2.slope_V, 0.25, 1e-5);
}

TEST(VoltageCircuit, SteadyStateWithZenerIsRobust) {
  VoltageCircuitParams c;
  // Negligible effect at low voltage, strong at the top; monotone; saturates.
  EXPECT_NEAR(steadyStateVrc(10.0, c), dividerVoltage(10.0, c), 2e-4);
  EXPECT_LT(steadyStateVrc(29.2, c), dividerVoltage(29.2, c) - 0.3);
  double prev = -1e9;
  for (double Vw = -100; Vw <= 1000; Vw += 0.5) {
    const double v = steadyStateVrc(Vw, c);
    ASSERT_TRUE(std::isfinite(v)) << Vw;
    ASSERT_GT(v, prev) << Vw;
    // It solves the node equation: zero rate.
    ASSERT_NEAR(vrcRate(v, Vw, c) * c.timeConstant_s(), 0.0, 1e-9 * (1 + std::abs(Vw))) << Vw;
    prev = v;
  }
  EXPECT_LT(steadyStateVrc(100.0, c), 6.5);  // protects the Arduino input
  EXPECT_LT(steadyStateVrc(1000.0, c), 7.5);
  const double neg = steadyStateVrc(-30.0, c);  // forward conduction
  EXPECT_GT(neg, -1.2);
  EXPECT_LT(neg, -0.5);
  EXPECT_TRUE(std::isfinite(steadyStateVrc(1e9, c)));
  EXPECT_TRUE(std::isfinite(steadyStateVrc(-1e9, c)));
}

TEST(VoltageCircuit, StepResponseTimeConstant) {
  VoltageCircuitParams c;
  c.has_zener = false;
  const double tau = c.timeConstant_s();
  const double Vw = 20.0, Vss = dividerVoltage(Vw, c);
  const double h = tau / 200.0;
  auto step = [&](double) { return Vw; };
  double V = 0, t = 0, t63 = -1;
  for (int k = 0; k < 2000; ++k) {
    const double Vn = rk4(V, t, h, step, c);
    const double tn = t + h;
    const double closed = Vss * (1.0 - std::exp(-tn / tau));
    ASSERT_NEAR(Vn, closed, 1e-9 * Vss) << "t = " << tn;
    const double target = Vss * (1.0 - std::exp(-1.0));
    if (t63 < 0 && Vn >= target) t63 = t + h * (target - V) / (Vn - V);
    V = Vn;
    t = tn;
  }
  EXPECT_NEAR(t63, tau, 1e-4 * tau);
  EXPECT_NEAR(t63, 596.56 * 280e-9, 0.01e-6);
  EXPECT_NEAR(V, Vss * (1.0 - std::exp(-t / tau)), 1e-9);
  EXPECT_NEAR(V, Vss, 2e-4);  // ten time constants
}

TEST(VoltageCircuit, InverseRecoversLeadVoltage) {
  for (bool zener : {false, true}) {
    VoltageCircuitParams c;
    c.has_zener = zener;
    const double tau = c.timeConstant_s();
    // A PWM-average-like wire voltage: ramps, a step, and a fast wiggle up into the knee.
    auto Vw = [](double t) {
      return 12.0 + 10.0 * std::sin(2 * 3.14159265 * 300.0 * t) + (t > 2e-3 ? 8.0 : 0.0);
    };
    const double h = tau / 100.0;
    double V = steadyStateVrc(Vw(0), c), t = 0, max_err = 0;
    for (int k = 0; k < 3000; ++k) {
      const double rate = vrcRate(V, Vw(t), c);
      max_err = std::max(max_err, std::abs(leadVoltageFromVrc(V, rate, c) - Vw(t)));
      if (!zener) {
        EXPECT_NEAR(motorVoltageFromVrc(V, rate, c), Vw(t), 1e-9);
      }
      V = rk4(V, t, h, Vw, c);
      t += h;
    }
    EXPECT_LT(max_err, 1e-9) << "zener " << zener;
  }
  // Steady state in, wire voltage out, across the knee.
  VoltageCircuitParams c;
  for (double Vw : {5.0, 14.8, 29.2, 40.0}) {
    EXPECT_NEAR(leadVoltageFromVrc(steadyStateVrc(Vw, c), 0.0, c), Vw, 1e-8 * Vw);
    // Ignoring the Zener underestimates the voltage at the top of the range.
    VoltageCircuitParams nz = c;
    nz.has_zener = false;
    if (Vw > 25) {
      EXPECT_LT(leadVoltageFromVrc(steadyStateVrc(Vw, c), 0.0, nz), Vw - 1.0);
    }
  }
}

TEST(VoltageCircuit, MotorVoltageIsOddAndMatchesWireModel) {
  VoltageCircuitParams c;
  for (double v : {0.0, 0.5, 2.0, 4.2, 4.9}) {
    for (double r : {0.0, 100.0, -300.0}) {
      EXPECT_NEAR(motorVoltageFromVrc(-v, -r, c), -motorVoltageFromVrc(v, r, c), 1e-12);
      if (v > 0) {  // a wire at V_RC > 0 against a grounded wire: the same as the wire model
        EXPECT_NEAR(motorVoltageFromVrc(v, r, c), leadVoltageFromVrc(v, r, c), 1e-5);
      }
    }
  }
  EXPECT_NEAR(motorVoltageFromVrc(0.0, 0.0, c), 0.0, 1e-15);
}

TEST(VoltageCircuit, MotorVoltageFromSampledSeries) {
  VoltageCircuitParams c;
  c.has_zener = false;
  const double tau = c.timeConstant_s();
  // U(t) = 10 + 8 sin(2 pi 0.5 t): slow, so V_RC = k (U - tau U') to O(tau^2).
  auto U = [](double t) { return 10.0 + 8.0 * std::sin(3.14159265358979 * t); };
  auto dU = [](double t) { return 8.0 * 3.14159265358979 * std::cos(3.14159265358979 * t); };
  std::vector<double> t, vrc;
  for (int k = 0; k < 400; ++k) {
    const double tk = 0.01 * k + 0.002 * std::sin(0.9 * k);  // uneven 100 Hz
    t.push_back(tk);
    vrc.push_back(c.dividerRatio() * (U(tk) - tau * dU(tk)));
  }
  const auto u = motorVoltageFromVrcSeries(t, vrc, c, 10.0);
  ASSERT_EQ(u.size(), t.size());
  for (std::size_t k = 20; k + 20 < t.size(); ++k) EXPECT_NEAR(u[k], U(t[k]), 0.05) << k;
  const auto u_raw = motorVoltageFromVrcSeries(t, vrc, c, 0.0);  // no smoothing
  for (std::size_t k = 1; k + 1 < t.size(); ++k) EXPECT_NEAR(u_raw[k], U(t[k]), 1e-3) << k;
}
