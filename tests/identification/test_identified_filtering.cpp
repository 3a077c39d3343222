// Issue 5, last check: "Filtering with the identified configuration is at least as good as with
// the nominal one on a different recording of the same vehicle" (docs/identification.md, 8).
//
// A truth vehicle that differs from the nominal configuration (gearbox efficiency, yaw
// inertia, motor viscous friction, a heavier passenger) drives the exciting scenario in the
// project's truth simulator (`wheelchair simulate --config truth.ini`); `wheelchair identify
// --write-config` identifies it with the nominal configuration as input. OTHER drives of the
// same vehicle (other scenarios, other seeds) are then filtered by the physics CD-EKF with the
// nominal and with the identified configuration, and the estimates are compared with the
// simulator's truth: velocity states v, omega (RMSE) and the pose (RMSE of the position,
// start frame), plus the encoders' and gyro's mean NIS. Needs the `wheelchair` program.
#include "../common/TestUtil.h"

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/estimation/EkfOptions.h"
#include "libwheelchair/estimation/Estimator.h"
#include "libwheelchair/simulation/Simulator.h"

#include <fmt/core.h>
#include <fmt/ranges.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <vector>

using namespace wheelchair;

namespace {

struct FilterErrors {
  double v_rmse = 0, omega_rmse = 0, pos_rmse = 0, nis_enc = 0, nis_gyro = 0;
  /// Position RMSE of the same configuration's filter with learn_healthy_encoder_scales =
  /// none (= pos_rmse when the configuration does not learn its radii).
  double pos_rmse_fixed_radii = 0;
};

/// EKF estimates against the simulator's truth (linear interpolation at the estimate times);
/// `learn_radii` false: the configuration's filter with learn_healthy_encoder_scales = none.
FilterErrors filterErrors(const simulation::SimulationResult& sim,
                          const config::WheelchairConfig& cfg, bool learn_radii = true) {
  estimation::EkfOptions opt;
  opt.loadFromConfig(cfg.ini(), "estimator");
  opt.filter = estimation::FilterKind::Physics;
  if (!learn_radii) opt.learn_healthy_encoder_scales = estimation::HealthyScaleLearning::None;
  const auto res = estimation::runEstimator(sim.recording, cfg, opt);
  const auto& tr = sim.truth.samples;
  double sv = 0, sw = 0, sp = 0;
  std::size_t n = 0, k = 1;
  for (const auto& e : res.estimates) {
    while (k + 1 < tr.size() && tr[k].t_s < e.t_s) ++k;
    if (e.t_s < tr.front().t_s || e.t_s > tr.back().t_s) continue;
    const auto &a = tr[k - 1], &b = tr[k];
    const double f = b.t_s > a.t_s ? std::clamp((e.t_s - a.t_s) / (b.t_s - a.t_s), 0.0, 1.0) : 0;
    auto lerp = [&](double x0, double x1) { return x0 + f * (x1 - x0); };
    sv += std::pow(e.x(0) - lerp(a.v_m_s, b.v_m_s), 2);
    sw += std::pow(e.x(1) - lerp(a.omega_rad_s, b.omega_rad_s), 2);
    sp += std::pow(e.x(2) - lerp(a.x_m, b.x_m), 2) + std::pow(e.x(3) - lerp(a.y_m, b.y_m), 2);
    ++n;
  }
  FilterErrors out;
  if (n == 0) return out;
  out.v_rmse = std::sqrt(sv / n);
  out.omega_rmse = std::sqrt(sw / n);
  out.pos_rmse = std::sqrt(sp / n);
  out.nis_enc = res.stats(estimation::Sensor::Encoders).meanNis();
  out.nis_gyro = res.stats(estimation::Sensor::Gyro).meanNis();
  return out;
}

struct Drive {
  const char* scenario;
  uint64_t seed;
};

struct Comparison {
  std::vector<std::pair<FilterErrors, FilterErrors>> runs;  ///< (nominal, identified) per drive
  std::string table;
};

/// Both position figures: the configured filter's, and with the radii held (learning off).
FilterErrors filterErrorsBoth(const simulation::SimulationResult& sim,
                              const config::WheelchairConfig& cfg) {
  auto e = filterErrors(sim, cfg);
  estimation::EkfOptions opt;
  opt.loadFromConfig(cfg.ini(), "estimator");
  e.pos_rmse_fixed_radii =
      opt.learn_healthy_encoder_scales == estimation::HealthyScaleLearning::None
          ? e.pos_rmse
          : filterErrors(sim, cfg, false).pos_rmse;
  return e;
}

/// Simulates the truth vehicle's exciting drive, identifies it through the CLI (nominal
/// configuration as input, --write-config) unless `given` is an "identified" configuration to
/// judge instead, then filters other drives with both configurations.
Comparison compare(const config::WheelchairConfig& truth, const std::vector<Drive>& drives,
                   const test::TempDir& dir, const config::WheelchairConfig* given = nullptr) {
  Comparison c;
  const std::string nominal_ini = test::sourcePath("config/wheelchair.ini");
  const auto nominal = config::WheelchairConfig::load(nominal_ini);
  auto identified = nominal;
  if (given) {
    identified = *given;
  } else {
    truth.save(dir / "truth.ini");
    const std::string excite = dir / "excite.rawlog";
    const auto sim = test::cli("simulate --scenario excite --seed 4 --duration 120 --config " +
                               (dir / "truth.ini") + " -o " + excite);
    EXPECT_EQ(sim.exit_code, 0) << sim.out;
    const auto id = test::cli("identify " + excite + " --config " + nominal_ini + " --json " +
                              (dir / "id.json") + " --write-config " + (dir / "id.ini"));
    EXPECT_EQ(id.exit_code, 0) << id.out;
    if (sim.exit_code != 0 || id.exit_code != 0) return c;
    identified = config::WheelchairConfig::load(dir / "id.ini");
  }
  simulation::SimulationOptions so;
  so.loadFromConfig(truth.ini(), "simulation");
  c.table = fmt::format(
      "| drive | config | v RMSE (m/s) | omega RMSE (rad/s) | position RMSE (m) | position RMSE, "
      "radii held (m) | mean NIS encoders | mean NIS gyro "
      "|\n|---|---|---:|---:|---:|---:|---:|---:|\n");
  for (const Drive& d : drives) {
    const auto s = simulation::simulate(truth, d.scenario, d.seed, 0, {}, so);
    const auto en = filterErrorsBoth(s, nominal), ei = filterErrorsBoth(s, identified);
    for (auto [name, e] : {std::pair{"nominal", en}, std::pair{"identified", ei}})
      c.table +=
          fmt::format("| {} seed {} | {} | {:.6f} | {:.6f} | {:.6f} | {:.6f} | {:.4f} | {:.4f} |\n",
                      d.scenario, d.seed, name, e.v_rmse, e.omega_rmse, e.pos_rmse,
                      e.pos_rmse_fixed_radii, e.nis_enc, e.nis_gyro);
    c.runs.push_back({en, ei});
  }
  std::printf("%s", c.table.c_str());
  return c;
}

double mean(const std::vector<std::pair<FilterErrors, FilterErrors>>& runs, bool identified,
            double FilterErrors::*m) {
  double s = 0;
  for (const auto& r : runs) s += (identified ? r.second : r.first).*m;
  return runs.empty() ? 0 : s / runs.size();
}

const std::vector<Drive> kDrives{{"three_task", 11}, {"square", 12}, {"excite", 13},
                                 {"three_task", 14}, {"square", 15}, {"excite", 16}};

/// Paired t statistic of identified/nominal - 1 over the drives (> 0: identified worse).
double pairedRelativeT(const std::vector<std::pair<FilterErrors, FilterErrors>>& runs,
                       double FilterErrors::*m) {
  std::vector<double> d;
  for (const auto& [n, i] : runs) d.push_back(i.*m / (n.*m) - 1);
  double mu = 0, ss = 0;
  for (double x : d) mu += x / d.size();
  for (double x : d) ss += (x - mu) * (x - mu);
  const double se = std::sqrt(ss / (d.size() - 1) / d.size());
  return se > 0 ? mu / se : (mu > 0 ? 1e9 : 0);
}

// Issue 5's "at least as good", and what it can assert for a filter that LEARNS its wheel radii
// while it drives (learn_healthy_encoder_scales, issue 17). Tolerances (docs/identification.md,
// 8, has the measured table over 12 drives): the comparison is PAIRED (both configurations
// filter the same recording), because the seed-to-seed spread of the position RMSE (9.3 +- 5.1
// mm over 12 drives) dwarfs any effect of the model. The paired relative differences
// identified/nominal - 1 measured with the radii held:
//   v      -15.6 % +- 2.4 % (all 12 drives better, worst -12.9 %)
//   omega   -1.5 % +- 1.3 % (all better, worst -0.2 %)
//   pos    +0.05 % +- 0.29 % (both signs, worst +0.8 %: the position is set by the encoder,
//          gyro and Pozyx updates; the dynamics only shape the prediction between them)
//   NIS    encoders -5.6 % +- 0.9 %, gyro -6.7 % +- 4.9 % (all lower)
// "No worse" allows +2 % per drive (about 7 standard deviations of the paired position
// difference, 2.5 x its worst case) and +0.5 % on the mean over drives; position +3 % per drive
// since the closed wheel scales carry their 0.5 % as consider variance (issue 17): the
// encoders' yaw rate weighs less and the heading leans more on the model, measured +2.1 % on
// three_task seed 11 (-0.4 .. +0.7 % on the others, +0.2 % on the mean); "strictly better" on
// v requires -5 % on every drive (4 standard deviations short of the measured mean).
// With the radii LEARNED, the position of one drive moves by -24 .. +18 % against the same
// configuration's filter with the radii held (the learned common scale's path through the
// drive: these truth wheels have exactly the nominal radii), and the paired identified/nominal
// position difference spreads to +2.2 % +- 5.6 % over the six drives (2026-11-25): 20 times the
// dynamics' effect, so the paired position comparison of the learning filters cannot see the
// model. And with a yaw process noise small enough to bring the gyro's NIS towards 1 (the
// manoeuvre-scaled yaw noise, or a constant q_omega <= 0.005), even the vehicle's EXACT
// configuration, given as the "identified" one, is +10 % / +14 % off the nominal's position on
// two drives with the radii held (docs/estimation.md, "Shipping the self-calibrating filter?"):
// single gyro readings gated at the 0.999 level move a drive's position by ~10 %, so per-drive
// position margins judge the gate, not the model. Hence: v, omega and the NIS (where the
// dynamics act) per drive from the filters as configured, with the margins above; the position
// with the radii held (learn_healthy_encoder_scales = none; the same as configured when it is
// none) and as configured each as a paired one-sided t test over the drives (identified not
// worse at the 1 % level: t < t_{0.99, n-1}, 3.36 for six drives).
// Returns the failed checks (empty: at least as good).
std::vector<std::string> notAsGood(const Comparison& c) {
  std::vector<std::string> f;
  auto check = [&](bool ok, const std::string& what) {
    if (!ok) f.push_back(what);
  };
  for (std::size_t k = 0; k < c.runs.size(); ++k) {
    const auto& [n, i] = c.runs[k];
    check(i.v_rmse < 0.95 * n.v_rmse, fmt::format("v, drive {}", k));  // strictly better
    check(i.omega_rmse <= 1.02 * n.omega_rmse, fmt::format("omega, drive {}", k));
    check(i.nis_enc <= 1.02 * n.nis_enc, fmt::format("NIS encoders, drive {}", k));
    check(i.nis_gyro <= 1.02 * n.nis_gyro, fmt::format("NIS gyro, drive {}", k));
  }
  check(mean(c.runs, true, &FilterErrors::omega_rmse) <
            mean(c.runs, false, &FilterErrors::omega_rmse),
        "mean omega");
  check(pairedRelativeT(c.runs, &FilterErrors::pos_rmse_fixed_radii) < 3.36,
        "position (radii held), paired t");
  check(pairedRelativeT(c.runs, &FilterErrors::pos_rmse) < 3.36, "position, paired t");
  return f;
}

// The vehicle as it really is: less efficient gearbox, more yaw inertia and viscous friction, a
// heavier passenger: a1 -21 %, a2 -31 %, a3 +9 %, a4 -5 % from the nominal ones.
config::WheelchairConfig differentVehicle() {
  auto truth = config::WheelchairConfig::load(test::sourcePath("config/wheelchair.ini"));
  truth.vehicle.gearbox_efficiency = 0.75;        // nominal 0.85
  truth.vehicle.yaw_inertia_kg_m2 = 11.0;         // nominal 8.0
  truth.vehicle.motor_viscous_Nm_s_rad = 3.2e-3;  // nominal 2.3e-3
  truth.vehicle.geom.body_mass_kg += 20.0;        // nominal 130 kg
  truth.syncToIni();
  return truth;
}

}  // namespace

TEST(IdentifiedFiltering, DifferentVehicleIdentifiedConfigFiltersBetter) {
  if (!std::filesystem::exists(WHEELCHAIR_CLI)) GTEST_SKIP() << WHEELCHAIR_CLI << " not built";
  test::TempDir dir;
  const auto c = compare(differentVehicle(), kDrives, dir);
  ASSERT_EQ(c.runs.size(), kDrives.size());
  const auto failed = notAsGood(c);
  EXPECT_TRUE(failed.empty()) << fmt::format("{}", fmt::join(failed, "; "));
}

// The check can fail: an "identified" configuration wrong in the other direction from the
// nominal one (gearbox efficiency 0.95 and yaw inertia 6 kg m^2 where the vehicle has 0.75 and
// 11, the nominal 0.85 and 8) is judged on the same drives and must not pass as at least as
// good. (Gearbox efficiency 0.6 does pass, with the radii learned or held: a1 -29 % from the
// nominal is nearer the heavier vehicle's -21 % than the nominal's 0 %, so it IS better.)
TEST(IdentifiedFiltering, AWronglyIdentifiedConfigIsNotAsGood) {
  test::TempDir dir;
  auto wrong = config::WheelchairConfig::load(test::sourcePath("config/wheelchair.ini"));
  wrong.vehicle.gearbox_efficiency = 0.95;
  wrong.vehicle.yaw_inertia_kg_m2 = 6.0;
  wrong.syncToIni();
  const auto c = compare(differentVehicle(), kDrives, dir, &wrong);
  ASSERT_EQ(c.runs.size(), kDrives.size());
  const auto failed = notAsGood(c);
  std::printf("failed checks: %s\n", fmt::format("{}", fmt::join(failed, "; ")).c_str());
  EXPECT_FALSE(failed.empty());
}

// The null case: the vehicle IS the nominal one; identifying it must not make filtering worse.
TEST(IdentifiedFiltering, NominalVehicleIdentifiedConfigIsNoWorse) {
  if (!std::filesystem::exists(WHEELCHAIR_CLI)) GTEST_SKIP() << WHEELCHAIR_CLI << " not built";
  test::TempDir dir;
  const auto truth = config::WheelchairConfig::load(test::sourcePath("config/wheelchair.ini"));
  const auto c = compare(truth, {kDrives.begin(), kDrives.begin() + 3}, dir);
  ASSERT_EQ(c.runs.size(), 3u);
  for (std::size_t k = 0; k < c.runs.size(); ++k) {
    const auto& [n, i] = c.runs[k];
    EXPECT_LE(i.v_rmse, 1.02 * n.v_rmse) << k;
    EXPECT_LE(i.omega_rmse, 1.02 * n.omega_rmse) << k;
    EXPECT_LE(i.pos_rmse, 1.02 * n.pos_rmse) << k;
  }
}
