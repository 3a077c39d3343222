#include "libwheelchair/estimation/HealthMonitor.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>

namespace wheelchair::estimation {

namespace {
constexpr double kDrift = 0.5;       // CUSUM k (in sigmas)
constexpr double kThreshold = 12.0;  // CUSUM h
constexpr double kReportSd = 0.005;  // a scale is reported once its sd is below this (-)
constexpr double kMinFault = 0.01;   // and it is off by more than this and 3 sd (-)
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

bool HealthMonitor::encoderInnovation(double t, double nu) {
  if (!std::isfinite(nu)) return false;
  gp_ = std::max(0.0, gp_ + nu - kDrift);
  gm_ = std::max(0.0, gm_ - nu - kDrift);
  if (gp_ == 0) zp_ = t;
  if (gm_ == 0) zm_ = t;
  if (gp_ <= kThreshold && gm_ <= kThreshold) return false;
  onset_s_ = gp_ > kThreshold ? zp_ : zm_;
  HealthEvent e;
  e.t_s = t;
  e.sensor = "encoders";
  e.kind = "inconsistent";
  e.parameter = "cusum";
  e.value = std::max(gp_, gm_);
  e.since_s = onset_s_;
  e.text = fmt::format(
      "encoders inconsistent with the gyro since t = {:.1f} s (CUSUM {:.1f} > {:.0f}): "
      "re-estimating the encoder scales",
      onset_s_ - t0_, e.value, kThreshold);
  events_.push_back(e);
  gp_ = gm_ = 0;
  zp_ = zm_ = t;
  return true;
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
  if (!(sd < kReportSd)) return;
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
  e.since_s = onset_s_;
  e.text = side < 2 ? encoderScaleText(kSide[side], k, sd, onset_s_ - t0_)
                    : fmt::format(
                          "encoders disagree: right / left reads {:.4f} (+-{:.4f}) since t = "
                          "{:.1f} s (which side: the next turn tells)",
                          k, sd, onset_s_ - t0_);
  events_.push_back(e);
}

}  // namespace wheelchair::estimation
