// Live model-health monitor of the physics EKF (docs/estimation.md, "Health monitor"): the
// online counterpart of `diagnose`, in its effect words.
//
// Detection: a two-sided CUSUM on the normalised innovation nu = y / sqrt(S) of the encoder
// yaw-rate row z_omega (the row that compares the encoders with the gyro):
//   g+ = max(0, g+ + nu - k),  g- = max(0, g- - nu - k),  alarm when g+ or g- > h
// with drift k = 0.5 and threshold h = 12 (for a consistent filter nu ~ N(0, 1): the mean
// run length to a false alarm is far beyond any drive; a 5 % scale step while moving at
// 0.8 m/s gives nu ~ 5 and an alarm within a few samples). The onset is the last time the
// alarming sum was 0. The caller then opens the encoder scale states (closed until then with
// open_sensor_errors_on_alarm; prior variance added), so the fault is ESTIMATED and the
// encoders are kept, corrected, instead of rejected.
// Estimation: after every encoder update while the encoder fault group is open (WheelchairEkf
// passes them only then: before an alarm the closed states hold a healthy chair's radii, which
// learn_healthy_encoder_scales may learn, not a fault) the per-wheel scales k = value +- sd are
// reported as an "estimate" event once sd < 0.005 and |k - 1| > max(3 sd, 0.01) (or
// sd < 0.01 and |k - 1| > 5 sd: a side decided by the fault prior), and again when a later
// estimate differs from the reported one by more than that (a new fault). Before a turn only
// the RATIO k_R / k_L is known (straight driving): it is reported the same way (parameter
// "scale_ratio", side ""), saying that the side needs a turn.
// Gyro: the same CUSUM on the gyro's normalised innovation, but only while the encoders show
// standstill (isolation: there omega = 0 is known without the gyro, so a persistent
// disagreement is the gyro's; while moving, a gyro bias and an encoder ratio fault both
// look like a yaw-rate disagreement). An alarm opens the bias state when it is estimated;
// the bias estimate is reported like the scales ("gyro reads +0.020 rad/s (+-0.001) too high
// (bias) since t = 3.0 s").
// Example text: "left encoder reads 5.0 % short (+-0.3 %) since t = 12.4 s".
#pragma once

#include "libwheelchair/estimation/EstimationTypes.h"

#include <string>
#include <vector>

namespace wheelchair::estimation {

/// Two-sided CUSUM (Page 1954) of a standardised innovation nu ~ N(0, 1):
///   g+ = max(0, g+ + nu - k),  g- = max(0, g- - nu - k),  alarm when g+ > h or g- > h;
/// the onset is the last time the alarming side was 0 (the change-point estimate).
/// k = 0.5 sigma, h = 12: a 1-sigma shift alarms after ~25 samples on average, a consistent
/// sensor about once in 5e5 samples (Siegmund's approximations of the run lengths).
struct Cusum {
  static constexpr double kDrift = 0.5;       ///< k (sigmas)
  static constexpr double kThreshold = 12.0;  ///< h
  explicit Cusum(double t0_s) : zp_s(t0_s), zm_s(t0_s), onset_s(t0_s) {}
  /// Adds one innovation at t_s; true on an alarm (then value(), high() and onset_s describe
  /// it until restart()).
  bool update(double t_s, double nu);
  /// Restarts both sums at t_s (after an alarm).
  void restart(double t_s);
  double value() const { return gp > gm ? gp : gm; }
  bool high() const { return gp > kThreshold; }  ///< the alarm is the positive side
  double gp = 0, gm = 0;                         ///< the sums
  double zp_s, zm_s;                             ///< last times they were 0 (s)
  double onset_s = 0;                            ///< onset of the last alarm (s)
};

class HealthMonitor {
 public:
  /// t0_s: start of the recording (texts give times relative to it).
  explicit HealthMonitor(double t0_s = 0) : t0_(t0_s), enc_(t0_s), gyro_(t0_s) {}

  /// One encoder z_omega normalised innovation (accepted or gated). Returns true on an alarm
  /// (then an "inconsistent" event has been added and the CUSUM restarted).
  bool encoderInnovation(double t_s, double nu);
  /// The scale estimates after an encoder update.
  void scales(double t_s, const SensorErrorEstimate& e);
  /// One gyro normalised innovation taken while the encoders show standstill (no tick in
  /// their last interval: omega = 0 is known without the gyro, so a disagreement is the
  /// gyro's). Same two-sided CUSUM as the encoders'. `bias_estimated`: the filter carries a
  /// gyro-bias state (the text says whether it is re-estimated). Returns true on an alarm.
  bool gyroInnovation(double t_s, double nu, bool bias_estimated);
  /// The gyro-bias estimate (estimate_gyro_bias on): reported once sd < 0.002 rad/s and
  /// |b| > max(3 sd, 0.005 rad/s), and again when it moves by more than that.
  void gyroBias(double t_s, double b_rad_s, double sd_rad_s);

  const std::vector<HealthEvent>& events() const { return events_; }

 private:
  /// side 0 right, 1 left, 2 the ratio k_R / k_L.
  void report(double t_s, int side, double k, double sd);

  double t0_;
  Cusum enc_;                       // encoders' z_omega (its onset: the fault hypothesis')
  double reported_[3] = {1, 1, 1};  // last reported scale per side, ratio (1: none)
  double reported_sd_[3] = {0, 0, 0};
  Cusum gyro_;                                       // the gyro at standstill
  double gyro_reported_ = 0, gyro_reported_sd_ = 0;  // last reported bias (0: none)
  bool gyro_latched_ = false;  // alarm reported and no bias state: no further gyro alarms
  std::vector<HealthEvent> events_;
};

/// The "dropouts" event of a failing sonar (excluded while it fails): its dropouts and
/// episodes from `st`, at t_s, since since_s.
HealthEvent sonarDropoutEvent(const SensorStats& st, double t_s, double since_s);

/// "left encoder reads 5.0 % short (+-0.3 %) since t = 12.4 s" (times relative to t0).
std::string encoderScaleText(const std::string& side, double k, double sd, double since_rel_s);

}  // namespace wheelchair::estimation
