#include "libwheelchair/estimation/HealthMonitor.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>

namespace wheelchair::estimation {

namespace {
constexpr double kThreshold = Cusum::kThreshold;
constexpr double kReportSd = 0.005;  // a scale is reported once its sd is below this (-)
constexpr double kMinFault = 0.01;   // and it is off by more than this and 3 sd (-)

/// An estimate is precise enough to report: sd below the reporting sd, or below twice it while
/// the value is off nominal by more than 5 sd (a fault sided by a prior, or a gyro bias learnt
/// from a short first standstill, carries a little more than the reporting sd but is news).
bool clearEnough(double offset, double sd, double report_sd) {
  return sd < report_sd || (sd < 2 * report_sd && std::abs(offset) > 5 * sd);
}
const char* const kSide[2] = {"right", "left"};
}  // namespace

HealthEvent sonarDropoutEvent(const SensorStats& st, double t_s, double since_s) {
  HealthEvent e;
  e.t_s = t_s;
  e.sensor = "sonar";
  e.kind = "dropouts";
  e.parameter = "episodes";
  e.value = static_cast<double>(st.dropout_episodes);
  e.since_s = since_s;
  e.text = fmt::format(
      "sonar gave no valid range (0 or out of range) {} times in {} episodes, excluded while it "
      "did",
      st.dropouts, st.dropout_episodes);
  return e;
}

std::string encoderScaleText(const std::string& side, double k, double sd, double since) {
  return fmt::format("{} encoder reads {:.1f} % {} (+-{:.1f} %) since t = {:.1f} s", side,
                     std::abs(1 - k) * 100, k < 1 ? "short" : "long", sd * 100, since);
}

bool Cusum::update(double t, double nu) {
  gp = std::max(0.0, gp + nu - kDrift);
  gm = std::max(0.0, gm - nu - kDrift);
  if (gp == 0) zp_s = t;
  if (gm == 0) zm_s = t;
  if (gp <= kThreshold && gm <= kThreshold) return false;
  onset_s = gp > kThreshold ? zp_s : zm_s;
  return true;
}

void Cusum::restart(double t) {
  gp = gm = 0;
  zp_s = zm_s = t;
}

namespace {
/// The "inconsistent" event of a CUSUM alarm of `sensor` at t_s (its text is the caller's).
HealthEvent alarmEvent(double t_s, const char* sensor, const Cusum& c) {
  HealthEvent e;
  e.t_s = t_s;
  e.sensor = sensor;
  e.kind = "inconsistent";
  e.parameter = "cusum";
  e.value = c.value();
  e.since_s = c.onset_s;
  return e;
}
}  // namespace

bool HealthMonitor::encoderInnovation(double t, double nu) {
  if (!std::isfinite(nu) || !enc_.update(t, nu)) return false;
  HealthEvent e = alarmEvent(t, "encoders", enc_);
  e.text = fmt::format(
      "encoders inconsistent with the gyro since t = {:.1f} s (CUSUM {:.1f} > {:.0f}): "
      "re-estimating the encoder scales",
      enc_.onset_s - t0_, e.value, kThreshold);
  events_.push_back(e);
  enc_.restart(t);
  return true;
}

bool HealthMonitor::gyroInnovation(double t, double nu, bool bias_estimated) {
  // Without a bias state nothing changes after an alarm: it is reported once.
  if (!std::isfinite(nu) || gyro_latched_ || !gyro_.update(t, nu)) return false;
  HealthEvent e = alarmEvent(t, "gyro", gyro_);
  e.text = fmt::format(
      "gyro reads {} than the standing chair's 0 since t = {:.1f} s (CUSUM {:.1f} > {:.0f}): {}",
      gyro_.high() ? "higher" : "lower", gyro_.onset_s - t0_, e.value, kThreshold,
      bias_estimated ? "re-estimating its bias"
                     : "its bias is not estimated (set estimate_gyro_bias = 1); the "
                       "encoder scales will take the blame while moving");
  events_.push_back(e);
  gyro_latched_ = !bias_estimated;
  gyro_.restart(t);
  return true;
}

void HealthMonitor::gyroBias(double t, double b, double sd) {
  constexpr double kReportSdRad = 0.002, kMinBiasRad = 0.005;  // rad/s
  if (!clearEnough(b, sd, kReportSdRad)) return;
  const double margin = std::max(3 * sd, kMinBiasRad);
  if (std::abs(b - gyro_reported_) <= std::max(margin, 3 * gyro_reported_sd_)) return;
  if (std::abs(b) <= margin && gyro_reported_ == 0) return;
  gyro_reported_ = b;
  gyro_reported_sd_ = sd;
  HealthEvent e;
  e.t_s = t;
  e.sensor = "gyro";
  e.kind = "estimate";
  e.effect = "gyro_bias";
  e.parameter = "bias_rad_s";
  e.value = b;
  e.sd = sd;
  e.since_s = gyro_.onset_s;
  e.text = fmt::format("gyro reads {:+.3f} rad/s (+-{:.3f}) too {} (bias) since t = {:.1f} s", b,
                       sd, b > 0 ? "high" : "low", gyro_.onset_s - t0_);
  events_.push_back(e);
}

void HealthMonitor::scales(double t, const SensorErrorEstimate& est) {
  if (!est.present) return;
  report(t, 0, est.encoder_scale_right, est.encoder_scale_right_sd);
  report(t, 1, est.encoder_scale_left, est.encoder_scale_left_sd);
  // The ratio alone while the sides are not resolved yet (straight driving since the onset).
  if (!(est.encoder_scale_right_sd < kReportSd && est.encoder_scale_left_sd < kReportSd))
    report(t, 2, est.encoder_scale_ratio, est.encoder_scale_ratio_sd);
}

void HealthMonitor::report(double t, int side, double k, double sd) {
  // Reported once sd < 0.5 % (and off by 3 sd, 1 %), or sooner when sd < 1 % and it is off
  // by 5 sd: a wheel sided by the fault prior carries the healthy wheel's 0.5 % and the
  // ratio's sd (~0.7 % in all), and a 5 % fault at +-0.7 % is news worth saying.
  if (!clearEnough(k - 1, sd, kReportSd)) return;
  const double margin = std::max(3 * sd, kMinFault);
  // New information: off nominal now and different from what was last reported (nominal
  // included: a fault that went away is reported back as nominal only via a new estimate).
  if (std::abs(k - reported_[side]) <= std::max(margin, 3 * reported_sd_[side])) return;
  if (std::abs(k - 1) <= margin && reported_[side] == 1) return;
  reported_[side] = k;
  reported_sd_[side] = sd;
  HealthEvent e;
  e.t_s = t;
  e.sensor = "encoders";
  e.kind = "estimate";
  e.effect = "encoder_scale";
  e.side = side < 2 ? kSide[side] : "";
  e.parameter = side < 2 ? "scale" : "scale_ratio";
  e.value = k;
  e.sd = sd;
  e.since_s = enc_.onset_s;
  e.text = side < 2 ? encoderScaleText(kSide[side], k, sd, enc_.onset_s - t0_)
                    : fmt::format(
                          "encoders disagree: right / left reads {:.4f} (+-{:.4f}) since t = "
                          "{:.1f} s (which side: the next turn tells)",
                          k, sd, enc_.onset_s - t0_);
  events_.push_back(e);
}

}  // namespace wheelchair::estimation
