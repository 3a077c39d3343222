// Fig. 5 over many drives: the paper's three-task drive with the faulty chair (left encoder
// pulley ratio 0.95, right gearbox friction x1.3, sonar dropouts: the faults of the bundled
// three_task_faulty recording), simulated with N seeds; every Fig. 5 variant and the baseline
// filter are evaluated with the metrics of `wheelchair evaluate` (SE2 alignment) against the
// simulator's true pose (default) or against Pozyx as `evaluate` does (--reference pozyx:
// Pozyx's 0.1 m noise puts a ~0.14 m floor under every ATE). One drive decides nothing; the
// campaign reports per-variant means and the paired EKF-minus-variant differences with their
// standard errors and win counts (docs/estimation.md, "Fig. 5 campaign").
//
//   build/bench/fig5_campaign [--runs N] [--seed S] [--config F] [--effects a;b;...]
//                             [--reference truth|pozyx] [--engine model|mujoco] [--check]
//                             [--estimate-encoder-scales] [--check-ate M] [--check-nees X]
//                             [--scenario NAME] [--duration S] [--json OUT] [--fixed-chair]
//
// The chair of each drive is drawn from the filter's prior (drawChair): a Monte-Carlo NEES is
// only meaningful when the truth is drawn from the distribution the filter assumes. Each
// wheel's encoder scale k_w = (nominal radius) / (true rolling radius) ~ N(prior mean,
// allowance) with the allowance the [estimator] section gives a healthy wheel
// (closed_encoder_scale_sigma while the scale states start closed, healthy_encoder_scale_sigma
// when they are open from the start, 0 when the filter carries none), and the gyro bias
// ~ N(gyro_bias_rad_s, closed_gyro_bias_sigma_rad_s or gyro_bias_sigma_rad_s) likewise. Both
// engines have ONE wheel radius: it is set to the mean of the two drawn radii ([vehicle]
// wheel_radius_m of the simulator's copy of the configuration: the model engine's dynamics,
// the MuJoCo model's tyre spheres and axle height), and each wheel's difference from it enters
// as the encoder scale it is kinematically equivalent to (an encoder_scale effect r_mean / r_w;
// the filter reads the ticks with the nominal radius). A gyro bias is a gyro_bias effect. The
// faulty drives keep their effects on top (encoder scales multiply). Seeded per drive (stream
// "fig5.chair" of the drive's seed); --fixed-chair: the nominal chair on every drive (the
// figures before 2026-11-24). The JSON records the prior, every drive's draw and the config.
//
// --scenario / --duration: another drive than three_task (e.g. `--scenario excite --duration
// 3600 --runs 4`: the one-hour drive; duration 0 = the scenario's own). The EKF's position NEES
// is also reported per quarter of the drive (a drifting covariance shows as a trend) and per
// axis (along-track, cross-track, heading: axisNees), and its
// mean NIS per sensor over all drives against the band of that mean (Measurement.h bookUpdate).
//
// --engine: the truth simulator (default model; mujoco = the chair as a MuJoCo multibody,
// whose physics is not the EKF's model, docs/simulation.md).
//
// --check: exit 1 unless the EKF's trajectory error is lower than that of both raw variants
// (encoders only; encoder v + gyro omega) and of the baseline filter, each with a paired
// t < -2 (the CTest `fig5_campaign_smoke` runs it on 6 drives).
//
// --estimate-encoder-scales: the sensor-error states on ([estimator] estimate_encoder_scales);
// --check-ate M / --check-nees X: exit 1 when the EKF's mean ATE (m) / mean position NEES
// (2 dof, vs truth) exceeds it (CTest `fig5_campaign_scales_smoke`: the faulty chair with the
// states on must stay <= 0.05 m and NEES <= 4).
//
// --check-along-track-min X: exit 1 when the EKF's along-track NEES (1 dof) is below X (CTest
// `fig5_campaign_drawn_chair_smoke`: with the chair drawn from the prior the rolling-radius
// allowance is exercised, 0.53 on 6 clean drives; the nominal chair, --fixed-chair, gives 0.02).
#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/effects/Effect.h"
#include "libwheelchair/estimation/EkfOptions.h"
#include "libwheelchair/evaluation/Batch.h"
#include "libwheelchair/evaluation/Metrics.h"
#include "libwheelchair/evaluation/Nees.h"
#include "libwheelchair/simulation/MujocoEngine.h"
#include "libwheelchair/simulation/Random.h"
#include "libwheelchair/simulation/Simulator.h"
#include "libwheelchair/stats/Distributions.h"
#include "libwheelchair/util/AtomicFile.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <array>
#include <cmath>
#include <future>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

using namespace wheelchair;

namespace {

/// The filter's prior on the chair's random constants (from its [estimator] section): what a
/// drive's chair is drawn from. Scales k = reported / true rim distance (-), bias rad/s.
struct ChairPrior {
  double scale_mean[2] = {1, 1}, scale_sigma = 0;  ///< per wheel, index 0 = right
  double gyro_bias_mean_rad_s = 0, gyro_bias_sigma_rad_s = 0;
  std::string scale_sigma_key, gyro_bias_sigma_key;  ///< which [estimator] key gave the sigma
};

/// The prior the physics filter carries for a HEALTHY chair: the scale states closed at the
/// start (open_sensor_errors_on_alarm) are consider states with closed_*_sigma; open from the
/// start they carry healthy_encoder_scale_sigma per wheel (the healthy wheel of the fault
/// prior; encoder_scale_sigma is the fault allowance) and gyro_bias_sigma_rad_s; not estimated:
/// held exactly at the prior mean (sigma 0).
ChairPrior chairPrior(const config::WheelchairConfig& cfg) {
  estimation::EkfOptions o;
  o.loadFromConfig(cfg.ini());
  ChairPrior p;
  p.scale_mean[0] = o.encoder_scale_right, p.scale_mean[1] = o.encoder_scale_left;
  p.gyro_bias_mean_rad_s = o.gyro_bias_rad_s;
  if (o.filter != estimation::FilterKind::Physics) return p;
  if (o.estimate_encoder_scales) {
    const bool closed = o.open_sensor_errors_on_alarm;
    p.scale_sigma = closed ? o.closed_encoder_scale_sigma : o.healthy_encoder_scale_sigma;
    p.scale_sigma_key = closed ? "closed_encoder_scale_sigma" : "healthy_encoder_scale_sigma";
  }
  if (o.estimate_gyro_bias) {
    const bool closed = o.open_sensor_errors_on_alarm;
    p.gyro_bias_sigma_rad_s = closed ? o.closed_gyro_bias_sigma_rad_s : o.gyro_bias_sigma_rad_s;
    p.gyro_bias_sigma_key = closed ? "closed_gyro_bias_sigma_rad_s" : "gyro_bias_sigma_rad_s";
  }
  return p;
}

/// One drive's chair. k_w = r_nominal / r_w (reported / true rim distance of wheel w's
/// encoder read with the nominal radius); the engines' one radius r_mean = (r_R + r_L) / 2.
struct DrawnChair {
  double encoder_scale[2] = {1, 1};
  double wheel_radius_m[2] = {0, 0};
  double mean_radius_m = 0;
  double gyro_bias_rad_s = 0;
};

/// Draws the chair of the drive `seed` from `prior` (own random stream: the sensor noise of a
/// drive is the same with and without the draw). Example: scale_sigma 0.005 gives true radii
/// 0.17 m +- 0.85 mm per wheel.
DrawnChair drawChair(const ChairPrior& prior, double nominal_radius_m, uint64_t seed) {
  simulation::Rng rng(seed, "fig5.chair");
  DrawnChair c;
  for (int w = 0; w < 2; ++w) {
    c.encoder_scale[w] = prior.scale_mean[w] + prior.scale_sigma * rng.normal();
    if (!(c.encoder_scale[w] > 0.5 && c.encoder_scale[w] < 2))
      throw std::runtime_error("drawn encoder scale " + std::to_string(c.encoder_scale[w]) +
                               " outside 0.5..2 (check the [estimator] scale prior)");
    c.wheel_radius_m[w] = nominal_radius_m / c.encoder_scale[w];
  }
  c.mean_radius_m = 0.5 * (c.wheel_radius_m[0] + c.wheel_radius_m[1]);
  c.gyro_bias_rad_s = prior.gyro_bias_mean_rad_s + prior.gyro_bias_sigma_rad_s * rng.normal();
  return c;
}

/// The simulator's configuration and effects for `chair`: [vehicle] wheel_radius_m = r_mean,
/// an encoder_scale r_mean / r_w per wheel and a gyro_bias, before the campaign's effects
/// (which stay on top: encoder scales multiply).
std::vector<effects::EffectSpec> applyChair(const DrawnChair& chair, const std::string& engine,
                                            config::WheelchairConfig& sim_cfg,
                                            const std::vector<effects::EffectSpec>& effects) {
  sim_cfg.set("vehicle", "wheel_radius_m", fmt::format("{:.17g}", chair.mean_radius_m));
  std::vector<effects::EffectSpec> out;
  const char* side[2] = {"right", "left"};
  for (int w = 0; w < 2; ++w) {
    const double s = chair.mean_radius_m / chair.wheel_radius_m[w];
    if (s != 1.0)
      out.push_back(simulation::parseEngineEffect(
          fmt::format("encoder_scale:side={},scale={:.17g}", side[w], s), engine));
  }
  if (chair.gyro_bias_rad_s != 0.0)
    out.push_back(simulation::parseEngineEffect(
        fmt::format("gyro_bias:bias_rad_s={:.17g}", chair.gyro_bias_rad_s), engine));
  out.insert(out.end(), effects.begin(), effects.end());
  return out;
}

struct RunMetrics {
  uint64_t seed = 0;
  DrawnChair chair;  ///< the drive's chair (nominal with --fixed-chair)
  std::map<std::string, double> ate_m, terminal_m;
  /// EKF speed error relative to the true speed, mean over estimates while |v_true| > 0.3 m/s.
  double ekf_speed_error_rel = 0;
  /// EKF position NEES against the truth at its 10 Hz samples (evaluation/Nees.h; truth only).
  std::vector<double> ekf_nees;
  /// The same errors split per axis, 1 dof each (axisNees): sums over the truth times of the
  /// along-track, cross-track (true heading frame) and heading NEES, and their count.
  std::array<double, 3> axis_nees_sum{};
  long axis_nees_count = 0;
  /// EKF NIS sums and counts per sensor (EstimationResult::sensors).
  std::array<double, estimation::kNumSensors> nis_sum{};
  std::array<long, estimation::kNumSensors> nis_count{};
  std::string error;
};

/// Per-axis NEES of the EKF against the truth (1 dof each; consistent: 1): at each reference
/// time the estimate is interpolated linearly between the two estimates around it (position,
/// heading by its wrapped difference, covariance), the position error e and its 2x2 covariance
/// are rotated into the true heading's frame (along-track, cross-track), and
/// e_along^2 / P_along, e_cross^2 / P_cross, e_phi^2 / P_phi are added to `sum`. Shows which
/// direction a position NEES off its band comes from (docs/estimation.md, "What keeps the NEES
/// low"). Example: a filter that carries a rolling-radius allowance the truth does not have
/// gives along-track << 1.
void axisNees(const estimation::EstimateSeries& est,
              const std::vector<evaluation::Position2DStamped>& ref, std::array<double, 3>& sum,
              long& count) {
  std::size_t j = 0;
  for (const auto& q : ref) {
    while (j + 1 < est.size() && est[j + 1].t_s < q.t_s) ++j;
    if (!q.hasHeading() || j + 1 >= est.size() || est[j].t_s > q.t_s) continue;
    const auto &a = est[j], &b = est[j + 1];
    const double dt_s = b.t_s - a.t_s;
    if (!(dt_s > 0) || dt_s > 0.5) continue;
    const double w = (q.t_s - a.t_s) / dt_s;
    const Eigen::Vector2d p = (1 - w) * a.x.segment<2>(2) + w * b.x.segment<2>(2);
    const double phi = a.x(4) + w * std::remainder(b.x(4) - a.x(4), 2 * M_PI);
    const Eigen::Matrix3d P = (1 - w) * a.P.block<3, 3>(2, 2) + w * b.P.block<3, 3>(2, 2);
    const double c = std::cos(q.phi_rad), sn = std::sin(q.phi_rad);
    Eigen::Matrix2d Rt;  // start frame -> (along, cross) of the true heading
    Rt << c, sn, -sn, c;
    const Eigen::Vector2d e = Rt * (p - Eigen::Vector2d(q.x_m, q.y_m));
    const Eigen::Matrix2d Pe = Rt * P.topLeftCorner<2, 2>() * Rt.transpose();
    const double e_phi = std::remainder(phi - q.phi_rad, 2 * M_PI);
    if (!(Pe(0, 0) > 0 && Pe(1, 1) > 0 && P(2, 2) > 0)) continue;
    sum[0] += e(0) * e(0) / Pe(0, 0);
    sum[1] += e(1) * e(1) / Pe(1, 1);
    sum[2] += e_phi * e_phi / P(2, 2);
    ++count;
  }
}

RunMetrics runOne(const config::WheelchairConfig& cfg, uint64_t seed,
                  const std::vector<effects::EffectSpec>& effects, bool against_truth,
                  const std::string& engine, const std::string& scenario, double duration_s,
                  const ChairPrior* prior) {
  RunMetrics out;
  out.seed = seed;
  try {
    simulation::SimulationOptions so;
    so.loadFromConfig(cfg.ini());
    so.engine = engine;
    // The truth's chair: drawn from the filter's prior (the filter keeps the nominal cfg).
    config::WheelchairConfig sim_cfg(cfg);
    const double r_nom_m = cfg.vehicle.geom.wheel_radius_m;
    out.chair = prior ? drawChair(*prior, r_nom_m, seed)
                      : DrawnChair{{1, 1}, {r_nom_m, r_nom_m}, r_nom_m, 0};
    const auto sim_effects = prior ? applyChair(out.chair, engine, sim_cfg, effects) : effects;
    const auto sim = simulation::simulate(sim_cfg, scenario, seed, duration_s, sim_effects, so);
    const auto est = evaluation::estimateVariants(sim.recording, cfg, true);
    for (int s = 0; s < estimation::kNumSensors; ++s) {
      out.nis_sum[s] = est.ekf.sensors[s].nis_sum;
      out.nis_count[s] = est.ekf.sensors[s].nis_count;
    }
    evaluation::MetricOptions mo;
    std::vector<evaluation::Position2DStamped> reference;
    if (against_truth) {
      // The simulator's true body pose (start frame, as the estimates), 10 Hz like Pozyx.
      double next_t = -1e300;
      for (const auto& s : sim.truth.samples)
        if (s.t_s >= next_t) {
          reference.push_back({s.t_s, s.x_m, s.y_m, s.phi_rad});
          next_t = s.t_s + 0.1;
        }
    } else {
      const auto gt = evaluation::groundTruthOf(sim.recording, cfg);
      mo.lever_arm_m = gt.lever_arm_m;
      reference = gt.samples;
    }
    // The true speed at each EKF output time: the last truth sample at or before it
    // ([simulation] truth_rate_hz, 100 Hz by default).
    double sum = 0;
    long n = 0;
    std::size_t j = 0;
    const auto& truth = sim.truth.samples;
    for (const auto& e : est.ekf.estimates) {
      while (j + 1 < truth.size() && truth[j + 1].t_s <= e.t_s) ++j;
      const double v_true = truth[j].v_m_s;
      if (std::fabs(v_true) > 0.3) {
        sum += (e.x(0) - v_true) / v_true;
        ++n;
      }
    }
    out.ekf_speed_error_rel = n ? sum / n : 0.0;
    if (against_truth) {
      std::vector<evaluation::PositionEstimateStamped> pe;
      for (const auto& e : est.ekf.estimates)
        pe.push_back({e.t_s, e.x.segment<2>(2), e.P.block<2, 2>(2, 2)});
      out.ekf_nees = evaluation::averageNees(pe, reference, evaluation::NeesOptions{}).nees;
      axisNees(est.ekf.estimates, reference, out.axis_nees_sum, out.axis_nees_count);
    }
    for (const auto& v : evaluation::variantNames()) {
      const auto m = evaluation::computeMetrics(est.trajectory(v), reference, mo);
      out.ate_m[v] = m.ate_rmse_m;
      out.terminal_m[v] = m.terminal_error_m;
    }
  } catch (const std::exception& e) {
    out.error = e.what();
  }
  return out;
}

struct Summary {
  double mean = 0, sd = 0, se = 0;
  int n = 0;
};

Summary summarise(const std::vector<double>& v) {
  Summary s;
  s.n = static_cast<int>(v.size());
  if (s.n == 0) return s;
  for (double x : v) s.mean += x;
  s.mean /= s.n;
  if (s.n > 1) {
    for (double x : v) s.sd += (x - s.mean) * (x - s.mean);
    s.sd = std::sqrt(s.sd / (s.n - 1));
    s.se = s.sd / std::sqrt(double(s.n));
  }
  return s;
}

struct Args {
  int runs = 40;
  bool against_truth = true;
  bool check = false;
  bool estimate_encoder_scales = false;  ///< [estimator] estimate_encoder_scales = 1
  bool fixed_chair = false;     ///< the nominal chair on every drive (no draw from the prior)
  double check_ate_m = -1;      ///< > 0: fail when the EKF's mean ATE exceeds it
  double check_nees = -1;       ///< > 0: fail when the EKF's mean position NEES does
  double check_along_min = -1;  ///< > 0: fail when the EKF's along-track NEES is below it
  uint64_t seed = 20200612;
  double duration_s = 0;  ///< 0: the scenario's own
  std::string cfg_path, json_path, engine = "model", scenario = "three_task";
  std::string effects_text =
      "encoder_scale:side=left,scale=0.95;motor_asymmetry:side=right,friction_ratio=1.3;"
      "sonar_dropout:probability=0.15,burst_length=3";
};

// The command line into `args`; 0, or the exit code (2: usage) after a message on stderr.
int parseArgs(int argc, char** argv, Args& args) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::runtime_error("missing value after " + a);
      return argv[++i];
    };
    if (a == "--runs")
      args.runs = std::stoi(next());
    else if (a == "--seed")
      args.seed = std::stoull(next());
    else if (a == "--config")
      args.cfg_path = next();
    else if (a == "--effects")
      args.effects_text = next();
    else if (a == "--check")
      args.check = true;
    else if (a == "--estimate-encoder-scales")
      args.estimate_encoder_scales = true;
    else if (a == "--fixed-chair")
      args.fixed_chair = true;
    else if (a == "--check-ate")
      args.check_ate_m = std::stod(next());
    else if (a == "--check-nees")
      args.check_nees = std::stod(next());
    else if (a == "--check-along-track-min")
      args.check_along_min = std::stod(next());
    else if (a == "--scenario")
      args.scenario = next();
    else if (a == "--duration")
      args.duration_s = std::stod(next());
    else if (a == "--reference") {
      const std::string r = next();
      if (r != "truth" && r != "pozyx") throw std::runtime_error("--reference: truth | pozyx");
      args.against_truth = r == "truth";
    } else if (a == "--engine") {
      args.engine = next();
      if (args.engine != "model" && args.engine != "mujoco") {
        std::cerr << "fig5_campaign: --engine must be model or mujoco\n";
        return 2;
      }
    } else if (a == "--json")
      args.json_path = next();
    else {
      std::cerr << "usage: fig5_campaign [--runs N] [--seed S] [--config F] [--effects a;b] "
                   "[--reference truth|pozyx] [--engine model|mujoco] [--check] "
                   "[--estimate-encoder-scales] [--check-ate M] [--check-nees X] "
                   "[--scenario NAME] [--duration S] [--json OUT] [--fixed-chair] "
                   "[--check-along-track-min X]\n";
      return 2;
    }
  }
  return 0;
}

// Every drive of the campaign, on two workers (the reference machine's cores); each run is
// independent and seeded.
std::vector<RunMetrics> runCampaign(const Args& args, const config::WheelchairConfig& cfg,
                                    const std::vector<effects::EffectSpec>& effects,
                                    const ChairPrior* prior) {
  const int runs = args.runs;
  const unsigned workers = std::max(1u, std::min(2u, std::thread::hardware_concurrency()));
  std::vector<RunMetrics> results(runs);
  std::vector<std::thread> pool;
  for (unsigned w = 0; w < workers; ++w)
    pool.emplace_back([&, w] {
      for (int k = static_cast<int>(w); k < runs; k += static_cast<int>(workers))
        results[k] = runOne(cfg, args.seed + static_cast<uint64_t>(k), effects, args.against_truth,
                            args.engine, args.scenario, args.duration_s, prior);
    });
  for (auto& t : pool) t.join();
  return results;
}

// Per-variant errors and the paired EKF-minus-variant differences over the successful runs.
struct Tally {
  std::map<std::string, std::vector<double>> ate, term, d_ate, d_term;
  std::map<std::string, int> wins_ate, wins_term;
  std::vector<double> speed_error;
  std::vector<double> nees_mean;          ///< per truth time: mean position NEES over the drives
  std::array<double, 3> axis_nees_sum{};  ///< along-track, cross-track, heading (1 dof each)
  long axis_nees_count = 0;
  std::array<double, estimation::kNumSensors> nis_sum{};
  std::array<long, estimation::kNumSensors> nis_count{};
  int failed = 0;
};

Tally tally(const std::vector<RunMetrics>& results) {
  Tally t;
  for (const auto& r : results) {
    if (!r.error.empty()) {
      ++t.failed;
      std::cerr << "seed " << r.seed << ": " << r.error << "\n";
      continue;
    }
    t.speed_error.push_back(r.ekf_speed_error_rel);
    for (int a = 0; a < 3; ++a) t.axis_nees_sum[a] += r.axis_nees_sum[a];
    t.axis_nees_count += r.axis_nees_count;
    for (int s = 0; s < estimation::kNumSensors; ++s) {
      t.nis_sum[s] += r.nis_sum[s];
      t.nis_count[s] += r.nis_count[s];
    }
    for (const auto& v : evaluation::variantNames()) {
      t.ate[v].push_back(r.ate_m.at(v));
      t.term[v].push_back(r.terminal_m.at(v));
      if (v == "ekf") continue;
      t.d_ate[v].push_back(r.ate_m.at("ekf") - r.ate_m.at(v));
      t.d_term[v].push_back(r.terminal_m.at("ekf") - r.terminal_m.at(v));
      t.wins_ate[v] += r.ate_m.at("ekf") < r.ate_m.at(v);
      t.wins_term[v] += r.terminal_m.at("ekf") < r.terminal_m.at(v);
    }
  }
  std::size_t len = SIZE_MAX;
  for (const auto& r : results)
    if (r.error.empty()) len = std::min(len, r.ekf_nees.size());
  const int ok = static_cast<int>(results.size()) - t.failed;
  if (ok > 0)
    for (std::size_t k = 0; k < len; ++k) {
      double m = 0;
      for (const auto& r : results)
        if (r.error.empty()) m += r.ekf_nees[k] / ok;
      t.nees_mean.push_back(m);
    }
  return t;
}

// Prints the campaign's tables and returns them as JSON.
nlohmann::json report(const Args& args, Tally& t) {
  const auto& names = evaluation::variantNames();
  const int ok = args.runs - t.failed;
  nlohmann::json j;
  j["runs"] = args.runs;
  j["failed"] = t.failed;
  j["seed"] = args.seed;
  j["effects"] = args.effects_text;
  j["reference"] = args.against_truth ? "truth" : "pozyx";
  j["engine"] = args.engine;
  j["estimate_encoder_scales"] = args.estimate_encoder_scales;
  fmt::print(
      "Fig. 5 campaign: {}, {} drives (seeds {}..{}), engine {}, effects {}; reference: "
      "{}\n",
      args.scenario, ok, args.seed, args.seed + args.runs - 1, args.engine, args.effects_text,
      args.against_truth ? "simulator truth at 10 Hz" : "Pozyx (as `wheelchair evaluate`)");
  fmt::print("{:<14} {:>16} {:>18}\n", "variant", "ATE rmse (m)", "terminal (m)");
  for (const auto& v : names) {
    const auto a = summarise(t.ate[v]), e = summarise(t.term[v]);
    fmt::print("{:<14} {:>7.3f} +- {:<6.3f} {:>8.3f} +- {:<6.3f}\n", v, a.mean, a.se, e.mean, e.se);
    j["variants"][v] = {{"ate_mean_m", a.mean},
                        {"ate_se_m", a.se},
                        {"terminal_mean_m", e.mean},
                        {"terminal_se_m", e.se}};
  }
  if (args.against_truth && ok > 0 && !t.nees_mean.empty()) {
    // Monte-Carlo NEES: at each 10 Hz truth time k the mean over the drives of NEES_k, for a
    // consistent filter chi2(2 R) / R; the share of times inside its two-sided 95 % band.
    const std::size_t len = t.nees_mean.size();
    const auto band = stats::chi2MeanBand(0.95, 2, ok);
    double all = 0;
    long inside = 0;
    for (const double m : t.nees_mean) {
      all += m / len;
      inside += m >= band.first && m <= band.second;
    }
    fmt::print(
        "EKF position NEES (Monte-Carlo over {} drives, {} times): mean {:.2f} (consistent: 2), "
        "{:.0f} % of the times inside the 95 % band {:.2f}..{:.2f}\n",
        ok, len, all, 100.0 * inside / len, band.first, band.second);
    // Per quarter of the drive: a covariance that drifts (grows too fast or too slowly against
    // the error) shows as a trend.
    std::vector<double> quarters(4, 0.0);
    for (std::size_t k = 0; k < len; ++k) quarters[4 * k / len] += t.nees_mean[k];
    for (int q = 0; q < 4; ++q) quarters[q] /= double((q + 1) * len / 4 - q * len / 4);
    fmt::print("  by quarter of the drive: {:.2f} {:.2f} {:.2f} {:.2f}\n", quarters[0], quarters[1],
               quarters[2], quarters[3]);
    j["ekf_nees"] = {
        {"mean", all}, {"inside95", double(inside) / len}, {"times", len}, {"quarters", quarters}};
    if (t.axis_nees_count > 0) {
      // The same errors per axis (1 dof each, consistent: 1; band of the mean over all drives
      // and times, optimistic: successive times are correlated).
      const double n = double(t.axis_nees_count);
      const auto b1 = stats::chi2MeanBand(0.95, 1, double(ok));
      fmt::print(
          "  per axis (1 dof, consistent: 1; band of {} drives {:.2f}..{:.2f}): along-track "
          "{:.2f}, cross-track {:.2f}, heading {:.2f}\n",
          ok, b1.first, b1.second, t.axis_nees_sum[0] / n, t.axis_nees_sum[1] / n,
          t.axis_nees_sum[2] / n);
      j["ekf_nees"]["along_track"] = t.axis_nees_sum[0] / n;
      j["ekf_nees"]["cross_track"] = t.axis_nees_sum[1] / n;
      j["ekf_nees"]["heading"] = t.axis_nees_sum[2] / n;
    }
  }
  // Mean NIS per sensor over every accepted update of every drive, against the 95 % band of that
  // mean for a consistent filter (dof 2: encoders, Pozyx; 1: gyro, sonar).
  fmt::print("EKF mean NIS:");
  for (int s = 0; s < estimation::kNumSensors; ++s) {
    if (t.nis_count[s] == 0) continue;
    const int dof =
        (s == int(estimation::Sensor::Encoders) || s == int(estimation::Sensor::Pozyx)) ? 2 : 1;
    const double m = t.nis_sum[s] / double(t.nis_count[s]);
    const auto b = stats::chi2MeanBand(0.95, dof, double(t.nis_count[s]));
    const char* name = estimation::sensorName(estimation::Sensor(s));
    fmt::print(" {} {:.3f} (dof {}, band {:.3f}..{:.3f})", name, m, dof, b.first, b.second);
    j["ekf_nis"][name] = {{"mean", m}, {"dof", dof}, {"updates", t.nis_count[s]}};
  }
  fmt::print("\n");
  const auto sp = summarise(t.speed_error);
  fmt::print(
      "EKF speed error while moving (|v| > 0.3 m/s): {:+.2f} % +- {:.2f} % of the true "
      "speed\n",
      100 * sp.mean, 100 * sp.se);
  j["ekf_speed_error_rel"] = {{"mean", sp.mean}, {"se", sp.se}};
  fmt::print("EKF minus variant (paired; negative = EKF better; t = mean / se; wins of {}):\n", ok);
  for (const auto& v : names) {
    if (v == "ekf") continue;
    const auto a = summarise(t.d_ate[v]), e = summarise(t.d_term[v]);
    fmt::print(
        "  {:<14} ATE {:+.4f} m (t = {:+.1f}, EKF better in {}), terminal {:+.4f} m "
        "(t = {:+.1f}, EKF better in {})\n",
        v, a.mean, a.se > 0 ? a.mean / a.se : 0.0, t.wins_ate[v], e.mean,
        e.se > 0 ? e.mean / e.se : 0.0, t.wins_term[v]);
    j["ekf_minus"][v] = {{"ate_mean_m", a.mean},          {"ate_se_m", a.se},
                         {"ate_ekf_wins", t.wins_ate[v]}, {"terminal_mean_m", e.mean},
                         {"terminal_se_m", e.se},         {"terminal_ekf_wins", t.wins_term[v]}};
  }
  return j;
}

// The chair of every drive and the prior they were drawn from, for the JSON; prints one line.
nlohmann::json chairJson(const Args& args, const ChairPrior& p,
                         const std::vector<RunMetrics>& results) {
  nlohmann::json j;
  j["fixed"] = args.fixed_chair;
  if (args.fixed_chair) {
    fmt::print("Chair: nominal on every drive (--fixed-chair)\n");
  } else {
    j["prior"] = {{"encoder_scale_mean", {p.scale_mean[0], p.scale_mean[1]}},
                  {"encoder_scale_sigma", p.scale_sigma},
                  {"encoder_scale_sigma_key", p.scale_sigma_key},
                  {"gyro_bias_mean_rad_s", p.gyro_bias_mean_rad_s},
                  {"gyro_bias_sigma_rad_s", p.gyro_bias_sigma_rad_s},
                  {"gyro_bias_sigma_key", p.gyro_bias_sigma_key}};
    fmt::print(
        "Chair: drawn per drive from the filter's prior: encoder scale (nominal / true radius) "
        "{:.4f}/{:.4f} +- {:.4f} ({}), gyro bias {:.2g} +- {:.2g} rad/s ({})\n",
        p.scale_mean[0], p.scale_mean[1], p.scale_sigma,
        p.scale_sigma_key.empty() ? "no scale states" : p.scale_sigma_key, p.gyro_bias_mean_rad_s,
        p.gyro_bias_sigma_rad_s,
        p.gyro_bias_sigma_key.empty() ? "no bias state" : p.gyro_bias_sigma_key);
  }
  for (const auto& r : results)
    j["drives"].push_back(
        {{"seed", r.seed},
         {"encoder_scale", {r.chair.encoder_scale[0], r.chair.encoder_scale[1]}},
         {"wheel_radius_m", {r.chair.wheel_radius_m[0], r.chair.wheel_radius_m[1]}},
         {"engine_wheel_radius_m", r.chair.mean_radius_m},
         {"gyro_bias_rad_s", r.chair.gyro_bias_rad_s}});
  return j;
}

// --check: true when the EKF's ATE is below every other variant's with a paired t < -2.
bool checkPasses(Tally& t) {
  bool ok_all = true;
  for (const auto& v : evaluation::variantNames()) {
    if (v == "ekf") continue;
    const auto a = summarise(t.d_ate[v]);
    const bool better = a.mean < 0 && (a.se == 0 || a.mean / a.se < -2);
    if (!better) {
      fmt::print("check FAILED: the EKF's ATE is not significantly below {}'s\n", v);
      ok_all = false;
    }
  }
  return ok_all;
}

}  // namespace

int main(int argc, char** argv) {
  Args args;
  if (const int rc = parseArgs(argc, argv, args)) return rc;
  auto cfg = config::WheelchairConfig::load(
      args.cfg_path.empty() ? std::string(WHEELCHAIR_SOURCE_DIR) + "/config/wheelchair.ini"
                            : args.cfg_path);
  if (args.estimate_encoder_scales) cfg.set("estimator", "estimate_encoder_scales", "1");
  std::vector<effects::EffectSpec> effects;
  std::stringstream ss(args.effects_text);
  for (std::string t; std::getline(ss, t, ';');)
    if (!t.empty()) effects.push_back(simulation::parseEngineEffect(t, args.engine));

  const ChairPrior prior = chairPrior(cfg);
  const auto results = runCampaign(args, cfg, effects, args.fixed_chair ? nullptr : &prior);
  Tally t = tally(results);
  const nlohmann::json chair = chairJson(args, prior, results);
  nlohmann::json j = report(args, t);
  j["chair"] = chair;
  j["config"] = cfg.text();
  try {
    if (!args.json_path.empty()) util::writeFileAtomically(args.json_path, j.dump(1) + "\n");
  } catch (const std::exception& e) {
    std::cerr << "fig5_campaign: " << e.what() << "\n";
    return 1;
  }
  if (t.failed) return 1;
  if (args.check) {
    if (!checkPasses(t)) return 1;
    fmt::print("check passed: EKF ATE below every other variant's (paired t < -2)\n");
  }
  if (args.check_ate_m > 0) {
    const double ate = j["variants"]["ekf"]["ate_mean_m"].get<double>();
    if (!(ate <= args.check_ate_m)) {
      fmt::print("check FAILED: EKF mean ATE {:.4f} m > {:.4f} m\n", ate, args.check_ate_m);
      return 1;
    }
    fmt::print("check passed: EKF mean ATE {:.4f} m <= {:.4f} m\n", ate, args.check_ate_m);
  }
  if (args.check_nees > 0) {
    const double nees = j.contains("ekf_nees") ? j["ekf_nees"]["mean"].get<double>() : 1e300;
    if (!(nees <= args.check_nees)) {
      fmt::print("check FAILED: EKF mean position NEES {:.2f} > {:.2f} (or no truth)\n", nees,
                 args.check_nees);
      return 1;
    }
    fmt::print("check passed: EKF mean position NEES {:.2f} <= {:.2f}\n", nees, args.check_nees);
  }
  if (args.check_along_min > 0) {
    const double a = j.contains("ekf_nees") && j["ekf_nees"].contains("along_track")
                         ? j["ekf_nees"]["along_track"].get<double>()
                         : -1.0;
    if (!(a >= args.check_along_min)) {
      fmt::print("check FAILED: EKF along-track NEES {:.2f} < {:.2f} (or no truth)\n", a,
                 args.check_along_min);
      return 1;
    }
    fmt::print("check passed: EKF along-track NEES {:.2f} >= {:.2f}\n", a, args.check_along_min);
  }
  return 0;
}
