#include "libwheelchair/diagnosis/CommandResponse.h"

#include "libwheelchair/estimation/CommandDrivenEkf.h"

#include "libwheelchair/model/Kinematics.h"
#include "libwheelchair/stats/Descriptive.h"
#include "libwheelchair/stats/Selection.h"
#include "libwheelchair/stats/Statistics.h"

#include <Eigen/Dense>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <optional>
#include <stdexcept>

namespace wheelchair::diagnosis {

using stats::effectiveSampleSize;
using stats::Evidence;
using stats::fitLinear;
using stats::Groups;
using stats::LinearFit;

using model::CommandKind;
using model::CommandResponseParams;
using model::CommandSignal;
using model::wrapAngle;
using stats::chi2Sf;
using stats::compareNestedWithFloor;
using stats::effectiveSampleSize;
using stats::Evidence;
using stats::fitLinear;
using stats::Groups;
using stats::LinearFit;
using stats::median;

namespace {

constexpr double kPi = 3.14159265358979323846;

struct Window {
  double t0, t1, v, w;
};

struct Prep {
  CommandSignal raw, clean;
  const io::Recording* rec = nullptr;
  std::vector<Window> win;
  double g0 = 0, g1 = 0;  // simulation grid range
  /// Measurement-noise floor of each window's mean velocity, per channel (0 v, 1 omega):
  /// differenced motion-capture noise plus the time resolution of the model's window means.
  std::vector<double> floor[2];
  double pose_noise_m = 0, heading_noise_rad = 0;
};

// Robust (MAD) white-noise scale of a sampled signal from its second differences
// (var = 6 sigma^2); the motion itself contributes a dt^2, negligible at motion-capture rates.
double secondDifferenceNoise(const std::vector<double>& t, const std::vector<double>& x) {
  std::vector<double> d;
  for (std::size_t k = 1; k + 1 < x.size(); ++k) {
    const double h0 = t[k] - t[k - 1], h1 = t[k + 1] - t[k];
    if (!(h0 > 0) || !(h1 > 0) || std::abs(h1 - h0) > 0.25 * std::max(h0, h1)) continue;
    d.push_back(std::abs(x[k + 1] - 2 * x[k] + x[k - 1]));
  }
  if (d.size() < 10) return 0;
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  return 1.4826 * d[d.size() / 2] / std::sqrt(6.0);
}

// Mean velocities over windows of Vicon poses (exact: differences of poses).
std::vector<Window> velocityWindows(const std::vector<io::GroundTruthPoseSample>& gt, double c0,
                                    double c1, double T) {
  std::vector<Window> out;
  std::size_t i = 0;
  while (i < gt.size()) {
    std::size_t j = i + 1;
    while (j < gt.size() && gt[j].t_s - gt[i].t_s < T) ++j;
    if (j >= gt.size()) break;
    const double dt = gt[j].t_s - gt[i].t_s;
    if (dt <= 2 * T && gt[i].t_s >= c0 && gt[j].t_s <= c1) {
      const double dphi = wrapAngle(gt[j].phi_rad - gt[i].phi_rad);
      const double dx = gt[j].x_m - gt[i].x_m, dy = gt[j].y_m - gt[i].y_m;
      const double d = std::hypot(dx, dy);
      const double arc = std::abs(dphi) > 1e-9 ? d * (dphi / 2) / std::sin(dphi / 2) : d;
      const double pm = gt[i].phi_rad + dphi / 2;
      const double sign = dx * std::cos(pm) + dy * std::sin(pm) >= 0 ? 1.0 : -1.0;
      out.push_back({gt[i].t_s, gt[j].t_s, sign * arc / dt, dphi / dt});
    }
    i = j;
  }
  return out;
}

Prep prepare(const io::Recording& rec, const CommandResponseOptions& o) {
  Prep p;
  p.rec = &rec;
  p.raw = commandSignal(rec, false, o.max_zero_run_s);
  p.clean = commandSignal(rec, true, o.max_zero_run_s);
  p.win = velocityWindows(rec.ground_truth, p.raw.startTime(), p.raw.endTime(), o.window_s);
  p.g0 = p.raw.startTime();
  p.g1 = p.win.empty() ? p.g0 : std::max(p.win.back().t1, p.g0);
  // Measurement model of a window mean: Var = 2 sigma_pose^2 / T^2 (two differenced poses)
  // + sum over command switches in the window of dc^2 dt^2 / 12 / T^2 (the model resolves a
  // switch time to its grid step dt: uniform timing error).
  {
    const auto& gt = rec.ground_truth;
    std::vector<double> t, x, y, ph;
    double unw = 0;
    for (std::size_t k = 0; k < gt.size(); ++k) {
      if (k > 0) unw += wrapAngle(gt[k].phi_rad - gt[k - 1].phi_rad);
      t.push_back(gt[k].t_s), x.push_back(gt[k].x_m), y.push_back(gt[k].y_m), ph.push_back(unw);
    }
    p.pose_noise_m =
        std::hypot(secondDifferenceNoise(t, x), secondDifferenceNoise(t, y)) / std::sqrt(2.0);
    p.heading_noise_rad = secondDifferenceNoise(t, ph);
  }
  const auto& cs = p.raw.samples();
  std::size_t ci = 0;
  for (const auto& w : p.win) {
    const double T = w.t1 - w.t0;
    double sw[2] = {0, 0};
    while (ci < cs.size() && cs[ci].t_s <= w.t0) ++ci;
    for (std::size_t k = ci; k < cs.size() && cs[k].t_s < w.t1; ++k) {
      if (k == 0) continue;
      sw[0] += std::pow(cs[k].v_m_s - cs[k - 1].v_m_s, 2);
      sw[1] += std::pow(cs[k].omega_rad_s - cs[k - 1].omega_rad_s, 2);
    }
    const double q = o.grid_dt_s * o.grid_dt_s / 12.0;
    p.floor[0].push_back((2 * p.pose_noise_m * p.pose_noise_m + sw[0] * q) / (T * T));
    p.floor[1].push_back((2 * p.heading_noise_rad * p.heading_noise_rad + sw[1] * q) / (T * T));
  }
  return p;
}

// Model of one channel (0 = v, 1 = omega).
struct ChannelModel {
  bool lag = false;
  double delay = 0, tau = 0;
  bool db_on = false;
  double db = 0;
  std::array<bool, 4> free{};
  std::array<double, 4> gain{1, 1, 1, 1};
};

// Walks a command signal at increasing query times.
class Cursor {
 public:
  explicit Cursor(const CommandSignal& s) : s_(s.samples()) {}
  Eigen::Vector2d at(double t) {
    while (i_ < s_.size() && s_[i_].t_s <= t) ++i_;
    if (i_ == 0) return Eigen::Vector2d::Zero();
    return {s_[i_ - 1].v_m_s, s_[i_ - 1].omega_rad_s};
  }

 private:
  const std::vector<model::CommandSample>& s_;
  std::size_t i_ = 0;
};

double interpCum(const std::vector<double>& C, double g0, double dt, double t) {
  const double u = (t - g0) / dt;
  if (u <= 0) return C.front() + u * 0;  // before the grid: nothing accumulated
  const std::size_t k = static_cast<std::size_t>(u);
  if (k + 1 >= C.size()) return C.back();
  const double a = u - k;
  return (1 - a) * C[k] + a * C[k + 1];
}

// Window means of the lag response to the command restricted to each kind (n_win x 4).
Eigen::MatrixXd kindColumns(const Prep& p, int ch, const ChannelModel& m, bool clean,
                            const CommandResponseOptions& o) {
  const CommandSignal& sig = clean ? p.clean : p.raw;
  const double dt = o.grid_dt_s;
  const std::size_t N = static_cast<std::size_t>(std::ceil((p.g1 - p.g0) / dt)) + 1;
  std::vector<double> C[4];
  for (auto& c : C) c.assign(N + 1, 0.0);
  double y[4] = {0, 0, 0, 0};
  const bool lag = m.lag && m.tau > 0;
  const double a = lag ? std::exp(-dt / m.tau) : 0, b = lag ? m.tau * (1 - a) : 0;
  CommandResponseParams kp;  // kind thresholds
  Cursor cur(sig);
  for (std::size_t k = 0; k < N; ++k) {
    const double tq = p.g0 + (k + 0.5) * dt - (m.lag ? m.delay : 0.0);
    const Eigen::Vector2d c = cur.at(tq);
    const int kind = static_cast<int>(model::classifyCommand(c(0), c(1), kp));
    double val = c(ch);
    if (m.db_on && std::abs(val) <= m.db) val = 0;
    for (int j = 0; j < 4; ++j) {
      const double in = j == kind ? val : 0.0;
      double integral;
      if (lag) {
        integral = in * dt + (y[j] - in) * b;
        y[j] = in + (y[j] - in) * a;
      } else {
        integral = in * dt;
        y[j] = in;
      }
      C[j][k + 1] = C[j][k] + integral;
    }
  }
  Eigen::MatrixXd X(p.win.size(), 4);
  for (std::size_t i = 0; i < p.win.size(); ++i) {
    const auto& w = p.win[i];
    for (int j = 0; j < 4; ++j)
      X(i, j) = (interpCum(C[j], p.g0, dt, w.t1) - interpCum(C[j], p.g0, dt, w.t0)) / (w.t1 - w.t0);
  }
  return X;
}

struct ChannelFit {
  double rss = 0;
  Eigen::VectorXd resid;
};

// Fits the free gains by least squares for the given lag/deadband; returns the residual.
ChannelFit fitChannel(const std::vector<Prep>& preps, int ch, ChannelModel& m, bool clean,
                      const CommandResponseOptions& o, bool fit_gains = true) {
  std::size_t n = 0;
  for (const auto& p : preps) n += p.win.size();
  Eigen::MatrixXd X(n, 4);
  Eigen::VectorXd y(n);
  std::size_t r = 0;
  for (const auto& p : preps) {
    const Eigen::MatrixXd Xp = kindColumns(p, ch, m, clean, o);
    for (std::size_t i = 0; i < p.win.size(); ++i, ++r) {
      X.row(r) = Xp.row(i);
      y(r) = ch == 0 ? p.win[i].v : p.win[i].w;
    }
  }
  std::vector<int> fr;
  Eigen::VectorXd target = y;
  for (int j = 0; j < 4; ++j) {
    if (fit_gains && m.free[j] && X.col(j).squaredNorm() > 1e-12)
      fr.push_back(j);
    else
      target -= m.gain[j] * X.col(j);
  }
  if (!fr.empty()) {
    Eigen::MatrixXd A(n, fr.size());
    for (std::size_t q = 0; q < fr.size(); ++q) A.col(q) = X.col(fr[q]);
    const Eigen::VectorXd g = A.colPivHouseholderQr().solve(target);
    for (std::size_t q = 0; q < fr.size(); ++q) {
      m.gain[fr[q]] = g(q);
      target -= g(q) * X.col(fr[q]);
    }
  }
  return {target.squaredNorm(), target};
}

// Optimises delay/tau (if lag) and the deadband (if on), gains by least squares inside.
ChannelFit optimiseChannel(const std::vector<Prep>& preps, int ch, ChannelModel& m, bool clean,
                           const CommandResponseOptions& o, bool coarse_lag) {
  const auto eval = [&](ChannelModel& mm) { return fitChannel(preps, ch, mm, clean, o).rss; };
  const std::vector<double> db_grid =
      ch == 0 ? std::vector<double>{0.005, 0.01, 0.015, 0.02, 0.03, 0.04, 0.05}
              : std::vector<double>{0.01, 0.02, 0.05, 0.1, 0.15, 0.2, 0.3};
  for (int round = 0; round < (m.db_on && m.lag ? 2 : 1); ++round) {
    if (m.db_on) {
      double best = std::numeric_limits<double>::infinity(), bdb = m.db;
      for (double d : db_grid) {
        ChannelModel t = m;
        t.db = d;
        const double s = eval(t);
        if (s < best) best = s, bdb = d;
      }
      m.db = bdb;
    }
    if (m.lag) {
      double best = std::numeric_limits<double>::infinity();
      if (coarse_lag && round == 0) {
        for (double d = 0; d <= o.max_delay_s + 1e-9; d += 0.04)
          for (double tau = 0; tau <= o.max_time_constant_s + 1e-9; tau += 0.05) {
            ChannelModel t = m;
            t.delay = d;
            t.tau = tau;
            const double s = eval(t);
            if (s < best) best = s, m.delay = d, m.tau = tau;
          }
      } else {
        best = eval(m);
      }
      double sd = 0.02, st = 0.025;
      while (sd > 0.002) {
        bool moved = false;
        for (int dim = 0; dim < 2; ++dim)
          for (int sgn : {-1, 1}) {
            ChannelModel t = m;
            if (dim == 0)
              t.delay = std::clamp(m.delay + sgn * sd, 0.0, o.max_delay_s);
            else
              t.tau = std::clamp(m.tau + sgn * st, 0.0, o.max_time_constant_s);
            const double s = eval(t);
            if (s < best - 1e-15) best = s, m.delay = t.delay, m.tau = t.tau, moved = true;
          }
        if (!moved) sd /= 2, st /= 2;
      }
    }
  }
  return fitChannel(preps, ch, m, clean, o);
}

struct FullModel {
  ChannelModel ch[2];
  bool zero = false;
};

CommandResponseParams toParams(const FullModel& M) {
  CommandResponseParams p;
  if (M.ch[0].lag) p.v.delay_s = M.ch[0].delay, p.v.time_constant_s = M.ch[0].tau;
  if (M.ch[1].lag) p.omega.delay_s = M.ch[1].delay, p.omega.time_constant_s = M.ch[1].tau;
  if (M.ch[0].db_on) p.v.deadband = M.ch[0].db;
  if (M.ch[1].db_on) p.omega.deadband = M.ch[1].db;
  for (int j = 0; j < 4; ++j) {
    p.v_gain[j] = M.ch[0].free[j] ? M.ch[0].gain[j] : 1.0;
    p.omega_gain[j] = M.ch[1].free[j] ? M.ch[1].gain[j] : 1.0;
  }
  return p;
}

struct Candidate {
  std::string effect;
  int ch;    // 0 v, 1 omega, -1 both
  int kind;  // command kind for command_gain
  int k;     // parameters added
};

bool isActive(const FullModel& M, const Candidate& c) {
  if (c.effect == "actuator_lag") return M.ch[c.ch].lag;
  if (c.effect == "deadband") return M.ch[c.ch].db_on;
  if (c.effect == "command_gain") return M.ch[c.ch].free[c.kind];
  return M.zero;
}

void setActive(FullModel& M, const Candidate& c, bool on) {
  if (c.effect == "actuator_lag") {
    M.ch[c.ch].lag = on;
    if (!on) M.ch[c.ch].delay = M.ch[c.ch].tau = 0;
  } else if (c.effect == "deadband") {
    M.ch[c.ch].db_on = on;
  } else if (c.effect == "command_gain") {
    M.ch[c.ch].free[c.kind] = on;
    if (!on) M.ch[c.ch].gain[c.kind] = 1;
  } else {
    M.zero = on;
  }
}

const char* channelName(int ch) {
  return ch == 0 ? "v" : ch == 1 ? "omega" : "v+omega";
}

Groups groupsOf(const std::vector<Prep>& preps) {
  Groups g;
  int s = 0;
  for (const auto& p : preps) {
    const int n = static_cast<int>(p.win.size());
    if (n > 0) g.push_back({s, s + n});
    s += n;
  }
  return g;
}

// Validation RSS of a channel with fixed parameters (no refit).
double fixedRss(const std::vector<Prep>& preps, int ch, const FullModel& M,
                const CommandResponseOptions& o) {
  ChannelModel m = M.ch[ch];
  return fitChannel(preps, ch, m, M.zero, o, /*fit_gains=*/false).rss;
}

// Ground-truth pose interpolated at t; false if outside or in a gap.
bool gtAt(const std::vector<io::GroundTruthPoseSample>& gt, double t, double max_gap, double& x,
          double& y, double& phi) {
  if (gt.empty() || t < gt.front().t_s || t > gt.back().t_s) return false;
  auto it =
      std::lower_bound(gt.begin(), gt.end(), t,
                       [](const io::GroundTruthPoseSample& s, double tt) { return s.t_s < tt; });
  if (it == gt.begin()) {
    x = it->x_m, y = it->y_m, phi = it->phi_rad;
    return true;
  }
  const auto& b = *it;
  const auto& a = *(it - 1);
  if (b.t_s - a.t_s > max_gap) return false;
  const double u = (t - a.t_s) / (b.t_s - a.t_s);
  x = a.x_m + u * (b.x_m - a.x_m);
  y = a.y_m + u * (b.y_m - a.y_m);
  phi = a.phi_rad + u * wrapAngle(b.phi_rad - a.phi_rad);
  return true;
}

nlohmann::json driftJson(const DriftMetrics& d) {
  return {{"drift_10s_m", d.drift_10s_m},
          {"drift_60s_m", d.drift_60s_m},
          {"heading_drift_10s_deg", d.heading_drift_10s_deg},
          {"heading_drift_60s_deg", d.heading_drift_60s_deg},
          {"n_windows_10s", d.n_10s},
          {"n_windows_60s", d.n_60s}};
}

using model::commandFeatures;

// Window means of command features for the unmodeled-term library.
Eigen::MatrixXd libraryFeatures(const Prep& p, bool clean) {
  const CommandSignal& s = clean ? p.clean : p.raw;
  Eigen::MatrixXd F(p.win.size(), 5);
  for (std::size_t i = 0; i < p.win.size(); ++i) {
    Eigen::Matrix<double, 5, 1> acc = Eigen::Matrix<double, 5, 1>::Zero();
    constexpr int K = 10;
    for (int q = 0; q < K; ++q) {
      const double t = p.win[i].t0 + (q + 0.5) / K * (p.win[i].t1 - p.win[i].t0);
      const Eigen::Vector2d c = s.at(t);
      acc += commandFeatures(c);
    }
    F.row(i) = acc.transpose() / K;
  }
  return F;
}
const char* const* kLibraryNames = commandLibraryNames().data();

// Window residuals of a channel with fixed parameters (no refit).
Eigen::VectorXd fixedResid(const std::vector<Prep>& preps, int ch, const FullModel& M,
                           const CommandResponseOptions& o) {
  ChannelModel m = M.ch[ch];
  return fitChannel(preps, ch, m, M.zero, o, /*fit_gains=*/false).resid;
}

// Windows where |contribution| > 2 sigma, merged over gaps < 1 s; at most 20 (longest).
std::vector<std::pair<double, double>> contributionSegments(const std::vector<Prep>& preps,
                                                            const Eigen::VectorXd& contrib,
                                                            double sigma) {
  std::vector<std::pair<double, double>> segs;
  std::size_t r = 0;
  for (const auto& p : preps)
    for (const auto& w : p.win) {
      if (r < static_cast<std::size_t>(contrib.size()) && std::abs(contrib(r)) > 2 * sigma) {
        if (!segs.empty() && w.t0 - segs.back().second < 1.0 && w.t0 >= segs.back().first)
          segs.back().second = w.t1;
        else
          segs.push_back({w.t0, w.t1});
      }
      ++r;
    }
  if (segs.size() > 20) {
    std::sort(segs.begin(), segs.end(),
              [](auto& a, auto& b) { return a.second - a.first > b.second - b.first; });
    segs.resize(20);
    std::sort(segs.begin(), segs.end());
  }
  return segs;
}

// Parameter covariance from the numerical Hessian of the fit RSS (Gauss-Newton: cov =
// 2 s^2 H^-1, s^2 = rss/n + floor), inflated by n / n_eff. `get`/`set` address the parameters.
Eigen::MatrixXd rssCovariance(const std::vector<Prep>& preps, int ch, const FullModel& M,
                              const CommandResponseOptions& o,
                              const std::vector<std::function<double&(ChannelModel&)>>& par,
                              const std::vector<double>& h, double floor_var, double n_eff) {
  const int k = static_cast<int>(par.size());
  ChannelModel base = M.ch[ch];
  // Keep the evaluation point inside the smooth region (a lag with tau = 0 switches off).
  for (int i = 0; i < k; ++i) par[i](base) = std::max(par[i](base), h[i]);
  auto f = [&](const std::vector<double>& d) {
    ChannelModel m = base;
    for (int i = 0; i < k; ++i) par[i](m) += d[i];
    return fitChannel(preps, ch, m, M.zero, o, false).rss;
  };
  std::vector<double> z(k, 0.0);
  const double f0 = f(z);
  Eigen::MatrixXd H(k, k);
  for (int i = 0; i < k; ++i) {
    auto p = z, m = z;
    p[i] = h[i], m[i] = -h[i];
    H(i, i) = (f(p) - 2 * f0 + f(m)) / (h[i] * h[i]);
    for (int j = 0; j < i; ++j) {
      auto pp = z, pm = z, mp = z, mm = z;
      pp[i] = h[i], pp[j] = h[j];
      pm[i] = h[i], pm[j] = -h[j];
      mp[i] = -h[i], mp[j] = h[j];
      mm[i] = -h[i], mm[j] = -h[j];
      H(i, j) = H(j, i) = (f(pp) - f(pm) - f(mp) + f(mm)) / (4 * h[i] * h[j]);
    }
  }
  std::size_t n = 0;
  for (const auto& p : preps) n += p.win.size();
  const double s2 = f0 / std::max<double>(1, n) + floor_var;
  const double infl = static_cast<double>(n) / std::max(1.0, n_eff);
  Eigen::FullPivLU<Eigen::MatrixXd> lu(H);
  if (!lu.isInvertible()) return Eigen::MatrixXd::Constant(k, k, std::nan(""));
  return 2 * s2 * infl * lu.inverse();
}

}  // namespace

const std::array<const char*, 5>& commandLibraryNames() {
  return model::commandFeatureNames();
}

bool UnmodeledTerms::empty() const {
  for (const auto& c : coef)
    for (double x : c)
      if (x != 0) return false;
  return true;
}

std::pair<std::vector<io::Recording>, std::vector<io::Recording>> splitRecordingsInTime(
    const std::vector<io::Recording>& recs, double fraction) {
  std::vector<io::Recording> a, b;
  for (const auto& r : recs) {
    double t0 = r.startTime(), t1 = r.endTime();
    if (!r.joystick.empty()) t0 = r.joystick.front().t_s, t1 = r.joystick.back().t_s;
    const double tc = t0 + fraction * (t1 - t0);
    io::Recording x, y;
    x.meta = y.meta = r.meta;
    auto cut = [tc](const auto& v, auto& lo, auto& hi) {
      for (const auto& e : v) (e.t_s < tc ? lo : hi).push_back(e);
    };
    cut(r.encoders, x.encoders, y.encoders);
    cut(r.imu, x.imu, y.imu);
    cut(r.motors, x.motors, y.motors);
    cut(r.sonar, x.sonar, y.sonar);
    cut(r.pozyx, x.pozyx, y.pozyx);
    cut(r.joystick, x.joystick, y.joystick);
    cut(r.ground_truth, x.ground_truth, y.ground_truth);
    cut(r.landmarks, x.landmarks, y.landmarks);
    // The command in effect at the cut continues into the second part.
    if (!x.joystick.empty() && (y.joystick.empty() || y.joystick.front().t_s > tc)) {
      io::JoystickSample j = x.joystick.back();
      j.t_s = tc;
      y.joystick.insert(y.joystick.begin(), j);
    }
    a.push_back(std::move(x));
    b.push_back(std::move(y));
  }
  return {a, b};
}

bool hasCommandResponseData(const io::Recording& rec) {
  return rec.joystick.size() >= 2 && rec.ground_truth.size() >= 2;
}

model::CommandSignal commandSignal(const io::Recording& rec, bool ignore_zero_runs,
                                   double max_zero_run_s) {
  std::vector<model::CommandSample> rows;
  rows.reserve(rec.joystick.size());
  for (const auto& j : rec.joystick) rows.push_back({j.t_s, j.v_cmd_m_s, j.omega_cmd_rad_s});
  model::CommandSignalOptions opt;
  opt.drop_short_zero_runs = ignore_zero_runs;
  opt.max_zero_run_s = max_zero_run_s;
  return model::CommandSignal(rows, opt);
}

DriftMetrics openLoopDrift(const std::vector<io::Recording>& recs,
                           const CommandResponseParams& params, bool ignore_zero_runs,
                           const CommandResponseOptions& o, const UnmodeledTerms* extra) {
  const model::CommandDrivenModel mdl(params);
  std::vector<double> e10, e60, h10, h60;
  const double dt = o.grid_dt_s;
  for (const auto& rec : recs) {
    if (!hasCommandResponseData(rec)) continue;
    const CommandSignal sig = commandSignal(rec, ignore_zero_runs, o.max_zero_run_s);
    const auto& gt = rec.ground_truth;
    const double g0 = sig.startTime();
    const double g1 = std::min(sig.endTime(), gt.back().t_s);
    if (g1 <= g0) continue;
    const std::size_t N = static_cast<std::size_t>((g1 - g0) / dt);
    std::vector<double> ds(N), dphi(N);
    Cursor cv(sig), cw(sig), cx(sig);
    const bool use_extra = extra && !extra->empty();
    double yv = 0, yw = 0;
    const double tv = params.v.time_constant_s, tw = params.omega.time_constant_s;
    for (std::size_t k = 0; k < N; ++k) {
      const double tm = g0 + (k + 0.5) * dt;
      const Eigen::Vector2d u =
          mdl.target(cv.at(tm - params.v.delay_s), cw.at(tm - params.omega.delay_s));
      const auto sv = model::lagStep(yv, u(0), dt, tv), sw = model::lagStep(yw, u(1), dt, tw);
      yv = sv.y_next, yw = sw.y_next;
      ds[k] = sv.integral, dphi[k] = sw.integral;
      if (use_extra) {
        const Eigen::Matrix<double, 5, 1> fe = commandFeatures(cx.at(tm));
        for (int j = 0; j < 5; ++j) {
          ds[k] += extra->coef[0][j] * fe(j) * dt;
          dphi[k] += extra->coef[1][j] * fe(j) * dt;
        }
      }
    }
    for (double W : {10.0, 60.0}) {
      for (double t0 = std::max(g0, gt.front().t_s); t0 + W <= g1; t0 += o.drift_start_every_s) {
        double x, y, phi, xe, ye, phie;
        if (!gtAt(gt, t0, o.max_gt_gap_s, x, y, phi) ||
            !gtAt(gt, t0 + W, o.max_gt_gap_s, xe, ye, phie))
          continue;
        const std::size_t k0 = static_cast<std::size_t>(std::llround((t0 - g0) / dt));
        const std::size_t k1 =
            std::min(N, static_cast<std::size_t>(std::llround((t0 + W - g0) / dt)));
        for (std::size_t k = k0; k < k1; ++k) {
          x += ds[k] * std::cos(phi + dphi[k] / 2);
          y += ds[k] * std::sin(phi + dphi[k] / 2);
          phi += dphi[k];
        }
        const double ep = std::hypot(x - xe, y - ye);
        const double eh = std::abs(wrapAngle(phi - phie)) * 180 / kPi;
        (W == 10.0 ? e10 : e60).push_back(ep);
        (W == 10.0 ? h10 : h60).push_back(eh);
      }
    }
  }
  DriftMetrics d;
  d.drift_10s_m = median(e10);
  d.drift_60s_m = median(e60);
  d.heading_drift_10s_deg = median(h10);
  d.heading_drift_60s_deg = median(h60);
  d.n_10s = e10.size();
  d.n_60s = e60.size();
  return d;
}

CommandResponseResult diagnoseCommandResponse(const std::vector<io::Recording>& fit,
                                              const std::vector<io::Recording>& validate,
                                              const CommandResponseOptions& o) {
  if (fit.empty() || validate.empty())
    throw std::invalid_argument("diagnoseCommandResponse: need fit and validation recordings");
  for (const auto* set : {&fit, &validate})
    for (const auto& r : *set)
      if (!hasCommandResponseData(r))
        throw std::invalid_argument(
            "diagnoseCommandResponse: every recording needs JOYSTICK commands and GROUND_TRUTH");
  std::vector<Prep> F, V;
  for (const auto& r : fit) F.push_back(prepare(r, o));
  for (const auto& r : validate) V.push_back(prepare(r, o));
  const Groups gF = groupsOf(F);
  CommandResponseResult res;
  res.max_zero_run_s = o.max_zero_run_s;
  for (const auto& p : F) res.fit_windows += p.win.size();
  for (const auto& p : V) res.validation_windows += p.win.size();
  if (res.fit_windows < 20) throw std::invalid_argument("diagnoseCommandResponse: too little data");

  // Catalogue.
  std::vector<Candidate> cat = {{"actuator_lag", 0, -1, 2},
                                {"actuator_lag", 1, -1, 2},
                                {"command_gain", 0, static_cast<int>(CommandKind::Straight), 1},
                                {"command_gain", 0, static_cast<int>(CommandKind::Arc), 1},
                                {"command_gain", 1, static_cast<int>(CommandKind::TurnInPlace), 1},
                                {"command_gain", 1, static_cast<int>(CommandKind::Arc), 1},
                                {"deadband", 0, -1, 1},
                                {"deadband", 1, -1, 1},
                                {"ignored_zero_commands", -1, -1, 1}};

  // Mean measurement-noise floor of the fit windows per channel (see prepare()).
  double floorF[2] = {0, 0};
  for (const auto& p : F)
    for (int ch = 0; ch < 2; ++ch)
      for (double f : p.floor[ch]) floorF[ch] += f;
  const double nF = static_cast<double>(res.fit_windows);
  for (double& f : floorF) f /= nF;
  res.noise_floor_v_m_s = std::sqrt(floorF[0]);
  res.noise_floor_omega_rad_s = std::sqrt(floorF[1]);
  auto compare = [&](int ch, double rss0, double rss1, int k, double ne) {
    return compareNestedWithFloor(rss0, rss1, nF, k, ne, floorF[ch]);
  };

  FullModel M;
  ChannelFit cur[2];
  for (int ch = 0; ch < 2; ++ch) cur[ch] = fitChannel(F, ch, M.ch[ch], M.zero, o);
  for (int ch = 0; ch < 2; ++ch) {
    ChannelModel m = M.ch[ch];
    ChannelFit f = fitChannel(V, ch, m, false, o, false);
    (ch == 0 ? res.validation_v : res.validation_omega).rms_before =
        std::sqrt(f.rss / std::max<double>(1, f.resid.size()));
  }
  // Forward selection over the catalogue (stats::selectTerms: Bonferroni over its terms).
  const stats::SelectionRule rule{o.alpha, static_cast<int>(cat.size()), o.min_delta_bic};
  std::vector<Candidate> accepted;
  std::vector<CommandResponseFinding> acc_findings;
  {
    double neff[2];
    struct Trial {
      FullModel M;
      ChannelFit fit[2];
      Evidence ev;
    };
    std::vector<Trial> trials(cat.size());
    stats::SelectionHooks h;
    h.step = [&](const std::vector<int>&) {
      for (int ch = 0; ch < 2; ++ch) neff[ch] = effectiveSampleSize(cur[ch].resid, gF, o.hac_lags);
    };
    h.evaluate = [&](int ci, const std::vector<int>&) {
      stats::Trial t;
      const Candidate& c = cat[ci];
      t.skip = isActive(M, c);
      if (t.skip) return t;
      FullModel T = M;
      setActive(T, c, true);
      Trial& tr = trials[ci];
      tr = Trial{T, {cur[0], cur[1]}, {}};
      const bool coarse = c.effect == "actuator_lag";
      for (int ch = 0; ch < 2; ++ch) {
        if (c.ch >= 0 && c.ch != ch) continue;
        tr.fit[ch] = optimiseChannel(F, ch, tr.M.ch[ch], tr.M.zero, o, coarse);
      }
      if (c.ch >= 0) {
        tr.ev = compare(c.ch, cur[c.ch].rss, tr.fit[c.ch].rss, c.k, neff[c.ch]);
      } else {
        const Evidence a = compare(0, cur[0].rss, tr.fit[0].rss, c.k, neff[0]);
        const Evidence b = compare(1, cur[1].rss, tr.fit[1].rss, c.k, neff[1]);
        tr.ev.lr = a.lr + b.lr;
        tr.ev.k = c.k;
        tr.ev.n_eff = std::min(neff[0], neff[1]);
        tr.ev.p_value = chi2Sf(std::max(0.0, tr.ev.lr), c.k);
        tr.ev.delta_bic = -tr.ev.lr + c.k * std::log(std::max(1.0, tr.ev.n_eff));
      }
      t.evidence = tr.ev;
      // Plausibility.
      bool plausible = true;
      if (c.effect == "command_gain") {
        const double g = tr.M.ch[c.ch].gain[c.kind];
        plausible = g >= o.min_gain && g <= o.max_gain;
      }
      if (c.effect == "actuator_lag") plausible = tr.M.ch[c.ch].delay > 0 || tr.M.ch[c.ch].tau > 0;
      if (!plausible) t.reject = "physically implausible parameters";
      return t;
    };
    h.accepted = [&](int ci) {
      const Trial& best = trials[ci];
      M = best.M;
      cur[0] = best.fit[0];
      cur[1] = best.fit[1];
      accepted.push_back(cat[ci]);
      CommandResponseFinding fd;
      fd.effect = cat[ci].effect;
      fd.channel = channelName(cat[ci].ch);
      if (cat[ci].kind >= 0) fd.kind = model::toString(static_cast<CommandKind>(cat[ci].kind));
      fd.delta_bic = best.ev.delta_bic;
      fd.lr = best.ev.lr;
      fd.p_value = best.ev.p_value;
      fd.n_eff = best.ev.n_eff;
      fd.k = cat[ci].k;
      fd.bonferroni_level = rule.level();
      acc_findings.push_back(fd);
    };
    stats::selectTerms(static_cast<int>(cat.size()), rule, h);
  }

  // Final parameters of every accepted term; validation of each (removed, others fixed).
  FullModel Final = M;
  for (std::size_t i = 0; i < accepted.size(); ++i) {
    const Candidate& c = accepted[i];
    CommandResponseFinding& fd = acc_findings[i];
    FullModel W = M;
    setActive(W, c, false);
    double with = 0, without = 0;
    for (int ch = 0; ch < 2; ++ch) {
      if (c.ch >= 0 && c.ch != ch) continue;
      with += fixedRss(V, ch, M, o);
      without += fixedRss(V, ch, W, o);
    }
    fd.validation_rss_with = with;
    fd.validation_rss_without = without;
    fd.validated = with < without;
    if (!fd.validated) setActive(Final, c, false);
  }
  for (std::size_t i = 0; i < accepted.size(); ++i) {
    const Candidate& c = accepted[i];
    CommandResponseFinding& fd = acc_findings[i];
    if (c.effect == "actuator_lag") {
      fd.parameters["delay_s"] = M.ch[c.ch].delay;
      fd.parameters["time_constant_s"] = M.ch[c.ch].tau;
    } else if (c.effect == "command_gain") {
      fd.parameters["scale"] = M.ch[c.ch].gain[c.kind];
    } else if (c.effect == "deadband") {
      fd.parameters[c.ch == 0 ? "threshold_m_s" : "threshold_rad_s"] = M.ch[c.ch].db;
    } else {
      fd.parameters["max_run_s"] = o.max_zero_run_s;
    }
    res.findings.push_back(fd);
  }

  // Uncertainty, segments and held-out drift of each catalogue term.
  const CommandResponseParams final_params = toParams(Final);
  const DriftMetrics drift_final = openLoopDrift(validate, final_params, Final.zero, o);
  std::size_t nV = 0;
  for (const auto& p : V) nV += p.win.size();
  for (std::size_t i = 0; i < accepted.size(); ++i) {
    const Candidate& c = accepted[i];
    CommandResponseFinding& fd = res.findings[i];
    const double nv = std::max<double>(1, nV) * (c.ch >= 0 ? 1 : 2);
    fd.validation_rms_with = std::sqrt(fd.validation_rss_with / nv);
    fd.validation_rms_without = std::sqrt(fd.validation_rss_without / nv);
    if (fd.validated) {
      FullModel W = Final;
      setActive(W, c, false);
      fd.drift_without = openLoopDrift(validate, toParams(W), W.zero, o);
      fd.drift_with = drift_final;
    } else {
      FullModel W = Final;
      setActive(W, c, true);
      if (c.ch >= 0) W.ch[c.ch] = M.ch[c.ch];
      fd.drift_without = drift_final;
      fd.drift_with = openLoopDrift(validate, toParams(W), W.zero, o);
    }
    // Segments: where the term changes the fit windows by more than 2 sigma.
    FullModel Wo = M;
    setActive(Wo, c, false);
    for (int ch = 0; ch < 2; ++ch) {
      if (c.ch >= 0 && c.ch != ch) continue;
      const Eigen::VectorXd contrib = fixedResid(F, ch, Wo, o) - cur[ch].resid;
      const double sig = std::sqrt(cur[ch].rss / nF + floorF[ch]);
      auto seg = contributionSegments(F, contrib, sig);
      fd.segments.insert(fd.segments.end(), seg.begin(), seg.end());
    }
    std::sort(fd.segments.begin(), fd.segments.end());
    // Uncertainty from the curvature of the fit RSS.
    if (c.effect == "actuator_lag") {
      const Eigen::MatrixXd C = rssCovariance(F, c.ch, M, o,
                                              {[](ChannelModel& m) -> double& { return m.delay; },
                                               [](ChannelModel& m) -> double& { return m.tau; }},
                                              {0.005, 0.005}, floorF[c.ch], fd.n_eff);
      fd.uncertainty["delay_s"] = std::sqrt(std::max(0.0, C(0, 0)));
      fd.uncertainty["time_constant_s"] = std::sqrt(std::max(0.0, C(1, 1)));
    } else if (c.effect == "command_gain") {
      const int kind = c.kind;
      const Eigen::MatrixXd C = rssCovariance(
          F, c.ch, M, o, {[kind](ChannelModel& m) -> double& { return m.gain[kind]; }}, {0.01},
          floorF[c.ch], fd.n_eff);
      fd.uncertainty["scale"] = std::sqrt(std::max(0.0, C(0, 0)));
    }
  }

  // Unmodeled: residual structure explained by command features, per channel; Bonferroni
  // over the library terms of both channels (5 x 2).
  const stats::SelectionRule lib_rule{o.alpha, 2 * 5, o.min_delta_bic};
  for (int ch = 0; ch < 2; ++ch) {
    std::size_t n = cur[ch].resid.size();
    Eigen::MatrixXd L(n, 5);
    std::size_t r = 0;
    for (const auto& p : F) {
      const Eigen::MatrixXd Lp = libraryFeatures(p, M.zero);
      L.middleRows(r, Lp.rows()) = Lp;
      r += Lp.rows();
    }
    std::vector<int> chosen;
    Eigen::VectorXd resid = cur[ch].resid;
    double rss = resid.squaredNorm();
    Eigen::VectorXd beta;
    double ne = 0;
    std::vector<Eigen::VectorXd> tbeta(5), tres(5);
    std::vector<Evidence> tev(5);
    stats::SelectionHooks h;
    h.step = [&](const std::vector<int>&) { ne = effectiveSampleSize(resid, gF, o.hac_lags); };
    h.evaluate = [&](int j, const std::vector<int>& acc) {
      stats::Trial t;
      t.skip = L.col(j).squaredNorm() < 1e-12;
      if (t.skip) return t;
      std::vector<int> cols = acc;
      cols.push_back(j);
      Eigen::MatrixXd A(n, cols.size());
      for (std::size_t q = 0; q < cols.size(); ++q) A.col(q) = L.col(cols[q]);
      tbeta[j] = A.colPivHouseholderQr().solve(cur[ch].resid);
      tres[j] = cur[ch].resid - A * tbeta[j];
      tev[j] = t.evidence = compare(ch, rss, tres[j].squaredNorm(), 1, ne);
      return t;
    };
    h.accepted = [&](int j) {
      chosen.push_back(j);
      resid = tres[j];
      rss = resid.squaredNorm();
      beta = tbeta[j];
      CommandResponseFinding fd;
      fd.effect = "unmodeled";
      fd.channel = channelName(ch);
      fd.kind = kLibraryNames[j];
      fd.delta_bic = tev[j].delta_bic;
      fd.lr = tev[j].lr;
      fd.p_value = tev[j].p_value;
      fd.n_eff = tev[j].n_eff;
      fd.k = 1;
      fd.bonferroni_level = lib_rule.level();
      res.findings.push_back(fd);
    };
    stats::selectTerms(5, lib_rule, h);
    // Coefficients (joint) and validation of the unmodeled terms as a group.
    if (!chosen.empty()) {
      Eigen::VectorXd vres;
      {
        ChannelModel m = Final.ch[ch];
        vres = fitChannel(V, ch, m, Final.zero, o, false).resid;
      }
      Eigen::MatrixXd LV(vres.size(), 5);
      std::size_t q = 0;
      for (const auto& p : V) {
        const Eigen::MatrixXd Lp = libraryFeatures(p, Final.zero);
        LV.middleRows(q, Lp.rows()) = Lp;
        q += Lp.rows();
      }
      Eigen::VectorXd pred = Eigen::VectorXd::Zero(vres.size());
      for (std::size_t c = 0; c < chosen.size(); ++c) pred += beta(c) * LV.col(chosen[c]);
      const double without = vres.squaredNorm(), with = (vres - pred).squaredNorm();
      // HAC uncertainty of the joint coefficients, and where the terms act.
      Eigen::MatrixXd A(n, chosen.size());
      for (std::size_t q2 = 0; q2 < chosen.size(); ++q2) A.col(q2) = L.col(chosen[q2]);
      const LinearFit lf = fitLinear(A, cur[ch].resid, gF, o.hac_lags);
      const Eigen::VectorXd contrib = A * beta;
      const auto seg = contributionSegments(F, contrib, std::sqrt(rss / nF + floorF[ch]));
      const bool ok = with < without;
      std::size_t c = 0;
      for (auto& fd : res.findings) {
        if (fd.effect != "unmodeled" || fd.channel != channelName(ch)) continue;
        if (ok) res.unmodeled.coef[ch][chosen[c]] = beta(c);
        fd.uncertainty["coefficient"] =
            lf.ok ? std::sqrt(std::max(0.0, lf.cov(c, c))) : std::nan("");
        fd.parameters["coefficient"] = beta(c++);
        fd.validation_rss_with = with;
        fd.validation_rss_without = without;
        fd.validation_rms_with = std::sqrt(with / std::max<double>(1, vres.size()));
        fd.validation_rms_without = std::sqrt(without / std::max<double>(1, vres.size()));
        fd.validated = ok;
        fd.segments = seg;
      }
    }
  }
  // Held-out drift of each channel's unmodeled terms (added to the selected model).
  for (int ch = 0; ch < 2; ++ch) {
    UnmodeledTerms one;
    one.coef[ch] = res.unmodeled.coef[ch];
    bool any = false;
    for (auto& fd : res.findings) any |= fd.effect == "unmodeled" && fd.channel == channelName(ch);
    if (!any) continue;
    if (one.empty()) {  // not validated: show what it would do
      std::size_t c = 0;
      for (auto& fd : res.findings)
        if (fd.effect == "unmodeled" && fd.channel == channelName(ch)) {
          for (int j = 0; j < 5; ++j)
            if (fd.kind == kLibraryNames[j]) one.coef[ch][j] = fd.parameters["coefficient"];
          ++c;
        }
    }
    const DriftMetrics d = openLoopDrift(validate, final_params, Final.zero, o, &one);
    for (auto& fd : res.findings)
      if (fd.effect == "unmodeled" && fd.channel == channelName(ch))
        fd.drift_without = drift_final, fd.drift_with = d;
  }

  res.params = toParams(Final);
  res.ignore_zero_runs = Final.zero;
  for (int ch = 0; ch < 2; ++ch) {
    ChannelModel m = Final.ch[ch];
    ChannelFit f = fitChannel(V, ch, m, Final.zero, o, false);
    auto& st = ch == 0 ? res.validation_v : res.validation_omega;
    st.rms_after = std::sqrt(f.rss / std::max<double>(1, f.resid.size()));
    st.n = f.resid.size();
  }
  const CommandResponseParams nominal;
  res.fit_before = openLoopDrift(validate, nominal, false, o);
  res.fit_after = drift_final;
  res.fit_after_unmodeled = openLoopDrift(validate, res.params, res.ignore_zero_runs, o,
                                          res.unmodeled.empty() ? nullptr : &res.unmodeled);
  res.fit_before_on_fit = openLoopDrift(fit, nominal, false, o);
  res.fit_after_on_fit = openLoopDrift(fit, res.params, res.ignore_zero_runs, o);
  return res;
}

nlohmann::json CommandResponseResult::toJson() const {
  nlohmann::json j;
  j["stage"] = "command_response";
  j["findings"] = nlohmann::json::array();
  for (const auto& f : findings) {
    nlohmann::json fj = {{"effect", f.effect},
                         {"channel", f.channel},
                         {"parameters", f.parameters},
                         {"evidence",
                          {{"delta_bic", f.delta_bic},
                           {"likelihood_ratio", f.lr},
                           {"p_value", f.p_value},
                           {"n_eff", f.n_eff},
                           {"k", f.k}}},
                         {"uncertainty", f.uncertainty},
                         {"validation",
                          {{"rss_without", f.validation_rss_without},
                           {"rss_with", f.validation_rss_with},
                           {"rms_without", f.validation_rms_without},
                           {"rms_with", f.validation_rms_with},
                           {"drift_without", driftJson(f.drift_without)},
                           {"drift_with", driftJson(f.drift_with)},
                           {"validated", f.validated}}}};
    fj["evidence"]["bonferroni_level"] = f.bonferroni_level;
    nlohmann::json seg = nlohmann::json::array();
    for (const auto& sg : f.segments) seg.push_back({sg.first, sg.second});
    fj["segments"] = seg;
    if (!f.kind.empty()) fj[f.effect == "unmodeled" ? "term" : "kind"] = f.kind;
    j["findings"].push_back(fj);
  }
  nlohmann::json m;
  m["v"] = {{"delay_s", params.v.delay_s},
            {"time_constant_s", params.v.time_constant_s},
            {"deadband_m_s", params.v.deadband}};
  m["omega"] = {{"delay_s", params.omega.delay_s},
                {"time_constant_s", params.omega.time_constant_s},
                {"deadband_rad_s", params.omega.deadband}};
  for (int k = 0; k < model::kNumCommandKinds; ++k) {
    const char* name = model::toString(static_cast<CommandKind>(k));
    m["v_gain"][name] = params.v_gain[k];
    m["omega_gain"][name] = params.omega_gain[k];
  }
  m["ignore_zero_runs"] = ignore_zero_runs;
  m["max_zero_run_s"] = max_zero_run_s;
  j["model"] = m;
  j["fit_before"] = driftJson(fit_before);
  j["fit_after"] = driftJson(fit_after);
  j["fit_after_with_unmodeled"] = driftJson(fit_after_unmodeled);
  j["noise_floor"] = {{"v_m_s", noise_floor_v_m_s}, {"omega_rad_s", noise_floor_omega_rad_s}};
  j["on_fit_recordings"] = {{"before", driftJson(fit_before_on_fit)},
                            {"after", driftJson(fit_after_on_fit)}};
  j["validation_residual_rms"] = {
      {"v_m_s", {{"before", validation_v.rms_before}, {"after", validation_v.rms_after}}},
      {"omega_rad_s",
       {{"before", validation_omega.rms_before}, {"after", validation_omega.rms_after}}},
      {"windows", validation_windows}};
  j["fit_windows"] = fit_windows;
  return j;
}

namespace {

nlohmann::json driftFit(const DriftMetrics& d, const std::string& channel, double rms,
                        const char* rms_key) {
  nlohmann::json j = driftJson(d);
  if (!channel.empty()) {
    j["channel"] = channel;
    j[rms_key] = rms;
  }
  return j;
}

const char* channelWords(const std::string& ch) {
  return ch == "v" ? "forward speed" : ch == "omega" ? "turn rate" : "velocities";
}

}  // namespace

void addCommandResponseFindings(const CommandResponseResult& r, DiagnosisReport& rep) {
  nlohmann::json rejected = nlohmann::json::array();
  for (const auto& f : r.findings) {
    if (f.effect == "unmodeled") continue;
    if (!f.validated) {
      rejected.push_back({{"effect", f.effect},
                          {"channel", f.channel},
                          {"kind", f.kind},
                          {"reason", "does not reduce the residual on the validation recordings"}});
      continue;
    }
    Finding x;
    x.command_response = true;
    x.effect = f.effect;
    x.channels = f.channel == "v+omega" ? std::vector<std::string>{"v", "omega"}
                                        : std::vector<std::string>{f.channel};
    x.segments = f.segments;
    for (const auto& [k, v] : f.parameters) x.parameters[k] = v;
    for (const auto& [k, v] : f.uncertainty) x.uncertainty[k] = v;
    if (f.effect != "actuator_lag" && f.effect != "ignored_zero_commands")
      x.parameters["channel"] = f.channel;
    if (!f.kind.empty()) x.parameters["kind"] = f.kind;
    const std::string what = channelWords(f.channel);
    auto pm = [&](const char* k) {
      auto it = f.uncertainty.find(k);
      return it == f.uncertainty.end() ? std::string() : fmt::format(" (+- {:.3f})", it->second);
    };
    if (f.effect == "actuator_lag") {
      x.description = fmt::format(
          "the robot's {} follows the command {:.2f} s late{} with a {:.2f} s time constant{}: "
          "the drive responds with a pure delay and a first-order lag, not instantly",
          what, f.parameters.at("delay_s"), pm("delay_s"), f.parameters.at("time_constant_s"),
          pm("time_constant_s"));
    } else if (f.effect == "command_gain") {
      const double g = f.parameters.at("scale");
      const std::string kind = f.kind == "turn_in_place" ? "turning in place"
                               : f.kind == "arc"         ? "in arcs"
                                                         : "driving " + f.kind;
      x.description = fmt::format(
          "{}, the robot's {} is {:.2f} x the commanded value{} ({:.0f}% {}): the response "
          "depends on the kind of command",
          kind, what, g, pm("scale"), std::abs(g - 1) * 100, g < 1 ? "less" : "more");
    } else if (f.effect == "deadband") {
      const double th = f.parameters.begin()->second;
      x.description = fmt::format(
          "commanded {} of magnitude <= {:.3g} {} do not move the robot: "
          "a deadband",
          what, th, f.channel == "v" ? "m/s" : "rad/s");
    } else {
      x.description = fmt::format(
          "the robot ignores (0,0) command lines lasting less than {:.2f} s between moving "
          "commands (logging blips)",
          f.parameters.at("max_run_s"));
    }
    x.evidence = {{"likelihood_ratio", f.lr},
                  {"p_value", f.p_value},
                  {"bonferroni_level", f.bonferroni_level},
                  {"delta_bic", f.delta_bic},
                  {"n_eff", f.n_eff},
                  {"added_parameters", f.k},
                  {"validation_rss_without", f.validation_rss_without},
                  {"validation_rss_with", f.validation_rss_with},
                  {"validated", f.validated}};
    const char* unit = f.channel == "v" ? "validation_rms_m_s" : "validation_rms_rad_s";
    if (f.channel == "v+omega") unit = "validation_rms";
    x.fit_before = driftFit(f.drift_without, f.channel, f.validation_rms_without, unit);
    x.fit_after = driftFit(f.drift_with, f.channel, f.validation_rms_with, unit);
    rep.addFinding(x);
  }
  // Unmodeled terms: one finding per channel.
  for (const std::string ch : {"v", "omega"}) {
    std::vector<const CommandResponseFinding*> terms;
    for (const auto& f : r.findings)
      if (f.effect == "unmodeled" && f.channel == ch) terms.push_back(&f);
    if (terms.empty()) continue;
    if (!terms.front()->validated) {
      for (auto* t : terms)
        rejected.push_back(
            {{"effect", "unmodeled"},
             {"channel", ch},
             {"term", t->kind},
             {"reason", "does not reduce the residual on the validation recordings"}});
      continue;
    }
    Finding x;
    x.command_response = true;
    x.effect = "unmodeled";
    x.channels = {ch};
    x.segments = terms.front()->segments;
    std::string eq = ch + " - model =";
    nlohmann::json per = nlohmann::json::array();
    for (auto* t : terms) {
      const double c = t->parameters.at("coefficient");
      x.parameters[t->kind] = c;
      if (t->uncertainty.count("coefficient"))
        x.uncertainty[t->kind] = t->uncertainty.at("coefficient");
      eq += fmt::format(" {:+.4g}*{}", c, t->kind);
      per.push_back({{"term", t->kind},
                     {"likelihood_ratio", t->lr},
                     {"p_value", t->p_value},
                     {"delta_bic", t->delta_bic},
                     {"n_eff", t->n_eff}});
    }
    x.parameters["channel"] = ch;
    x.description = fmt::format(
        "a term outside the catalogue acts on the robot's {}: {} ({}; commands in m/s, rad/s)",
        channelWords(ch), eq, ch == "v" ? "m/s" : "rad/s");
    x.evidence = {{"terms", per},
                  {"added_parameters", terms.size()},
                  {"validation_rss_without", terms.front()->validation_rss_without},
                  {"validation_rss_with", terms.front()->validation_rss_with},
                  {"validated", true}};
    const char* unit = ch == "v" ? "validation_rms_m_s" : "validation_rms_rad_s";
    x.fit_before =
        driftFit(terms.front()->drift_without, ch, terms.front()->validation_rms_without, unit);
    x.fit_after = driftFit(terms.front()->drift_with, ch, terms.front()->validation_rms_with, unit);
    rep.addFinding(x);
  }
  rep.fit_before = driftJson(r.fit_before);
  // The corrected model: the selected catalogue terms plus the validated unmodeled terms
  // (validation["command_response"]["fit_after"] is the catalogue terms alone).
  rep.fit_after = driftJson(r.unmodeled.empty() ? r.fit_after : r.fit_after_unmodeled);
  rep.fit_after["includes_unmodeled_terms"] = !r.unmodeled.empty();
  rep.validation["command_response"] = r.toJson();
  rep.channels["v"] = {{"unit", "m/s (mean over ground-truth windows)"},
                       {"before", {{"rms", r.validation_v.rms_before}}},
                       {"after", {{"rms", r.validation_v.rms_after}}},
                       {"noise_floor_rms", r.noise_floor_v_m_s}};
  rep.channels["omega"] = {{"unit", "rad/s (mean over ground-truth windows)"},
                           {"before", {{"rms", r.validation_omega.rms_before}}},
                           {"after", {{"rms", r.validation_omega.rms_after}}},
                           {"noise_floor_rms", r.noise_floor_omega_rad_s}};
  if (!rejected.empty()) rep.info["command_response_rejected"] = rejected;
  rep.config_updates["mrclam_response"] = commandResponseConfigKeys(r);
}

std::map<std::string, std::string> commandResponseConfigKeys(const CommandResponseResult& r) {
  estimation::CommandDrivenEkfOptions o;
  o.response = r.params;
  o.ignore_zero_runs = r.ignore_zero_runs;
  o.max_zero_run_s = r.max_zero_run_s;
  o.unmodeled = r.unmodeled.coef;
  return estimation::responseConfigKeys(o);
}

void writeCommandResponseConfig(const CommandResponseResult& r, config::WheelchairConfig& cfg) {
  for (const auto& [key, value] : commandResponseConfigKeys(r))
    cfg.set("mrclam_response", key, value);
}

}  // namespace wheelchair::diagnosis
