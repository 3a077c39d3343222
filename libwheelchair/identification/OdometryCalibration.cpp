#include "libwheelchair/identification/OdometryCalibration.h"

#include "libwheelchair/model/Kinematics.h"
#include "libwheelchair/sensors/Encoders.h"
#include "libwheelchair/sensors/Filtering.h"
#include "libwheelchair/stats/LevenbergMarquardt.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace wheelchair::identification {

namespace {

/// Errors of dead reckoning against the truth, per sample after the first: x, y (m) and
/// heading x heading_weight_m (m).
Eigen::VectorXd poseResiduals(const std::vector<OdometryRun>& runs, const OdometryGeometry& g,
                              double heading_weight_m) {
  std::size_t n = 0;
  for (const auto& r : runs) n += r.size() > 1 ? r.size() - 1 : 0;
  Eigen::VectorXd e(3 * n);
  std::size_t k = 0;
  for (const auto& r : runs) {
    if (r.size() < 2) continue;
    const auto p = deadReckon(r, g);
    for (std::size_t i = 1; i < r.size(); ++i) {
      e(k++) = p[i].x_m - r.x_m[i];
      e(k++) = p[i].y_m - r.y_m[i];
      e(k++) = heading_weight_m * (p[i].phi_rad - r.phi_rad[i]);
    }
  }
  return e;
}

using Vec6 = Eigen::Matrix<double, 6, 1>;

OdometryGeometry applyDelta(const OdometryGeometry& g0, const Vec6& d) {
  return {g0.m_per_tick_right * (1 + d(0)),
          g0.m_per_tick_left * (1 + d(1)),
          g0.track_m * (1 + d(2)),
          g0.lever_x_m + d(3),
          g0.lever_y_m + d(4),
          g0.travel_angle_rad + d(5)};
}

}  // namespace

OdometryGeometry odometryGeometry(const config::WheelchairConfig& cfg) {
  const auto& g = cfg.vehicle.geom;
  const double rpt = cfg.encoders.params.wheelRadPerTick();
  OdometryGeometry o{g.odometryRadius(0) * rpt, g.odometryRadius(1) * rpt, g.track_width_m};
  o.travel_angle_rad = g.odometry_travel_angle_rad;
  return o;
}

void applyOdometryGeometry(const OdometryGeometry& o, config::WheelchairConfig& cfg) {
  const double rpt = cfg.encoders.params.wheelRadPerTick();
  auto& g = cfg.vehicle.geom;
  g.wheel_radius_right_m = o.m_per_tick_right / rpt;
  g.wheel_radius_left_m = o.m_per_tick_left / rpt;
  g.wheel_radius_m = 0.5 * (g.wheel_radius_right_m + g.wheel_radius_left_m);
  g.track_width_m = o.track_m;
  g.odometry_travel_angle_rad = o.travel_angle_rad;
  cfg.syncToIni();
}

OdometryRun odometryRun(const io::Recording& rec, const std::string& name) {
  OdometryRun run;
  run.name = name;
  std::vector<io::GroundTruthPoseSample> gt = rec.ground_truth;
  std::stable_sort(gt.begin(), gt.end(), [](auto& a, auto& b) { return a.t_s < b.t_s; });
  std::vector<double> tg, xg, yg, pg;
  for (const auto& p : gt) {
    if (!tg.empty() && !(p.t_s > tg.back())) continue;
    // Heading unwrapped: each sample within pi of the previous one.
    const double phi = pg.empty() ? p.phi_rad : pg.back() + model::wrapAngle(p.phi_rad - pg.back());
    tg.push_back(p.t_s), xg.push_back(p.x_m), yg.push_back(p.y_m), pg.push_back(phi);
  }
  if (tg.size() < 2 || rec.encoders.size() < 2) return run;
  const auto un = sensors::unwrapTicks(rec.encoders);
  for (std::size_t i = 0; i < un.t_s.size(); ++i) {
    const double t = un.t_s[i];
    if (t < tg.front() || t > tg.back()) continue;
    if (!run.t_s.empty() && !(t > run.t_s.back())) continue;
    run.t_s.push_back(t);
    run.ticks_right.push_back(static_cast<double>(un.right[i]));
    run.ticks_left.push_back(static_cast<double>(un.left[i]));
  }
  run.x_m = sensors::resampleLinear(tg, xg, run.t_s);
  run.y_m = sensors::resampleLinear(tg, yg, run.t_s);
  run.phi_rad = sensors::resampleLinear(tg, pg, run.t_s);
  return run;
}

OdometryRun cropRun(const OdometryRun& r, double t0, double t1) {
  OdometryRun o;
  o.name = r.name;
  for (std::size_t i = 0; i < r.size(); ++i) {
    if (r.t_s[i] < t0 || r.t_s[i] > t1) continue;
    o.t_s.push_back(r.t_s[i]);
    o.ticks_right.push_back(r.ticks_right[i]);
    o.ticks_left.push_back(r.ticks_left[i]);
    o.x_m.push_back(r.x_m[i]);
    o.y_m.push_back(r.y_m[i]);
    o.phi_rad.push_back(r.phi_rad[i]);
  }
  return o;
}

std::vector<Pose2> deadReckon(const OdometryRun& r, const OdometryGeometry& g) {
  std::vector<Pose2> p;
  if (r.size() == 0) return p;
  p.reserve(r.size());
  const double ax = g.lever_x_m, ay = g.lever_y_m;
  auto tracked = [&](const Pose2& axle) {  // the ground-truth point of an axle pose
    const double c = std::cos(axle.phi_rad), s = std::sin(axle.phi_rad);
    return Pose2{axle.x_m + c * ax - s * ay, axle.y_m + s * ax + c * ay, axle.phi_rad};
  };
  const double c0 = std::cos(r.phi_rad[0]), s0 = std::sin(r.phi_rad[0]);
  Pose2 q{r.x_m[0] - (c0 * ax - s0 * ay), r.y_m[0] - (s0 * ax + c0 * ay), r.phi_rad[0]};
  p.push_back(tracked(q));
  for (std::size_t i = 1; i < r.size(); ++i) {
    const double dR = g.m_per_tick_right * (r.ticks_right[i] - r.ticks_right[i - 1]);
    const double dL = g.m_per_tick_left * (r.ticks_left[i] - r.ticks_left[i - 1]);
    const double ds = 0.5 * (dR + dL), dphi = (dR - dL) / g.track_m;
    // The arc of one interval (model::integratePoseArc with dt = 1: ds and dphi per interval);
    // the heading is kept continuous (the ground truth's is unwrapped).
    // the chord is laid along heading + travel angle (0: along the heading)
    const Eigen::Vector3d next = model::integratePoseArc(
        Eigen::Vector3d(q.x_m, q.y_m, q.phi_rad + g.travel_angle_rad), ds, dphi, 1.0);
    q = Pose2{next(0), next(1), q.phi_rad + dphi};
    p.push_back(tracked(q));
  }
  return p;
}

OdometryError odometryError(const OdometryRun& r, const OdometryGeometry& g) {
  OdometryError e;
  if (r.size() < 2) return e;
  const auto p = deadReckon(r, g);
  double sum = 0;
  for (std::size_t i = 1; i < r.size(); ++i)
    sum += std::hypot(p[i].x_m - r.x_m[i], p[i].y_m - r.y_m[i]);
  const std::size_t n = r.size() - 1;
  e.mean_position_m = sum / n;
  e.end_position_m = std::hypot(p[n].x_m - r.x_m[n], p[n].y_m - r.y_m[n]);
  e.end_heading_rad = std::abs(p[n].phi_rad - r.phi_rad[n]);
  e.runs = 1;
  return e;
}

OdometryError meanOdometryError(const std::vector<OdometryRun>& runs, const OdometryGeometry& g) {
  OdometryError m;
  for (const auto& r : runs) {
    if (r.size() < 2) continue;
    const OdometryError e = odometryError(r, g);
    m.end_position_m += e.end_position_m;
    m.mean_position_m += e.mean_position_m;
    m.end_heading_rad += e.end_heading_rad;
    ++m.runs;
  }
  if (m.runs) {
    m.end_position_m /= m.runs, m.mean_position_m /= m.runs, m.end_heading_rad /= m.runs;
  }
  return m;
}

UmbmarkResult umbmark(const std::vector<OdometryRun>& squares, double L,
                      const OdometryGeometry& nominal) {
  if (!(L > 0)) throw std::invalid_argument("umbmark: the square side must be > 0");
  UmbmarkResult u;
  for (const auto& r : squares) {
    if (r.size() < 2) continue;
    const auto p = deadReckon(r, nominal);
    const std::size_t n = r.size() - 1;
    // return error eps = truth - odometry, in the start frame (x along the initial heading)
    const double c = std::cos(r.phi_rad[0]), s = std::sin(r.phi_rad[0]);
    const double ex = r.x_m[n] - p[n].x_m, ey = r.y_m[n] - p[n].y_m;
    const double x = c * ex + s * ey, y = -s * ex + c * ey;
    if (r.phi_rad[n] - r.phi_rad[0] < 0)
      u.x_cw_m += x, u.y_cw_m += y, ++u.n_cw;
    else
      u.x_ccw_m += x, u.y_ccw_m += y, ++u.n_ccw;
  }
  if (u.n_cw == 0 || u.n_ccw == 0)
    throw std::invalid_argument("umbmark: needs square runs in both directions (cw and ccw)");
  u.x_cw_m /= u.n_cw, u.y_cw_m /= u.n_cw, u.x_ccw_m /= u.n_ccw, u.y_ccw_m /= u.n_ccw;
  const double b = nominal.track_m;
  u.alpha_rad = (u.x_cw_m + u.x_ccw_m) / (-4 * L);
  u.beta_rad = (u.x_cw_m - u.x_ccw_m) / (-4 * L);
  u.E_d = 1;
  if (std::abs(u.beta_rad) > 1e-12) {
    const double R = (L / 2) / std::sin(u.beta_rad / 2);
    u.E_d = (R + b / 2) / (R - b / 2);
  }
  u.E_b = (M_PI / 2) / (M_PI / 2 - u.alpha_rad);
  const double k_mean = 0.5 * (nominal.m_per_tick_right + nominal.m_per_tick_left);
  u.corrected.m_per_tick_right = 2 * u.E_d / (u.E_d + 1) * k_mean;
  u.corrected.m_per_tick_left = 2 / (u.E_d + 1) * k_mean;
  u.corrected.track_m = u.E_b * b;
  return u;
}

OdometryGeometry leastSquaresCalibration(const std::vector<OdometryRun>& runs, double segment_s) {
  if (!(segment_s > 0)) throw std::invalid_argument("leastSquaresCalibration: segment_s <= 0");
  std::vector<std::array<double, 3>> head;  // dN_R, dN_L, dphi
  std::vector<std::array<double, 6>> disp;  // ax_R, ax_L, dx, ay_R, ay_L, dy
  for (const auto& r : runs) {
    std::size_t a = 0;
    while (a + 1 < r.size()) {
      std::size_t b = a;
      while (b + 1 < r.size() && r.t_s[b + 1] - r.t_s[a] <= segment_s + 1e-9) ++b;
      if (b == a) ++b;
      head.push_back({r.ticks_right[b] - r.ticks_right[a], r.ticks_left[b] - r.ticks_left[a],
                      r.phi_rad[b] - r.phi_rad[a]});
      std::array<double, 6> d{0, 0, r.x_m[b] - r.x_m[a], 0, 0, r.y_m[b] - r.y_m[a]};
      for (std::size_t i = a + 1; i <= b; ++i) {
        const double phi = 0.5 * (r.phi_rad[i] + r.phi_rad[i - 1]);
        const double nR = r.ticks_right[i] - r.ticks_right[i - 1];
        const double nL = r.ticks_left[i] - r.ticks_left[i - 1];
        d[0] += 0.5 * nR * std::cos(phi), d[1] += 0.5 * nL * std::cos(phi);
        d[3] += 0.5 * nR * std::sin(phi), d[4] += 0.5 * nL * std::sin(phi);
      }
      disp.push_back(d);
      a = b;
    }
  }
  if (head.size() < 3) throw std::invalid_argument("leastSquaresCalibration: too little data");
  Eigen::MatrixXd A(head.size(), 2);
  Eigen::VectorXd y(head.size());
  for (std::size_t i = 0; i < head.size(); ++i)
    A(i, 0) = head[i][0], A(i, 1) = -head[i][1], y(i) = head[i][2];
  const Eigen::Vector2d c = A.colPivHouseholderQr().solve(y);
  // step 2: with the heading ratios fixed, k = b c, the displacement is linear in b alone
  double num = 0, den = 0;
  for (const auto& d : disp) {
    const double ax = c(0) * d[0] + c(1) * d[1], ay = c(0) * d[3] + c(1) * d[4];
    num += ax * d[2] + ay * d[5], den += ax * ax + ay * ay;
  }
  const double b = num / den;
  OdometryGeometry g{b * c(0), b * c(1), b};
  if (!(g.m_per_tick_right > 0) || !(g.m_per_tick_left > 0) || !(g.track_m > 0))
    throw std::runtime_error("leastSquaresCalibration: non-positive solution (no motion?)");
  return g;
}

OdometryRun shiftTruth(const OdometryRun& r, double d) {
  OdometryRun o = r;
  if (r.size() < 2) return o;
  std::vector<double> t_shifted(r.t_s);
  for (double& t : t_shifted) t -= d;
  o.x_m = sensors::resampleLinear(r.t_s, r.x_m, t_shifted);
  o.y_m = sensors::resampleLinear(r.t_s, r.y_m, t_shifted);
  o.phi_rad = sensors::resampleLinear(r.t_s, r.phi_rad, t_shifted);
  return o;
}

double estimateTimeOffset(const OdometryRun& r, const OdometryGeometry& g, double max_s,
                          double step_s) {
  if (r.size() < 10 || !(step_s > 0)) return 0;
  // cumulative odometric heading; it is the one re-sampled (ticks carry no measurement noise),
  // the truth's increments stay as measured: re-sampling the noisy truth between its samples
  // would average its noise and favour half-sample shifts whatever the true lag.
  std::vector<double> th(r.size(), 0.0), y(r.size() - 1);
  for (std::size_t i = 1; i < r.size(); ++i) {
    th[i] = th[i - 1] + (g.m_per_tick_right * (r.ticks_right[i] - r.ticks_right[i - 1]) -
                         g.m_per_tick_left * (r.ticks_left[i] - r.ticks_left[i - 1])) /
                            g.track_m;
    y[i - 1] = r.phi_rad[i] - r.phi_rad[i - 1];
  }
  double best = 0, best_cost = 1e300;
  std::vector<double> t_shifted(r.size());
  for (double d = -max_s; d <= max_s + 1e-12; d += step_s) {
    // the encoders trail by d: the truth at t pairs with the odometry at t + d
    for (std::size_t i = 0; i < r.size(); ++i) t_shifted[i] = r.t_s[i] + d;
    const std::vector<double> w = sensors::resampleLinear(r.t_s, th, t_shifted);
    double sww = 0, swy = 0, syy = 0;
    for (std::size_t i = 1; i < r.size(); ++i) {
      const double wi = w[i] - w[i - 1];
      sww += wi * wi, swy += wi * y[i - 1], syy += y[i - 1] * y[i - 1];
    }
    const double cost = sww > 0 ? syy - swy * swy / sww : syy;
    if (cost < best_cost) best_cost = cost, best = d;
  }
  return best;
}

OdometryGeometry trajectoryCalibration(const std::vector<OdometryRun>& runs,
                                       const OdometryGeometry& g0, const TrajectoryFit& fit,
                                       double* rms_m) {
  // free directions of the relative correction delta (k_R, k_L, b)
  std::vector<Vec6> dirs;
  auto unitv = [](std::initializer_list<int> idx) {
    Vec6 v = Vec6::Zero();
    for (int i : idx) v(i) = 1;
    return v;
  };
  if (fit.common_scale && (fit.free[0] || fit.free[1])) dirs.push_back(unitv({0, 1}));
  if (!fit.common_scale) {
    if (fit.free[0]) dirs.push_back(unitv({0}));
    if (fit.free[1]) dirs.push_back(unitv({1}));
  }
  if (fit.free[2]) dirs.push_back(unitv({2}));
  if (fit.uniform_scale) dirs.push_back(unitv({0, 1, 2}));
  if (fit.lever_arm) dirs.push_back(unitv({3})), dirs.push_back(unitv({4}));
  if (fit.travel_angle) dirs.push_back(unitv({5}));
  const int p = static_cast<int>(dirs.size());
  auto deltaOf = [&](const Eigen::VectorXd& x) {  // delta = sum_j x_j dirs_j
    Vec6 d = Vec6::Zero();
    for (int j = 0; j < p; ++j) d += x(j) * dirs[j];
    return d;
  };
  auto residuals = [&](const Eigen::VectorXd& x, Eigen::VectorXd& e, Eigen::MatrixXd*) {
    e = poseResiduals(runs, applyDelta(g0, deltaOf(x)), fit.heading_weight_m);
  };
  // Stay physical: at most halve a parameter; a lever arm within the robot.
  auto physical = [&](const Eigen::VectorXd& x) {
    const Vec6 d = deltaOf(x);
    return !(d.head<3>().array() <= -0.5).any() && d.segment<2>(3).norm() <= 0.5 * g0.track_m &&
           std::abs(d(5)) < 0.5;
  };
  Eigen::VectorXd x = Eigen::VectorXd::Zero(p), e;
  residuals(x, e, nullptr);
  if (p > 0 && e.size() > p) {
    stats::LmOptions lm;
    lm.max_iterations = fit.max_iterations;
    lm.min_relative_decrease = 1e-10;
    const stats::LmResult sol = stats::levenbergMarquardt(residuals, x, lm, physical);
    x = sol.x, e = sol.r;
  }
  if (rms_m) *rms_m = e.size() ? std::sqrt(e.squaredNorm() / (e.size() / 3)) : 0.0;
  return applyDelta(g0, deltaOf(x));
}

}  // namespace wheelchair::identification
