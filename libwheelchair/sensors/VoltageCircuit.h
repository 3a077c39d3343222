// The motor-voltage sensing circuit of Fig. 4b / Appendix VII (docs/sensors.md, "Voltage
// circuit"): per motor-lead wire, a divider R1..R4 feeding a capacitor C (the Arduino input),
// with an optional Zener diode Z_d (knee V_d) across C for over-voltage protection.
//
// Seen from the capacitor the divider is a Thevenin source
//   V_th = k V_w,  k = R_{2||4} / (R_{1||3} + R_{2||4})                          (10)
//   R_|| = R_{1||3} R_{2||4} / (R_{1||3} + R_{2||4}) = 596.56 ohm
// so the node equation with the Zener current I_z(V) is
//   R_|| C dV_RC/dt = -V_RC + k V_w - R_|| I_z(V_RC)                             (11) + Zener
// which is (11) of the paper when I_z = 0. The Zener is modelled with a soft exponential knee
//   I_z(V) = I_knee exp((V - V_d) / V_slope)           (reverse conduction, V > 0)
//          - I_fwd (exp(-V / V_fwd) - 1)               (forward conduction, V < 0)
// whose I_knee and V_slope are fitted to Table II (fitZenerSoftKnee; the defaults below are
// that fit). The forward branch is not identified by any data (Table II is V > 0 only); it is
// a generic silicon diode that only keeps the model bounded for negative wire voltages.
//
// Example:
//   VoltageCircuitParams c;                           // Table III + Zener fit
//   double vrc = steadyStateVrc(29.2, c);             // ~ 4.69 V (Table II: 4.684)
//   double Vw  = leadVoltageFromVrc(vrc, 0.0, c);     // ~ 29.2 V
#pragma once

#include <vector>

namespace wheelchair::sensors {

struct VoltageCircuitParams {
  double R1_ohm = 30220, R2_ohm = 6980, R3_ohm = 3835, R4_ohm = 807;  ///< Table III measured
  double C_F = 280e-9;                                                ///< Table III nominal
  bool has_zener = true;
  double zener_knee_V = 5.1;  ///< V_d (nominal, Table III)
  /// Soft-knee model I_z(V) = I_knee exp((V - V_d) / V_slope), fitted to Table II's V_RCZ
  /// column with Table II's V_RC,exp as the Thevenin voltage (docs/sensors.md, "Zener fit").
  double zener_current_at_knee_A = 2.397e-3;
  double zener_slope_V = 0.3364;
  /// Forward branch I = -I_fwd (exp(-V / V_fwd) - 1), a generic silicon junction (not fitted).
  double zener_forward_saturation_A = 1e-12;
  double zener_forward_slope_V = 0.04;

  double R13_ohm() const;                 ///< R_{1||3} = 3403.13 ohm
  double R24_ohm() const;                 ///< R_{2||4} = 723.367 ohm (printed 723.36)
  double dividerRatio() const;            ///< R_{2||4}/(R_{1||3}+R_{2||4}), eq. (10)
  double theveninResistance_ohm() const;  ///< R_|| = 596.56 ohm
  double timeConstant_s() const;          ///< R_|| C (167.04 us with C = 280 nF)
  double cutoffFrequency_Hz() const;      ///< 1 / (2 pi R_|| C) (952.8 Hz)
};

/// Diode current I_z(V) at capacitor voltage V (A, positive from the node to ground); 0 when
/// has_zener is false. Exponents are clamped so it never overflows.
double zenerCurrent(double v_V, const VoltageCircuitParams& p);
/// d I_z / d V (A/V).
double zenerConductance(double v_V, const VoltageCircuitParams& p);

/// V_R of eq. (10): the divider's output, no Zener.
double dividerVoltage(double V_w, const VoltageCircuitParams& p);
/// Steady-state capacitor voltage for a Thevenin (open-circuit) voltage v_open_V: the root of
/// (v_open - V)/R_|| = I_z(V), by a bracketed Newton iteration (bisection safeguard; the
/// residual is strictly monotone, so the root is unique). Equals v_open_V without a Zener.
double clampedVoltage(double v_open_V, const VoltageCircuitParams& p);
/// Steady-state V_RC for a wire voltage V_w, with the Zener knee: clampedVoltage(k V_w).
double steadyStateVrc(double V_w, const VoltageCircuitParams& p);
/// dV_RC/dt of (11) including the Zener current (V/s).
double vrcRate(double vrc_V, double V_w, const VoltageCircuitParams& p);
/// Inverse of (11) incl. the Zener: the wire voltage V_w that explains a measured V_RC and
/// its rate, V_w = (V_RC + R_|| C dV_RC/dt + R_|| I_z(V_RC)) / k.
double leadVoltageFromVrc(double vrc_V, double vrc_rate_V_s, const VoltageCircuitParams& p);

/// Motor voltage U = V_w1 - V_w2 from the differential V_RC = V_RC1 - V_RC2 of one motor,
/// for the power balance (4). Without Zener conduction (11) is linear and this is exact:
/// U = (V_RC + R_|| C dV_RC/dt) / k. The Zener acts on each wire separately, which the
/// difference alone cannot resolve; this assumes the idle wire of the lead sits at 0 V (one
/// wire carries the PWM average, the other is grounded, swapped when reversing) and applies
/// the reverse-knee current to |V_RC| with the sign of V_RC (an odd function).
double motorVoltageFromVrc(double vrc_V, double vrc_rate_V_s, const VoltageCircuitParams& p);

/// Convenience: U(t) from a sampled V_RC series (strictly increasing t_s, may be uneven):
/// zero-phase Butterworth smoothing at cutoff_hz (filtfiltButter2 on the time base, see
/// Filtering.h), central-difference derivative, then motorVoltageFromVrc at every sample.
/// cutoff_hz <= 0 disables the smoothing. With the real circuit R_|| C = 167 us, the rate
/// term is a small correction at 100 Hz sampling; the smoothing matters more.
std::vector<double> motorVoltageFromVrcSeries(const std::vector<double>& t_s,
                                              const std::vector<double>& vrc_V,
                                              const VoltageCircuitParams& p,
                                              double cutoff_hz = 10.0);

/// Result of fitZenerSoftKnee.
struct ZenerFit {
  double current_at_knee_A = 0;  ///< I_knee
  double slope_V = 0;            ///< V_slope
  double rms_residual_V = 0;     ///< RMS of clampedVoltage(v_open) - v_clamped
  double max_abs_residual_V = 0;
  int iterations = 0;
  bool converged = false;
};

/// Least-squares fit of the soft-knee (I_knee, V_slope) to steady-state pairs: open-circuit
/// (Thevenin) voltages v_open_V and the measured voltages with the Zener v_clamped_V. The
/// residuals are voltages, clampedVoltage(v_open) - v_clamped, minimised by Levenberg-Marquardt
/// in (ln I_knee, ln V_slope) started from a log-linear regression of
/// I = (v_open - v_clamped)/R_|| on v_clamped. Uses p's resistors and knee V_d (which only
/// sets where I_knee is quoted). Needs at least 2 pairs.
ZenerFit fitZenerSoftKnee(const std::vector<double>& v_open_V,
                          const std::vector<double>& v_clamped_V, const VoltageCircuitParams& p);

}  // namespace wheelchair::sensors
