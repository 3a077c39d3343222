#include "libwheelchair/sensors/VoltageCircuit.h"

#include "libwheelchair/sensors/Filtering.h"
#include "libwheelchair/stats/LevenbergMarquardt.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace wheelchair::sensors {

namespace {
constexpr double kPi = 3.141592653589793238462643383279;
constexpr double kMaxExp = 700.0;  // exp(700) ~ 1e304: large but finite

double clampedExp(double a) {
  return std::exp(std::min(a, kMaxExp));
}
double parallel(double a, double b) {
  return a * b / (a + b);
}

/// Reverse (Zener) branch with explicit parameters.
double reverseCurrent(double v, double i_knee, double v_d, double slope) {
  return i_knee * clampedExp((v - v_d) / slope);
}
}  // namespace

double VoltageCircuitParams::R13_ohm() const {
  return parallel(R1_ohm, R3_ohm);
}
double VoltageCircuitParams::R24_ohm() const {
  return parallel(R2_ohm, R4_ohm);
}
double VoltageCircuitParams::dividerRatio() const {
  return R24_ohm() / (R13_ohm() + R24_ohm());
}
double VoltageCircuitParams::theveninResistance_ohm() const {
  return parallel(R13_ohm(), R24_ohm());
}
double VoltageCircuitParams::timeConstant_s() const {
  return theveninResistance_ohm() * C_F;
}
double VoltageCircuitParams::cutoffFrequency_Hz() const {
  return 1.0 / (2.0 * kPi * timeConstant_s());
}

double zenerCurrent(double v, const VoltageCircuitParams& p) {
  if (!p.has_zener) return 0.0;
  const double rev = reverseCurrent(v, p.zener_current_at_knee_A, p.zener_knee_V, p.zener_slope_V);
  const double fwd =
      -p.zener_forward_saturation_A * (clampedExp(-v / p.zener_forward_slope_V) - 1.0);
  return rev + fwd;
}

double zenerConductance(double v, const VoltageCircuitParams& p) {
  if (!p.has_zener) return 0.0;
  const double a_rev = (v - p.zener_knee_V) / p.zener_slope_V;
  const double a_fwd = -v / p.zener_forward_slope_V;
  const double g_rev =
      a_rev < kMaxExp ? p.zener_current_at_knee_A * std::exp(a_rev) / p.zener_slope_V : 0.0;
  const double g_fwd =
      a_fwd < kMaxExp ? p.zener_forward_saturation_A * std::exp(a_fwd) / p.zener_forward_slope_V
                      : 0.0;
  return g_rev + g_fwd;
}

double dividerVoltage(double V_w, const VoltageCircuitParams& p) {
  return p.dividerRatio() * V_w;
}

double clampedVoltage(double v_open, const VoltageCircuitParams& p) {
  if (!p.has_zener || !std::isfinite(v_open)) return v_open;
  const double R = p.theveninResistance_ohm();
  // g is strictly decreasing: g' = -1/R - I_z'(V) < 0.
  auto g = [&](double V) { return (v_open - V) / R - zenerCurrent(V, p); };
  auto dg = [&](double V) { return -1.0 / R - zenerConductance(V, p); };

  // Bracket [lo, hi] with g(lo) >= 0 >= g(hi).
  double lo = std::min(v_open, 0.0) - 1.0, hi = std::max(v_open, 0.0) + 1.0;
  for (double step = 1.0; g(lo) < 0 && step < 1e6; step *= 2) lo -= step;
  for (double step = 1.0; g(hi) > 0 && step < 1e6; step *= 2) hi += step;
  // Tighten on the conducting side: where the Zener alone carries all of v_open/R.
  if (v_open > 0 && p.zener_current_at_knee_A > 0) {
    const double vz =
        p.zener_knee_V + p.zener_slope_V * std::log(v_open / (R * p.zener_current_at_knee_A));
    if (vz > lo && vz < hi && g(vz) <= 0) hi = vz;
  }
  if (v_open < 0 && p.zener_forward_saturation_A > 0) {
    // Where the forward branch alone carries all of -v_open/R.
    const double vf =
        -p.zener_forward_slope_V * std::log1p(-v_open / (R * p.zener_forward_saturation_A));
    if (vf > lo && vf < hi && g(vf) >= 0) lo = vf;
  }
  // Safeguarded Newton (Numerical Recipes' rtsafe): bisect whenever the Newton step leaves
  // the bracket or does not at least halve the previous step (slow on the exponentials).
  double x = std::clamp(v_open, lo, hi);
  double dx_old = hi - lo, dx = dx_old;
  for (int it = 0; it < 300; ++it) {
    const double gx = g(x);
    if (gx == 0) return x;
    if (gx > 0)
      lo = x;
    else
      hi = x;
    const double d = dg(x);
    const double newton = x - gx / d;
    double xn;
    if (!(newton > lo && newton < hi) || std::abs(2.0 * gx) > std::abs(dx_old * d)) {
      xn = 0.5 * (lo + hi);
      dx_old = dx;
      dx = xn - x;
    } else {
      xn = newton;
      dx_old = dx;
      dx = xn - x;
    }
    if (std::abs(dx) <= 1e-15 * (1.0 + std::abs(x)) || hi - lo <= 4e-16 * (1.0 + std::abs(x)))
      return xn;
    x = xn;
  }
  return x;
}

double steadyStateVrc(double V_w, const VoltageCircuitParams& p) {
  return clampedVoltage(p.dividerRatio() * V_w, p);
}

double vrcRate(double vrc_V, double V_w, const VoltageCircuitParams& p) {
  const double R = p.theveninResistance_ohm();
  return (-vrc_V + p.dividerRatio() * V_w - R * zenerCurrent(vrc_V, p)) / p.timeConstant_s();
}

double leadVoltageFromVrc(double vrc_V, double vrc_rate_V_s, const VoltageCircuitParams& p) {
  const double R = p.theveninResistance_ohm();
  return (vrc_V + p.timeConstant_s() * vrc_rate_V_s + R * zenerCurrent(vrc_V, p)) /
         p.dividerRatio();
}

double motorVoltageFromVrc(double vrc_V, double vrc_rate_V_s, const VoltageCircuitParams& p) {
  const double R = p.theveninResistance_ohm();
  double iz = 0.0;
  if (p.has_zener) {
    const double a = std::abs(vrc_V);
    // Odd and continuous through 0: subtract the (tiny) leakage at 0 V.
    iz = reverseCurrent(a, p.zener_current_at_knee_A, p.zener_knee_V, p.zener_slope_V) -
         reverseCurrent(0.0, p.zener_current_at_knee_A, p.zener_knee_V, p.zener_slope_V);
    if (vrc_V < 0) iz = -iz;
  }
  return (vrc_V + p.timeConstant_s() * vrc_rate_V_s + R * iz) / p.dividerRatio();
}

std::vector<double> motorVoltageFromVrcSeries(const std::vector<double>& t_s,
                                              const std::vector<double>& vrc_V,
                                              const VoltageCircuitParams& p, double cutoff_hz) {
  if (t_s.size() != vrc_V.size())
    throw std::invalid_argument("motorVoltageFromVrcSeries: size mismatch");
  const std::vector<double> xs = cutoff_hz > 0 ? filtfiltButter2(t_s, vrc_V, cutoff_hz) : vrc_V;
  const std::vector<double> rate = centralDerivative(t_s, xs);
  std::vector<double> u(xs.size());
  for (std::size_t i = 0; i < xs.size(); ++i) u[i] = motorVoltageFromVrc(xs[i], rate[i], p);
  return u;
}

ZenerFit fitZenerSoftKnee(const std::vector<double>& v_open, const std::vector<double>& v_cl,
                          const VoltageCircuitParams& p0) {
  if (v_open.size() != v_cl.size() || v_open.size() < 2)
    throw std::invalid_argument("fitZenerSoftKnee: need >= 2 pairs of equal-size series");
  const std::size_t n = v_open.size();
  VoltageCircuitParams p = p0;
  p.has_zener = true;
  const double R = p.theveninResistance_ohm();

  // Start: ln I = alpha + beta V over the pairs with a clear drop (>= 2 mV).
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  int m = 0;
  for (double min_drop : {2e-3, 1e-12}) {
    sx = sy = sxx = sxy = 0;
    m = 0;
    for (std::size_t j = 0; j < n; ++j) {
      const double drop = v_open[j] - v_cl[j];
      if (drop < min_drop) continue;
      const double y = std::log(drop / R), x = v_cl[j];
      sx += x, sy += y, sxx += x * x, sxy += x * y;
      ++m;
    }
    if (m >= 2) break;
  }
  double beta = 3.0, alpha = std::log(1e-3) - beta * p.zener_knee_V;  // generic fallback
  if (m >= 2 && m * sxx - sx * sx > 0) {
    const double b = (m * sxy - sx * sy) / (m * sxx - sx * sx);
    if (b > 0) {
      beta = b;
      alpha = (sy - beta * sx) / m;
    }
  }
  Eigen::Vector2d q(alpha + beta * p.zener_knee_V, std::log(1.0 / beta));  // ln I_k, ln V_s

  auto residuals = [&](const Eigen::VectorXd& qq, Eigen::VectorXd& r, Eigen::MatrixXd* J) {
    p.zener_current_at_knee_A = std::exp(qq(0));
    p.zener_slope_V = std::exp(qq(1));
    r.resize(n);
    if (J) J->resize(n, 2);
    for (std::size_t j = 0; j < n; ++j) {
      const double V = clampedVoltage(v_open[j], p);
      r(j) = V - v_cl[j];
      if (J) {
        // Implicit derivative of (v_open - V)/R - I_z(V; q) = 0.
        const double irev =
            reverseCurrent(V, p.zener_current_at_knee_A, p.zener_knee_V, p.zener_slope_V);
        const double denom = 1.0 / R + zenerConductance(V, p);
        (*J)(j, 0) = -irev / denom;                                              // d/d ln I_k
        (*J)(j, 1) = -irev * (-(V - p.zener_knee_V) / p.zener_slope_V) / denom;  // d/d ln V_s
      }
    }
  };

  stats::LmOptions lm;
  lm.max_iterations = 200;
  lm.max_tries = 30;
  lm.lambda_down = 0.3;
  lm.lambda_min = 1e-12;
  lm.min_diagonal = 1e-300;
  lm.min_step_norm = 1e-12;
  const stats::LmResult sol = stats::levenbergMarquardt(residuals, q, lm);
  ZenerFit fit;
  fit.iterations = sol.iterations;
  fit.converged = sol.converged;
  const Eigen::VectorXd& r = sol.r;
  q = sol.x;
  fit.current_at_knee_A = std::exp(q(0));
  fit.slope_V = std::exp(q(1));
  fit.rms_residual_V = std::sqrt(r.squaredNorm() / double(n));
  fit.max_abs_residual_V = r.cwiseAbs().maxCoeff();
  return fit;
}

}  // namespace wheelchair::sensors
