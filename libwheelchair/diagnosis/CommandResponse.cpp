#include "libwheelchair/diagnosis/CommandResponse.h"

#include "libwheelchair/diagnosis/HeldOut.h"
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
  return 1.4826 * stats::median(std::move(d)) / std::sqrt(6.0);
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

namespace {

// Per-window open-loop errors (10 s, 60 s; position m, |heading| deg) of one model.
struct DriftErrors {
  std::vector<double> e10, h10, e60, h60;
  DriftMetrics summary() const {
    DriftMetrics d;
    d.drift_10s_m = median(e10);
    d.drift_60s_m = median(e60);
    d.heading_drift_10s_deg = median(h10);
    d.heading_drift_60s_deg = median(h60);
    d.n_10s = e10.size();
    d.n_60s = e60.size();
    return d;
  }
};

// Increments of arc length and heading of the model on a uniform grid from g0.
void integrateResponse(const CommandSignal& sig, const CommandResponseParams& params,
                       const UnmodeledTerms* extra, double g0, double dt, std::size_t N,
                       std::vector<double>& ds, std::vector<double>& dphi) {
  const model::CommandDrivenModel mdl(params);
  ds.assign(N, 0.0);
  dphi.assign(N, 0.0);
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
}

DriftErrors driftErrors(const std::vector<const io::Recording*>& recs,
                        const CommandResponseParams& params, bool ignore_zero_runs,
                        const CommandResponseOptions& o, const UnmodeledTerms* extra) {
  DriftErrors out;
  const double dt = o.grid_dt_s;
  for (const io::Recording* rec : recs) {
    if (!hasCommandResponseData(*rec)) continue;
    const CommandSignal sig = commandSignal(*rec, ignore_zero_runs, o.max_zero_run_s);
    const auto& gt = rec->ground_truth;
    const double g0 = sig.startTime();
    const double g1 = std::min(sig.endTime(), gt.back().t_s);
    if (g1 <= g0) continue;
    const std::size_t N = static_cast<std::size_t>((g1 - g0) / dt);
    std::vector<double> ds, dphi;
    integrateResponse(sig, params, extra, g0, dt, N, ds, dphi);
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
        (W == 10.0 ? out.e10 : out.e60).push_back(ep);
        (W == 10.0 ? out.h10 : out.h60).push_back(eh);
      }
    }
  }
  return out;
}

std::vector<const io::Recording*> pointers(const std::vector<io::Recording>& recs) {
  std::vector<const io::Recording*> p;
  for (const auto& r : recs) p.push_back(&r);
  return p;
}

}  // namespace

DriftMetrics openLoopDrift(const std::vector<io::Recording>& recs,
                           const CommandResponseParams& params, bool ignore_zero_runs,
                           const CommandResponseOptions& o, const UnmodeledTerms* extra) {
  return driftErrors(pointers(recs), params, ignore_zero_runs, o, extra).summary();
}

namespace {

// Everything the selection steps share: the prepared fit / validation windows, the
// cross-validation folds and the measurement-noise floor of the fit windows.
struct Ctx {
  const CommandResponseOptions& o;
  std::vector<Prep> F, V;
  std::vector<io::Recording> block_recs;  // time blocks of a single fit recording
  std::vector<Prep> folds;                // CV folds: the fit recordings or the blocks
  Groups gF;
  double floorF[2] = {0, 0};
  double nF = 0;
  Evidence compare(int ch, double rss0, double rss1, int k, double ne) const {
    return compareNestedWithFloor(rss0, rss1, nF, k, ne, floorF[ch]);
  }
};

Ctx makeContext(const std::vector<io::Recording>& fit, const std::vector<io::Recording>& validate,
                const CommandResponseOptions& o) {
  Ctx c{o, {}, {}, {}, {}, {}, {0, 0}, 0};
  for (const auto& r : fit) c.F.push_back(prepare(r, o));
  for (const auto& r : validate) c.V.push_back(prepare(r, o));
  c.gF = groupsOf(c.F);
  for (const auto& p : c.F) c.nF += p.win.size();
  for (const auto& p : c.F)
    for (int ch = 0; ch < 2; ++ch)
      for (double f : p.floor[ch]) c.floorF[ch] += f;
  for (double& f : c.floorF) f /= std::max(1.0, c.nF);
  if (fit.size() >= 2) {
    c.folds = c.F;
  } else {  // one recording: 4 contiguous time blocks (fractions of the remaining span)
    std::vector<io::Recording> rest = fit;
    for (double frac : {1.0 / 4, 1.0 / 3, 1.0 / 2}) {
      auto [a, b] = splitRecordingsInTime(rest, frac);
      c.block_recs.push_back(std::move(a.front()));
      rest = std::move(b);
    }
    c.block_recs.push_back(std::move(rest.front()));
    for (const auto& r : c.block_recs)
      if (hasCommandResponseData(r)) c.folds.push_back(prepare(r, o));
  }
  return c;
}

const std::vector<Candidate>& catalogue() {
  static const std::vector<Candidate> cat = {
      {"actuator_lag", 0, -1, 2},
      {"actuator_lag", 1, -1, 2},
      {"command_gain", 0, static_cast<int>(CommandKind::Straight), 1},
      {"command_gain", 0, static_cast<int>(CommandKind::Arc), 1},
      {"command_gain", 1, static_cast<int>(CommandKind::TurnInPlace), 1},
      {"command_gain", 1, static_cast<int>(CommandKind::Arc), 1},
      {"deadband", 0, -1, 1},
      {"deadband", 1, -1, 1},
      {"ignored_zero_commands", -1, -1, 1}};
  return cat;
}

// A selected term: a catalogue candidate or one library feature (j) of a channel.
struct Term {
  bool library = false;
  Candidate cand{};
  int ch = 0, j = 0;
  CommandResponseFinding fd;  // selection evidence; validation filled later
  bool kept = true;
};

int termChannel(const Term& t) {
  return t.library ? t.ch : t.cand.ch;
}

CommandResponseFinding selectionFinding(const std::string& effect, int ch, const std::string& kind,
                                        const Evidence& ev, int k, double level) {
  CommandResponseFinding fd;
  fd.effect = effect;
  fd.channel = channelName(ch);
  fd.kind = kind;
  fd.delta_bic = ev.delta_bic;
  fd.lr = ev.lr;
  fd.p_value = ev.p_value;
  fd.n_eff = ev.n_eff;
  fd.k = k;
  fd.bonferroni_level = level;
  return fd;
}

// Likelihood-ratio evidence of a candidate that changes both channels (sum of the two).
Evidence bothChannels(const Ctx& c, const ChannelFit cur[2], const ChannelFit trial[2], int k,
                      const double neff[2]) {
  const Evidence a = c.compare(0, cur[0].rss, trial[0].rss, k, neff[0]);
  const Evidence b = c.compare(1, cur[1].rss, trial[1].rss, k, neff[1]);
  Evidence ev;
  ev.lr = a.lr + b.lr;
  ev.k = k;
  ev.n_eff = std::min(neff[0], neff[1]);
  ev.p_value = chi2Sf(std::max(0.0, ev.lr), k);
  ev.delta_bic = -ev.lr + k * std::log(std::max(1.0, ev.n_eff));
  return ev;
}

// Forward selection over the catalogue (stats::selectTerms: Bonferroni over its terms) on the
// fit windows. M and cur are the selected model and its residuals.
std::vector<Term> selectCatalogue(const Ctx& c, FullModel& M, ChannelFit cur[2]) {
  const auto& cat = catalogue();
  const stats::SelectionRule rule{c.o.alpha, static_cast<int>(cat.size()), c.o.min_delta_bic};
  std::vector<Term> terms;
  double neff[2];
  struct Trial {
    FullModel M;
    ChannelFit fit[2];
    Evidence ev;
  };
  std::vector<Trial> trials(cat.size());
  stats::SelectionHooks h;
  h.step = [&](const std::vector<int>&) {
    for (int ch = 0; ch < 2; ++ch)
      neff[ch] = effectiveSampleSize(cur[ch].resid, c.gF, c.o.hac_lags);
  };
  h.evaluate = [&](int ci, const std::vector<int>&) {
    stats::Trial t;
    const Candidate& cd = cat[ci];
    t.skip = isActive(M, cd);
    if (t.skip) return t;
    Trial& tr = trials[ci];
    tr = Trial{M, {cur[0], cur[1]}, {}};
    setActive(tr.M, cd, true);
    for (int ch = 0; ch < 2; ++ch)
      if (cd.ch < 0 || cd.ch == ch)
        tr.fit[ch] =
            optimiseChannel(c.F, ch, tr.M.ch[ch], tr.M.zero, c.o, cd.effect == "actuator_lag");
    tr.ev = cd.ch >= 0 ? c.compare(cd.ch, cur[cd.ch].rss, tr.fit[cd.ch].rss, cd.k, neff[cd.ch])
                       : bothChannels(c, cur, tr.fit, cd.k, neff);
    t.evidence = tr.ev;
    bool plausible = true;
    if (cd.effect == "command_gain") {
      const double g = tr.M.ch[cd.ch].gain[cd.kind];
      plausible = g >= c.o.min_gain && g <= c.o.max_gain;
    }
    if (cd.effect == "actuator_lag") plausible = tr.M.ch[cd.ch].delay > 0 || tr.M.ch[cd.ch].tau > 0;
    if (!plausible) t.reject = "physically implausible parameters";
    return t;
  };
  h.accepted = [&](int ci) {
    const Trial& best = trials[ci];
    M = best.M;
    cur[0] = best.fit[0];
    cur[1] = best.fit[1];
    Term t;
    t.cand = cat[ci];
    const std::string kind =
        cat[ci].kind >= 0 ? model::toString(static_cast<CommandKind>(cat[ci].kind)) : "";
    t.fd = selectionFinding(cat[ci].effect, cat[ci].ch, kind, best.ev, cat[ci].k, rule.level());
    terms.push_back(t);
  };
  stats::selectTerms(static_cast<int>(cat.size()), rule, h);
  return terms;
}

// Window means of the library features of every window of `preps`, stacked.
Eigen::MatrixXd stackedLibrary(const std::vector<Prep>& preps, bool clean) {
  std::size_t n = 0;
  for (const auto& p : preps) n += p.win.size();
  Eigen::MatrixXd L(n, 5);
  std::size_t r = 0;
  for (const auto& p : preps) {
    const Eigen::MatrixXd Lp = libraryFeatures(p, clean);
    L.middleRows(r, Lp.rows()) = Lp;
    r += Lp.rows();
  }
  return L;
}

// Forward selection of library features on what the catalogue leaves, per channel;
// Bonferroni over the library terms of both channels (5 x 2). Appends candidate Terms.
void selectLibrary(const Ctx& c, const FullModel& M, const ChannelFit cur[2],
                   std::vector<Term>& terms) {
  const stats::SelectionRule rule{c.o.alpha, 2 * 5, c.o.min_delta_bic};
  const Eigen::MatrixXd L = stackedLibrary(c.F, M.zero);
  for (int ch = 0; ch < 2; ++ch) {
    const Eigen::Index n = cur[ch].resid.size();
    Eigen::VectorXd resid = cur[ch].resid;
    double ne = 0;
    std::vector<Eigen::VectorXd> tres(5);
    std::vector<Evidence> tev(5);
    stats::SelectionHooks h;
    h.step = [&](const std::vector<int>&) { ne = effectiveSampleSize(resid, c.gF, c.o.hac_lags); };
    h.evaluate = [&](int j, const std::vector<int>& acc) {
      stats::Trial t;
      t.skip = L.col(j).squaredNorm() < 1e-12;
      if (t.skip) return t;
      std::vector<int> cols = acc;
      cols.push_back(j);
      Eigen::MatrixXd A(n, cols.size());
      for (std::size_t q = 0; q < cols.size(); ++q) A.col(q) = L.col(cols[q]);
      const Eigen::VectorXd b = A.colPivHouseholderQr().solve(cur[ch].resid);
      tres[j] = cur[ch].resid - A * b;
      tev[j] = t.evidence = c.compare(ch, resid.squaredNorm(), tres[j].squaredNorm(), 1, ne);
      return t;
    };
    h.accepted = [&](int j) {
      resid = tres[j];
      Term t;
      t.library = true;
      t.ch = ch;
      t.j = j;
      t.fd = selectionFinding("unmodeled", ch, kLibraryNames[j], tev[j], 1, rule.level());
      terms.push_back(t);
    };
    stats::selectTerms(5, rule, h);
  }
}

// The model of the kept terms: the catalogue flags of `selected` with the terms not kept (and
// `drop`, if >= 0) switched off, and the kept library terms.
struct Model {
  FullModel M;
  std::vector<std::pair<int, int>> lib;  // (channel, feature)
  UnmodeledTerms U;
};

Model modelOf(const FullModel& selected, const std::vector<Term>& terms, int drop = -1) {
  Model m{selected, {}, {}};
  for (std::size_t i = 0; i < terms.size(); ++i) {
    const bool on = terms[i].kept && static_cast<int>(i) != drop;
    if (terms[i].library) {
      if (on) m.lib.push_back({terms[i].ch, terms[i].j});
    } else if (!on) {
      setActive(m.M, terms[i].cand, false);
    }
  }
  return m;
}

// Refits the linear parts (gains of free kinds, library coefficients) on `train`; delays,
// time constants and deadbands stay as they are.
void refitLinear(const std::vector<Prep>& train, Model& m, const CommandResponseOptions& o) {
  m.U = UnmodeledTerms{};
  const Eigen::MatrixXd L = stackedLibrary(train, m.M.zero);
  for (int ch = 0; ch < 2; ++ch) {
    const ChannelFit f = fitChannel(train, ch, m.M.ch[ch], m.M.zero, o, true);
    std::vector<int> cols;
    for (const auto& [c, j] : m.lib)
      if (c == ch) cols.push_back(j);
    if (cols.empty()) continue;
    Eigen::MatrixXd A(L.rows(), cols.size());
    for (std::size_t q = 0; q < cols.size(); ++q) A.col(q) = L.col(cols[q]);
    const Eigen::VectorXd b = A.colPivHouseholderQr().solve(f.resid);
    for (std::size_t q = 0; q < cols.size(); ++q) m.U.coef[ch][cols[q]] = b(q);
  }
}

// Held-out predictions of a model on `preps`: window residuals per channel (library terms
// included) and per-window open-loop drift errors.
struct Prediction {
  Eigen::VectorXd r[2];
  DriftErrors drift;
};

Prediction predict(const std::vector<Prep>& preps, const Model& m,
                   const CommandResponseOptions& o) {
  Prediction p;
  const Eigen::MatrixXd L = stackedLibrary(preps, m.M.zero);
  for (int ch = 0; ch < 2; ++ch) {
    p.r[ch] = fixedResid(preps, ch, m.M, o);
    for (int j = 0; j < 5; ++j) p.r[ch] -= m.U.coef[ch][j] * L.col(j);
  }
  std::vector<const io::Recording*> recs;
  for (const auto& q : preps) recs.push_back(q.rec);
  p.drift = driftErrors(recs, toParams(m.M), m.M.zero, o, m.U.empty() ? nullptr : &m.U);
  return p;
}

// Pooled held-out comparison of a model with and without one term.
struct Paired {
  std::vector<double> gain;  // per window: r_without^2 - r_with^2 (the term's channels)
  double rss_without = 0, rss_with = 0;
  std::vector<double> e10_with, e10_without, h10_with, h10_without;
  DriftMetrics with, without;
  void add(const Prediction& with_p, const Prediction& without_p, int ch) {
    for (int c = 0; c < 2; ++c) {
      if (ch >= 0 && c != ch) continue;
      for (Eigen::Index i = 0; i < with_p.r[c].size(); ++i) {
        const double a = without_p.r[c](i) * without_p.r[c](i), b = with_p.r[c](i) * with_p.r[c](i);
        gain.push_back(a - b);
        rss_without += a, rss_with += b;
      }
    }
    auto app = [](std::vector<double>& d, const std::vector<double>& s) {
      d.insert(d.end(), s.begin(), s.end());
    };
    app(e10_with, with_p.drift.e10), app(e10_without, without_p.drift.e10);
    app(h10_with, with_p.drift.h10), app(h10_without, without_p.drift.h10);
  }
};

nlohmann::json pairedJson(const Paired& p, double p_boot) {
  return {{"window_rss_without", p.rss_without},
          {"window_rss_with", p.rss_with},
          {"bootstrap_prob_no_gain", p_boot},
          {"drift_10s_m_without", median(p.e10_without)},
          {"drift_10s_m_with", median(p.e10_with)},
          {"heading_drift_10s_deg_without", median(p.h10_without)},
          {"heading_drift_10s_deg_with", median(p.h10_with)},
          {"n_windows", p.gain.size()},
          {"n_drift_windows", p.e10_with.size()}};
}

// Step 1 of the held-out rule (header): cross-validation over the folds with backward
// elimination. Sets kept = false, rejected_by and heldout on the terms that fail.
void pruneByCrossValidation(const Ctx& c, const FullModel& selected, std::vector<Term>& terms) {
  if (c.folds.size() < 2) return;
  for (;;) {
    std::vector<Paired> paired(terms.size());
    for (std::size_t k = 0; k < c.folds.size(); ++k) {
      std::vector<Prep> train, test{c.folds[k]};
      for (std::size_t q = 0; q < c.folds.size(); ++q)
        if (q != k) train.push_back(c.folds[q]);
      Model full = modelOf(selected, terms);
      refitLinear(train, full, c.o);
      const Prediction pf = predict(test, full, c.o);
      for (std::size_t i = 0; i < terms.size(); ++i) {
        if (!terms[i].kept) continue;
        Model wo = modelOf(selected, terms, static_cast<int>(i));
        refitLinear(train, wo, c.o);
        paired[i].add(pf, predict(test, wo, c.o), termChannel(terms[i]));
      }
    }
    int worst = -1;
    double worst_bad = 0;
    for (std::size_t i = 0; i < terms.size(); ++i) {
      if (!terms[i].kept) continue;
      const Paired& p = paired[i];
      const double pb = blockBootstrapProbNotPositive(p.gain, c.o.hac_lags);
      terms[i].fd.heldout["cross_validation"] = pairedJson(p, pb);
      terms[i].fd.heldout["cross_validation"]["folds"] = c.folds.size();
      const double d0 = median(p.e10_without), d1 = median(p.e10_with);
      const double h0 = median(p.h10_without), h1 = median(p.h10_with);
      auto rel = [](double w, double wo) {  // no 10-s window in the folds: not judged
        return std::isfinite(w) && std::isfinite(wo) ? (w - wo) / std::max(wo, 1e-9) : -1.0;
      };
      const double worse = std::max(rel(d1, d0), rel(h1, h0));
      double bad = 0;
      if (worse > 1e-9)
        bad = 1 + worse;  // trajectory worse: first to go
      else if (pb >= c.o.cv_bootstrap_level)
        bad = pb;  // no robust gain in its quantity
      if (bad > worst_bad) worst_bad = bad, worst = static_cast<int>(i);
    }
    if (worst < 0) return;
    terms[worst].kept = false;
    terms[worst].fd.rejected_by = "cross_validation";
  }
}

// Step 2 of the held-out rule: the gate on the validation recordings (model refitted on all
// fit data). Fills the validation numbers of every kept term.
void gateOnValidation(const Ctx& c, const FullModel& selected, std::vector<Term>& terms) {
  for (;;) {
    Model full = modelOf(selected, terms);
    refitLinear(c.F, full, c.o);
    const Prediction pf = predict(c.V, full, c.o);
    const DriftMetrics dwith = pf.drift.summary();
    int worst = -1;
    double worst_bad = -1;
    for (std::size_t i = 0; i < terms.size(); ++i) {
      if (!terms[i].kept) continue;
      Model wo = modelOf(selected, terms, static_cast<int>(i));
      refitLinear(c.F, wo, c.o);
      const Prediction pw = predict(c.V, wo, c.o);
      Paired p;
      p.add(pf, pw, termChannel(terms[i]));
      CommandResponseFinding& fd = terms[i].fd;
      fd.validation_rss_with = p.rss_with;
      fd.validation_rss_without = p.rss_without;
      const double nv = std::max<double>(1, p.gain.size());
      fd.validation_rms_with = std::sqrt(p.rss_with / nv);
      fd.validation_rms_without = std::sqrt(p.rss_without / nv);
      fd.drift_with = dwith;
      fd.drift_without = pw.drift.summary();
      fd.heldout["validation"] = pairedJson(p, blockBootstrapProbNotPositive(p.gain, c.o.hac_lags));
      const DriftMetrics &a = fd.drift_with, &b = fd.drift_without;
      // relative worsening; a drift with no window (NaN: recordings shorter than 60 s) is not
      // judged
      auto rel = [](double w, double wo) {
        return std::isfinite(w) && std::isfinite(wo) ? (w - wo) / std::max(std::abs(wo), 1e-9)
                                                     : -1.0;
      };
      const double worse =
          std::max({rel(a.drift_10s_m, b.drift_10s_m), rel(a.drift_60s_m, b.drift_60s_m),
                    rel(a.heading_drift_10s_deg, b.heading_drift_10s_deg),
                    rel(a.heading_drift_60s_deg, b.heading_drift_60s_deg),
                    p.rss_with >= p.rss_without ? 1.0 : -1.0});
      if (worse > 1e-9 && worse > worst_bad) worst_bad = worse, worst = static_cast<int>(i);
    }
    if (worst < 0) return;
    terms[worst].kept = false;
    terms[worst].fd.rejected_by = "validation";
  }
}

// Parameters, uncertainty (curvature of the fit RSS; library: HAC) and segments of the kept
// terms of the final model (refitted on all fit data); a rejected term's parameters are those
// of the model with every proposed term (`selected`, refitted on all fit data), so that the
// JSON says what was rejected.
void describeTerms(const Ctx& c, const Model& fin, const FullModel& selected,
                   std::vector<Term>& terms) {
  std::vector<Term> all = terms;
  for (auto& t : all) t.kept = true;
  Model proposed = modelOf(selected, all);
  refitLinear(c.F, proposed, c.o);
  ChannelFit cur[2];
  for (int ch = 0; ch < 2; ++ch) {
    ChannelModel m = fin.M.ch[ch];
    cur[ch] = fitChannel(c.F, ch, m, fin.M.zero, c.o, false);
  }
  const Eigen::MatrixXd L = stackedLibrary(c.F, fin.M.zero);
  for (std::size_t i = 0; i < terms.size(); ++i) {
    Term& t = terms[i];
    CommandResponseFinding& fd = t.fd;
    const FullModel& M = t.kept ? fin.M : proposed.M;
    if (t.library) {
      fd.parameters["coefficient"] = (t.kept ? fin.U : proposed.U).coef[t.ch][t.j];
      if (!t.kept) continue;
      std::vector<int> cols;
      for (const auto& [ch, j] : fin.lib)
        if (ch == t.ch) cols.push_back(j);
      Eigen::MatrixXd A(L.rows(), cols.size());
      for (std::size_t q = 0; q < cols.size(); ++q) A.col(q) = L.col(cols[q]);
      const LinearFit lf = fitLinear(A, cur[t.ch].resid, c.gF, c.o.hac_lags);
      const auto pos = std::find(cols.begin(), cols.end(), t.j) - cols.begin();
      fd.uncertainty["coefficient"] =
          lf.ok ? std::sqrt(std::max(0.0, lf.cov(pos, pos))) : std::nan("");
      const Eigen::VectorXd contrib = fin.U.coef[t.ch][t.j] * L.col(t.j);
      fd.segments =
          contributionSegments(c.F, contrib, std::sqrt(cur[t.ch].rss / c.nF + c.floorF[t.ch]));
      continue;
    }
    const Candidate& cd = t.cand;
    if (cd.effect == "actuator_lag") {
      fd.parameters["delay_s"] = M.ch[cd.ch].delay;
      fd.parameters["time_constant_s"] = M.ch[cd.ch].tau;
    } else if (cd.effect == "command_gain") {
      fd.parameters["scale"] = M.ch[cd.ch].gain[cd.kind];
    } else if (cd.effect == "deadband") {
      fd.parameters[cd.ch == 0 ? "threshold_m_s" : "threshold_rad_s"] = M.ch[cd.ch].db;
    } else {
      fd.parameters["max_run_s"] = c.o.max_zero_run_s;
    }
    if (!t.kept) continue;
    FullModel Wo = M;
    setActive(Wo, cd, false);
    for (int ch = 0; ch < 2; ++ch) {
      if (cd.ch >= 0 && cd.ch != ch) continue;
      const Eigen::VectorXd contrib = fixedResid(c.F, ch, Wo, c.o) - cur[ch].resid;
      const auto seg =
          contributionSegments(c.F, contrib, std::sqrt(cur[ch].rss / c.nF + c.floorF[ch]));
      fd.segments.insert(fd.segments.end(), seg.begin(), seg.end());
    }
    std::sort(fd.segments.begin(), fd.segments.end());
    if (cd.effect == "actuator_lag") {
      const Eigen::MatrixXd C = rssCovariance(c.F, cd.ch, M, c.o,
                                              {[](ChannelModel& m) -> double& { return m.delay; },
                                               [](ChannelModel& m) -> double& { return m.tau; }},
                                              {0.005, 0.005}, c.floorF[cd.ch], fd.n_eff);
      fd.uncertainty["delay_s"] = std::sqrt(std::max(0.0, C(0, 0)));
      fd.uncertainty["time_constant_s"] = std::sqrt(std::max(0.0, C(1, 1)));
    } else if (cd.effect == "command_gain") {
      const int kind = cd.kind;
      const Eigen::MatrixXd C = rssCovariance(
          c.F, cd.ch, M, c.o, {[kind](ChannelModel& m) -> double& { return m.gain[kind]; }}, {0.01},
          c.floorF[cd.ch], fd.n_eff);
      fd.uncertainty["scale"] = std::sqrt(std::max(0.0, C(0, 0)));
    }
  }
}

// Held-out residual RMS per channel and drift summaries of the result.
void summarise(const Ctx& c, const std::vector<io::Recording>& fit,
               const std::vector<io::Recording>& validate, const Model& fin,
               CommandResponseResult& res) {
  const Model nominal{};
  const Prediction pn = predict(c.V, nominal, c.o);
  Model catalogue_only = fin;
  catalogue_only.U = UnmodeledTerms{};
  const Prediction pc = predict(c.V, catalogue_only, c.o);
  const Prediction pa = predict(c.V, fin, c.o);
  for (int ch = 0; ch < 2; ++ch) {
    auto& st = ch == 0 ? res.validation_v : res.validation_omega;
    const double n = std::max<double>(1, pa.r[ch].size());
    st.rms_before = std::sqrt(pn.r[ch].squaredNorm() / n);
    st.rms_after = std::sqrt(pa.r[ch].squaredNorm() / n);
    st.n = pa.r[ch].size();
  }
  res.fit_before = pn.drift.summary();
  res.fit_after = pc.drift.summary();
  res.fit_after_unmodeled = pa.drift.summary();
  const CommandResponseParams nominal_params;
  res.fit_before_on_fit = openLoopDrift(fit, nominal_params, false, c.o);
  res.fit_after_on_fit = openLoopDrift(fit, res.params, res.ignore_zero_runs, c.o);
  (void)validate;
}

}  // namespace

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
  const Ctx c = makeContext(fit, validate, o);
  CommandResponseResult res;
  res.max_zero_run_s = o.max_zero_run_s;
  res.fit_windows = static_cast<std::size_t>(c.nF);
  for (const auto& p : c.V) res.validation_windows += p.win.size();
  if (res.fit_windows < 20) throw std::invalid_argument("diagnoseCommandResponse: too little data");
  res.noise_floor_v_m_s = std::sqrt(c.floorF[0]);
  res.noise_floor_omega_rad_s = std::sqrt(c.floorF[1]);

  FullModel M;
  ChannelFit cur[2];
  for (int ch = 0; ch < 2; ++ch) cur[ch] = fitChannel(c.F, ch, M.ch[ch], M.zero, o);
  std::vector<Term> terms = selectCatalogue(c, M, cur);
  selectLibrary(c, M, cur, terms);
  pruneByCrossValidation(c, M, terms);
  gateOnValidation(c, M, terms);

  Model fin = modelOf(M, terms);
  refitLinear(c.F, fin, o);
  describeTerms(c, fin, M, terms);
  for (auto& t : terms) {
    t.fd.validated = t.kept;
    res.findings.push_back(t.fd);
  }
  res.params = toParams(fin.M);
  res.ignore_zero_runs = fin.M.zero;
  res.unmodeled = fin.U;
  summarise(c, fit, validate, fin, res);
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

namespace {

nlohmann::json rejectedJson(const CommandResponseFinding& f) {
  nlohmann::json j = {{"effect", f.effect},
                      {"channel", f.channel},
                      {f.effect == "unmodeled" ? "term" : "kind", f.kind},
                      {"parameters", f.parameters},
                      {"rejected_by", f.rejected_by},
                      {"heldout", f.heldout}};
  j["reason"] = f.rejected_by == "cross_validation"
                    ? "across the fit recordings (or time blocks) it does not predict the left-out "
                      "data better: no robust window-residual gain (block bootstrap) or a worse "
                      "10-s open-loop drift"
                    : "on the validation recordings its channel's residual or an open-loop drift "
                      "gets worse";
  return j;
}

std::string catalogueDescription(const CommandResponseFinding& f) {
  const std::string what = channelWords(f.channel);
  auto pm = [&](const char* k) {
    auto it = f.uncertainty.find(k);
    return it == f.uncertainty.end() ? std::string() : fmt::format(" (+- {:.3f})", it->second);
  };
  if (f.effect == "actuator_lag")
    return fmt::format(
        "the robot's {} follows the command {:.2f} s late{} with a {:.2f} s time constant{}: "
        "the drive responds with a pure delay and a first-order lag, not instantly",
        what, f.parameters.at("delay_s"), pm("delay_s"), f.parameters.at("time_constant_s"),
        pm("time_constant_s"));
  if (f.effect == "command_gain") {
    const double g = f.parameters.at("scale");
    const std::string kind = f.kind == "turn_in_place" ? "turning in place"
                             : f.kind == "arc"         ? "in arcs"
                                                       : "driving " + f.kind;
    return fmt::format(
        "{}, the robot's {} is {:.2f} x the commanded value{} ({:.0f}% {}): the response "
        "depends on the kind of command",
        kind, what, g, pm("scale"), std::abs(g - 1) * 100, g < 1 ? "less" : "more");
  }
  if (f.effect == "deadband")
    return fmt::format("commanded {} of magnitude <= {:.3g} {} do not move the robot: a deadband",
                       what, f.parameters.begin()->second, f.channel == "v" ? "m/s" : "rad/s");
  return fmt::format(
      "the robot ignores (0,0) command lines lasting less than {:.2f} s between moving "
      "commands (logging blips)",
      f.parameters.at("max_run_s"));
}

Finding catalogueFinding(const CommandResponseFinding& f) {
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
  x.description = catalogueDescription(f);
  x.evidence = {{"likelihood_ratio", f.lr},
                {"p_value", f.p_value},
                {"bonferroni_level", f.bonferroni_level},
                {"delta_bic", f.delta_bic},
                {"n_eff", f.n_eff},
                {"added_parameters", f.k},
                {"validation_rss_without", f.validation_rss_without},
                {"validation_rss_with", f.validation_rss_with},
                {"validated", f.validated},
                {"heldout", f.heldout}};
  const char* unit = f.channel == "v"       ? "validation_rms_m_s"
                     : f.channel == "omega" ? "validation_rms_rad_s"
                                            : "validation_rms";
  x.fit_before = driftFit(f.drift_without, f.channel, f.validation_rms_without, unit);
  x.fit_after = driftFit(f.drift_with, f.channel, f.validation_rms_with, unit);
  return x;
}

// Words for a library term (what it depends on, read as physics).
const char* termReading(const std::string& term, const std::string& ch) {
  if (term == "v_cmd*|omega_cmd|")
    return ch == "v" ? "the forward speed drops in proportion to the turn rate (in arcs the "
                       "inner wheel slows or stops: the robot pivots)"
                     : "the turn rate depends on speed times turn rate";
  if (term == "1") return "a constant offset (a bias of the drive or of the motion capture)";
  if (term == "v_cmd") return "a gain on the commanded speed";
  if (term == "omega_cmd") return "a gain on the commanded turn rate";
  return "a term even in the turn rate (left and right turns alike)";
}

// One `unmodeled` finding per channel from its kept library terms (each passed the held-out
// rule on its own).
Finding unmodeledFinding(const std::string& ch,
                         const std::vector<const CommandResponseFinding*>& terms) {
  Finding x;
  x.command_response = true;
  x.effect = "unmodeled";
  x.channels = {ch};
  std::string eq = ch + " - model =", words;
  nlohmann::json per = nlohmann::json::array();
  for (auto* t : terms) {
    const double c = t->parameters.at("coefficient");
    x.parameters[t->kind] = c;
    if (t->uncertainty.count("coefficient"))
      x.uncertainty[t->kind] = t->uncertainty.at("coefficient");
    eq += fmt::format(" {:+.4g}*{}", c, t->kind);
    words += fmt::format("{}{}", words.empty() ? "" : "; ", termReading(t->kind, ch));
    per.push_back({{"term", t->kind},
                   {"likelihood_ratio", t->lr},
                   {"p_value", t->p_value},
                   {"delta_bic", t->delta_bic},
                   {"n_eff", t->n_eff},
                   {"heldout", t->heldout}});
    x.segments.insert(x.segments.end(), t->segments.begin(), t->segments.end());
  }
  std::sort(x.segments.begin(), x.segments.end());
  x.parameters["channel"] = ch;
  x.description = fmt::format(
      "a term outside the catalogue acts on the robot's {}: {} ({}; commands in m/s, rad/s): {}",
      channelWords(ch), eq, ch == "v" ? "m/s" : "rad/s", words);
  // The group's held-out numbers: the model with all kept terms vs without this channel's
  // library terms; the per-term gate numbers are in evidence.terms[].heldout.
  const CommandResponseFinding& f = *terms.front();
  x.evidence = {{"terms", per}, {"added_parameters", terms.size()}, {"validated", true}};
  const char* unit = ch == "v" ? "validation_rms_m_s" : "validation_rms_rad_s";
  x.fit_before = driftFit(f.drift_without, ch, f.validation_rms_without, unit);
  x.fit_after = driftFit(f.drift_with, ch, f.validation_rms_with, unit);
  for (auto* t : terms) {  // the least favourable of the terms (each one removed alone)
    const nlohmann::json wo = driftJson(t->drift_without);
    for (const char* k :
         {"drift_10s_m", "drift_60s_m", "heading_drift_10s_deg", "heading_drift_60s_deg"})
      x.fit_before[k] = std::min(x.fit_before[k].get<double>(), wo[k].get<double>());
    x.fit_before[unit] = std::min(x.fit_before[unit].get<double>(), t->validation_rms_without);
  }
  return x;
}

void setChannelsAndDrift(const CommandResponseResult& r, DiagnosisReport& rep) {
  rep.fit_before = driftJson(r.fit_before);
  // The corrected model: the kept catalogue terms plus the kept unmodeled terms
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
}

}  // namespace

void addCommandResponseFindings(const CommandResponseResult& r, DiagnosisReport& rep) {
  nlohmann::json rejected = nlohmann::json::array();
  std::map<std::string, std::vector<const CommandResponseFinding*>> lib;
  for (const auto& f : r.findings) {
    if (!f.validated)
      rejected.push_back(rejectedJson(f));
    else if (f.effect == "unmodeled")
      lib[f.channel].push_back(&f);
    else
      rep.addFinding(catalogueFinding(f));
  }
  for (const std::string ch : {"v", "omega"})
    if (lib.count(ch)) rep.addFinding(unmodeledFinding(ch, lib[ch]));
  setChannelsAndDrift(r, rep);
  if (!rejected.empty()) rep.info["command_response_rejected"] = rejected;
  // The nominal model is visibly wrong when a rejected term still lowered the left-out window
  // residual robustly in cross-validation: a mismatch, but no correction that predicts the
  // held-out trajectory better (nothing is reported as a finding).
  for (const auto& f : r.findings) {
    const auto& cv = f.heldout.value("cross_validation", nlohmann::json::object());
    if (!f.validated && cv.value("bootstrap_prob_no_gain", 1.0) < 0.05 && !rep.mismatch) {
      rep.mismatch = true;
      rep.info["command_response_mismatch"] =
          "the commands do not explain the motion (terms lower the left-out window residual) "
          "but no term improved the held-out open-loop drift: see command_response_rejected";
    }
  }
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
