#include "libwheelchair/estimation/DeadReckoning.h"

#include "libwheelchair/model/Kinematics.h"

#include <algorithm>
#include <cmath>
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
  // Gyro omega at t: linear interpolation, held beyond the ends (0 without gyro samples).
  auto omegaAt = [&](double t) {
    if (gy.empty()) return 0.0;
    if (t <= gy.front().first) return gy.front().second;
    if (t >= gy.back().first) return gy.back().second;
    const auto it = std::upper_bound(gy.begin(), gy.end(), std::make_pair(t, -1e300));
    const auto& b = *it;
    const auto& a = *(it - 1);
    if (b.first == a.first) return b.second;
    const double w = (t - a.first) / (b.first - a.first);
    return (1 - w) * a.second + w * b.second;
  };
  DeadReckoningSample s;
  s.t_s = iv.front().t0_s;
  out.push_back(s);
  for (const auto& w : iv) {
    // Sub-intervals split at the gyro sample times inside (t0, t1).
    double ta = w.t0_s;
    auto it = std::upper_bound(gy.begin(), gy.end(), std::make_pair(ta, 1e300));
    auto sub = [&](double tb) {
      if (tb <= ta) return;
      const double om = 0.5 * (omegaAt(ta) + omegaAt(tb));  // exact mean of the linear segment
      step(s, w.v_m_s, om, tb - ta);
      ta = tb;
    };
    for (; it != gy.end() && it->first < w.t1_s; ++it) {
      sub(it->first);
      s.t_s = ta;
      out.push_back(s);
    }
    sub(w.t1_s);
    s.t_s = w.t1_s;
    out.push_back(s);
  }
  return out;
}

double pathLength(const std::vector<DeadReckoningSample>& traj) {
  double L = 0;
  for (std::size_t i = 1; i < traj.size(); ++i)
    L += std::hypot(traj[i].x_m - traj[i - 1].x_m, traj[i].y_m - traj[i - 1].y_m);
  return L;
}

}  // namespace wheelchair::estimation
