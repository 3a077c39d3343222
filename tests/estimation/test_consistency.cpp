// Monte-Carlo consistency of the physics CD-EKF on data generated from its own model:
// average NEES (7 canonical states) and NIS (per sensor) inside their 95 % chi-square bands.
#include "SyntheticDrive.h"

#include "libwheelchair/estimation/Estimator.h"
#include "libwheelchair/stats/Distributions.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Dense>

#include <chrono>
#include <cstdio>
#include <string>

using namespace wheelchair;
using namespace wheelchair::estimation;
using namespace wheelchair::estimation::test;

namespace {

struct McConfig {
  int runs = 20;
  double duration_s = 12.0;
  ObstacleFormOption form = ObstacleFormOption::Cartesian;
};

EkfOptions consistencyOptions(ObstacleFormOption form) {
  EkfOptions o;
  o.obstacle_form = form;
  o.q_v_m2_s3 = 0.01;
  o.q_omega_rad2_s3 = 0.02;
  o.q_xy_m2_s = 1e-9;
  o.q_phi_rad2_s = 1e-9;
  o.q_obstacle_m2_s = 1e-9;
  o.q_obstacle_bearing_rad2_s = 1e-9;
  o.encoder_extra_noise_m_s = 0.005;
  setPriorsOfTheTruth(o, {1.5, 2.5});
  return o;
}

std::string fmtv(const Eigen::Matrix<double, 7, 1>& v) {
  std::string s;
  char b[32];
  for (int i = 0; i < 7; ++i) {
    std::snprintf(b, sizeof b, " %.4g", v(i));
    s += b;
  }
  return s;
}

struct McResult {
  Eigen::Matrix<double, 7, 1> per_component;  ///< mean err_i^2 / P_ii (1 if consistent)
  double mean_nees = 0;
  double frac_times_inside = 0;
  std::pair<double, double> band;
  std::array<double, kNumSensors> mean_nis{};
  std::array<std::pair<double, double>, kNumSensors> nis_band{};
  std::array<double, kNumSensors> nis_inside95{};
};

McResult monteCarlo(const McConfig& mc) {
  const config::WheelchairConfig cfg;
  EkfOptions opt = consistencyOptions(mc.form);
  opt.resolveSensorDefaults(cfg);
  std::mt19937_64 prior_rng(12345);
  std::normal_distribution<double> N01(0.0, 1.0);
  // NEES per output index summed over runs (outputs are on the same grid in every run).
  std::vector<double> nees_sum;
  std::vector<int> nees_n;
  std::array<double, kNumSensors> nis_sum{};
  std::array<long, kNumSensors> nis_n{}, nis_in{};
  Eigen::Matrix<double, 7, 1> comp = Eigen::Matrix<double, 7, 1>::Zero();
  long ncomp = 0;
  for (int run = 0; run < mc.runs; ++run) {
    SynthOptions so;
    so.duration_s = mc.duration_s;
    so.currents = curvyCurrents(0.37 * run, 1.6, 0.4);  // v ~ 0.3 m/s, omega ~ +-0.25 rad/s
    so.start_pause_s = 0.0;  // the truth has process noise from the start, as the filter assumes
    // Obstacle drawn from the filter's prior (configured position and covariance).
    const double d0 = std::hypot(opt.initial_obstacle_x_m, opt.initial_obstacle_y_m);
    const double b0 = std::atan2(opt.initial_obstacle_y_m, opt.initial_obstacle_x_m);
    // Drawn from the prior of the filter's own obstacle form: Gaussian in (d, beta) for the
    // polar form, in (px, py) (the linearised polar covariance) for the Cartesian one.
    const double sd = opt.initial_obstacle_range_sigma_m;
    const double sb = opt.initial_obstacle_bearing_sigma_deg * M_PI / 180;
    const double n1 = N01(prior_rng), n2 = N01(prior_rng);
    if (opt.obstacle_form == ObstacleFormOption::Polar) {
      const double d = d0 + sd * n1, b = b0 + sb * n2;
      so.obstacle_world = Eigen::Vector2d(d * std::cos(b), d * std::sin(b));
    } else {
      so.obstacle_world = Eigen::Vector2d(d0 * std::cos(b0), d0 * std::sin(b0)) +
                          sd * n1 * Eigen::Vector2d(std::cos(b0), std::sin(b0)) +
                          d0 * sb * n2 * Eigen::Vector2d(-std::sin(b0), std::cos(b0));
    }
    const SynthRun sr = synthesize(cfg, so, 1000 + run);
    const EstimationResult res = runEstimator(sr.rec, cfg, opt);
    if (run == 0)
      std::printf("CVODE: %ld intervals, %.2f steps and %.2f f-evaluations per interval\n",
                  res.cvode.intervals, double(res.cvode.steps) / res.cvode.intervals,
                  double(res.cvode.rhs_evals) / res.cvode.intervals);
    if (nees_sum.empty()) {
      nees_sum.assign(res.estimates.size(), 0.0);
      nees_n.assign(res.estimates.size(), 0);
    }
    for (std::size_t i = 0; i < res.estimates.size() && i < nees_sum.size(); ++i) {
      const EstimateSample& e = res.estimates[i];
      Eigen::Matrix<double, 7, 1> err = e.x - sr.canonical(e.t_s, so.obstacle_world);
      err(4) = model::wrapAngle(err(4));
      nees_sum[i] += err.dot(e.P.ldlt().solve(err));
      ++nees_n[i];
      for (int j = 0; j < 7; ++j) comp[j] += err(j) * err(j) / e.P(j, j);
      ++ncomp;
    }
    for (int s = 0; s < kNumSensors; ++s) {
      const SensorStats& st = res.sensors[s];
      nis_sum[s] += st.nis_sum;
      nis_n[s] += st.nis_count;
      nis_in[s] += st.nis_inside95;
    }
  }
  McResult r;
  r.per_component = comp / ncomp;
  r.band = stats::chi2MeanBand(0.95, 7, mc.runs);
  double total = 0;
  int count = 0, inside = 0;
  for (std::size_t i = 0; i < nees_sum.size(); ++i) {
    if (nees_n[i] != mc.runs) continue;
    const double m = nees_sum[i] / mc.runs;
    total += m;
    ++count;
    if (m >= r.band.first && m <= r.band.second) ++inside;
  }
  r.mean_nees = total / count;
  r.frac_times_inside = double(inside) / count;
  for (int s = 0; s < kNumSensors; ++s) {
    if (!nis_n[s]) continue;
    const int dof = (s == int(Sensor::Encoders) || s == int(Sensor::Pozyx)) ? 2 : 1;
    r.mean_nis[s] = nis_sum[s] / nis_n[s];
    r.nis_band[s] =
        stats::chi2MeanBand(0.95, dof, double(nis_n[s]) / mc.runs);  // per-run mean band
    r.nis_inside95[s] = double(nis_in[s]) / nis_n[s];
  }
  return r;
}

void report(const char* name, const McResult& r, const McConfig& mc) {
  std::printf(
      "[%s] %d runs x %.0f s: mean NEES %.3f (7 dof; 95%% band of a %d-run mean "
      "[%.3f, %.3f]); times with run-averaged NEES inside the band: %.1f%%\n",
      name, mc.runs, mc.duration_s, r.mean_nees, mc.runs, r.band.first, r.band.second,
      100 * r.frac_times_inside);
  std::printf("[%s]   per state err^2/var (v omega x y phi o1 o2):%s\n", name,
              fmtv(r.per_component).c_str());
  for (int s = 0; s < 3; ++s)
    std::printf(
        "[%s]   NIS %-8s mean %.3f (band of one run's mean [%.3f, %.3f]), inside the "
        "single-sample 95%% band %.1f%%\n",
        name, sensorName(Sensor(s)), r.mean_nis[s], r.nis_band[s].first, r.nis_band[s].second,
        100 * r.nis_inside95[s]);
}

void checkConsistency(const McConfig& mc, const char* name) {
  const auto t0 = std::chrono::steady_clock::now();
  const McResult r = monteCarlo(mc);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  report(name, r, mc);
  std::printf("[%s]   wall time %.2f s\n", name, secs);
  EXPECT_GT(r.mean_nees, r.band.first);
  EXPECT_LT(r.mean_nees, r.band.second);
  EXPECT_GT(r.frac_times_inside, 0.80);
  for (int s = 0; s < 3; ++s) {
    EXPECT_GT(r.mean_nis[s], r.nis_band[s].first) << sensorName(Sensor(s));
    EXPECT_LT(r.mean_nis[s], r.nis_band[s].second) << sensorName(Sensor(s));
    EXPECT_NEAR(r.nis_inside95[s], 0.95, 0.03) << sensorName(Sensor(s));
  }
}

}  // namespace

TEST(Consistency, NeesAndNisInsideChiSquareBandsCartesian) {
  McConfig mc;
  mc.form = ObstacleFormOption::Cartesian;
  checkConsistency(mc, "cartesian (7)");
}

TEST(Consistency, NeesAndNisInsideChiSquareBandsPolar) {
  McConfig mc;
  mc.form = ObstacleFormOption::Polar;
  checkConsistency(mc, "polar (8)");
}
