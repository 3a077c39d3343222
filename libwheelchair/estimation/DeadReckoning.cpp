#include "libwheelchair/estimation/DeadReckoning.h"

#include "libwheelchair/model/Kinematics.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <tuple>

namespace wheelchair::estimation {

namespace {

std::vector<io::EncoderSample> sortedEncoders(std::vector<io::EncoderSample> e) {
  std::sort(e.begin(), e.end(), [](const io::EncoderSample& a, const io::EncoderSample& b) {
    return std::tie(a.t_s, a.right_ticks, a.left_ticks) <
           std::tie(b.t_s, b.right_ticks, b.left_ticks);
  });
  return e;
}

// Arc step with a continuous (unwrapped) heading.
void step(DeadReckoningSample& s, double v, double omega, double dt) {
  const Eigen::Vector3d p = model::integratePoseArc({s.x_m, s.y_m, s.phi_rad}, v, omega, dt);
  s.x_m = p(0);
  s.y_m = p(1);
  s.phi_rad += omega * dt;
  s.v_m_s = v;
  s.omega_rad_s = omega;
}

}  // namespace

std::vector<DeadReckoningSample> deadReckoningEncoders(const std::vector<io::EncoderSample>& enc,
                                                       const sensors::EncoderParams& p,
                                                       const model::Geometry& g) {
  const auto iv = sensors::wheelSpeedsFromTicks(sortedEncoders(enc), p, g);
  std::vector<DeadReckoningSample> out;
  if (iv.empty()) return out;
  out.reserve(iv.size() + 1);  // sized once: no doubling slack on a long drive
  DeadReckoningSample s;
  s.t_s = iv.front().t0_s;
  out.push_back(s);
  for (const auto& w : iv) {
    step(s, w.v_m_s, w.omega_rad_s, w.dt());
    s.t_s = w.t1_s;
    out.push_back(s);
  }
  return out;
}

namespace {

/// Encoder v + gyro omega one interval at a time (deadReckoningEncoderGyro's loop, header
/// comment): gyro samples arrive sorted by (time, value), finite only; an interval may be
/// integrated once the gyro is known past its end (knownPast). Gyro samples the integration
/// has passed are dropped, so a stream needs only a window of them.
class EncoderGyroIntegrator {
 public:
  void addGyro(double t, double w) {
    if (!have_first_) first_ = {t, w};
    have_first_ = true;
    gy_.emplace_back(t, w);
  }
  void setGyroComplete() { complete_ = true; }
  bool knownPast(double t) const { return complete_ || (!gy_.empty() && gy_.back().first > t); }
  template <typename Emit>
  void interval(const sensors::WheelSpeedInterval& w, const Emit& emit) {
    if (!started_) {
      started_ = true;
      s_.t_s = w.t0_s;
      emit(s_);
    }
    // Sub-intervals split at the gyro sample times inside (t0, t1).
    double ta = w.t0_s;
    auto it = std::upper_bound(gy_.begin(), gy_.end(), std::make_pair(ta, 1e300));
    auto sub = [&](double tb) {
      if (tb <= ta) return;
      const double om = 0.5 * (omegaAt(ta) + omegaAt(tb));  // exact mean of the linear segment
      step(s_, w.v_m_s, om, tb - ta);
      ta = tb;
    };
    for (; it != gy_.end() && it->first < w.t1_s; ++it) {
      sub(it->first);
      s_.t_s = ta;
      emit(s_);
    }
    sub(w.t1_s);
    s_.t_s = w.t1_s;
    emit(s_);
    // Later times are >= t1: keep the last sample before t1 and everything after it.
    while (gy_.size() >= 2 && gy_[1].first < w.t1_s) gy_.pop_front();
  }

 private:
  // Gyro omega at t: linear interpolation, held beyond the ends (0 without gyro samples).
  double omegaAt(double t) const {
    if (!have_first_) return 0.0;
    if (t <= first_.first) return first_.second;
    if (t >= gy_.back().first) return gy_.back().second;
    const auto it = std::upper_bound(gy_.begin(), gy_.end(), std::make_pair(t, -1e300));
    const auto& b = *it;
    const auto& a = *(it - 1);
    if (b.first == a.first) return b.second;
    const double w = (t - a.first) / (b.first - a.first);
    return (1 - w) * a.second + w * b.second;
  }

  std::deque<std::pair<double, double>> gy_;
  std::pair<double, double> first_;
  bool have_first_ = false, complete_ = false, started_ = false;
  DeadReckoningSample s_;
};

}  // namespace

std::vector<DeadReckoningSample> deadReckoningEncoderGyro(const std::vector<io::EncoderSample>& enc,
                                                          const std::vector<io::ImuSample>& imu,
                                                          const sensors::EncoderParams& p,
                                                          const model::Geometry& g) {
  const auto iv = sensors::wheelSpeedsFromTicks(sortedEncoders(enc), p, g);
  std::vector<DeadReckoningSample> out;
  if (iv.empty()) return out;
  std::vector<std::pair<double, double>> gy;
  gy.reserve(imu.size());
  for (const auto& m : imu)
    if (std::isfinite(m.gyro_z_rad_s)) gy.emplace_back(m.t_s, m.gyro_z_rad_s);
  std::sort(gy.begin(), gy.end());
  out.reserve(iv.size() + 1 + gy.size());  // at most one sample per interval and gyro time
  EncoderGyroIntegrator integ;
  for (const auto& [t, w] : gy) integ.addGyro(t, w);
  gy = {};
  integ.setGyroComplete();
  for (const auto& w : iv)
    integ.interval(w, [&](const DeadReckoningSample& s) { out.push_back(s); });
  return out;
}

DeadReckoningRun deadReckonRawlog(const std::string& rawlog, const io::RecordingSummary& summary,
                                  bool with_gyro, const sensors::EncoderParams& p,
                                  const model::Geometry& g,
                                  const std::function<void(const DeadReckoningSample&)>& f) {
  io::RawlogWindowReader in(rawlog, summary.lateness_s);
  io::SortedStream<io::EncoderSample> enc(io::encoderLess);
  io::SortedStream<io::ImuSample> imu(io::imuLess);
  sensors::WheelSpeedConverter conv(p, g.wheel_radius_m, g.track_width_m);
  std::deque<sensors::WheelSpeedInterval> pending;
  EncoderGyroIntegrator integ;
  DeadReckoningRun run;
  DeadReckoningSample prev, s;  // encoders only: the running pose
  const auto emit = [&](const DeadReckoningSample& x) {
    if (run.samples++ > 0) run.path_m += std::hypot(x.x_m - prev.x_m, x.y_m - prev.y_m);
    prev = x;
    f(x);
  };
  while (!in.eof()) {
    in.read([&](const io::AnySample& x, std::size_t k) {
      if (const auto* e = std::get_if<io::EncoderSample>(&x)) enc.push(*e, k);
      if (const auto* m = std::get_if<io::ImuSample>(&x); m && with_gyro) imu.push(*m, k);
    });
    const double wm = in.watermark();
    for (const io::ImuSample* m; (m = imu.head(wm)); imu.pop())
      if (std::isfinite(m->gyro_z_rad_s)) integ.addGyro(m->t_s, m->gyro_z_rad_s);
    if (in.eof()) integ.setGyroComplete();
    for (const io::EncoderSample* e; (e = enc.head(wm)); enc.pop())
      if (auto iv = conv.add(*e)) pending.push_back(*iv);
    for (; !pending.empty() && (!with_gyro || integ.knownPast(pending.front().t1_s));
         pending.pop_front()) {
      const auto& w = pending.front();
      if (with_gyro) {
        integ.interval(w, emit);
        continue;
      }
      if (run.samples == 0) {
        s.t_s = w.t0_s;
        emit(s);
      }
      step(s, w.v_m_s, w.omega_rad_s, w.dt());
      s.t_s = w.t1_s;
      emit(s);
    }
  }
  return run;
}

double pathLength(const std::vector<DeadReckoningSample>& traj) {
  double L = 0;
  for (std::size_t i = 1; i < traj.size(); ++i)
    L += std::hypot(traj[i].x_m - traj[i - 1].x_m, traj[i].y_m - traj[i - 1].y_m);
  return L;
}

}  // namespace wheelchair::estimation
