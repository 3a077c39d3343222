// Identification on simulated drives with known parameters (DriveGenerator.h: DriveTrain +
// sensor forward models, realistic noise, jittered asynchronous sampling). The truth vehicle
// differs from the nominal configuration the identification is given, so nothing is
// recovered "by default". test_cli_identify.cpp repeats the key checks with the project's
// truth simulator (through `wheelchair simulate`).
#include "DriveGenerator.h"

#include "libwheelchair/identification/Identification.h"
#include "libwheelchair/model/VehicleParams.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

using namespace wheelchair;
using identification::Estimate;
using identification::IdentificationOptions;
using identification::IdentificationResult;

namespace {

// Truth: the nominal chair with a heavier yaw inertia, more viscous friction, a different
// gearbox efficiency (all unknown to the identification, which gets the nominal config).
config::WheelchairConfig truthConfig() {
  config::WheelchairConfig c;
  c.vehicle.yaw_inertia_kg_m2 = 9.5;
  c.vehicle.motor_viscous_Nm_s_rad = 2.8e-3;
  c.vehicle.gearbox_efficiency = 0.8;
  c.syncToIni();
  return c;
}

struct Truth {
  double theta5, D1, D2;
  model::OdeCoefficients a;
};

Truth truthOf(const config::WheelchairConfig& c) {
  const auto th = model::lumpedTheta(c.vehicle);
  return {th(4), identification::d1Weights(c.vehicle.geom).dot(th),
          identification::d2Weights(c.vehicle.geom).dot(th),
          model::odeCoefficients(c.vehicle.geom, th)};
}

io::Recording sim(const config::WheelchairConfig& c, bool exciting, uint64_t seed, double dur,
                  const std::function<void(model::DriveTrain&)>& modify = {}) {
  model::DriveTrain dt = model::DriveTrain::symmetric(c.vehicle);
  if (modify) modify(dt);
  test::GeneratorOptions go;
  go.duration_s = dur;
  go.seed = seed;
  return test::generateDrive(c, dt, exciting ? test::excitingDemand(seed) : test::straightDemand(),
                             go);
}

struct Check {
  int n = 0, covered = 0;
  double worst_rel = 0;
  void add(const char* name, const Estimate& e, double truth, uint64_t seed) {
    ASSERT_TRUE(e.identifiable) << name << ": " << e.reason;
    const double err = e.value - truth;
    const double rel = std::abs(err / truth);
    worst_rel = std::max(worst_rel, rel);
    EXPECT_LT(rel, 0.03) << name << " seed " << seed << ": " << e.value << " vs truth " << truth;
    ++n;
    covered += std::abs(err) < 1.96 * e.se;
    std::printf(
        "  seed %2lu %-12s est %-11.5g truth %-11.5g err %+6.2f %%  se %5.2f %%  "
        "|err|/se %.2f\n",
        (unsigned long)seed, name, e.value, truth, 100 * err / truth, 100 * e.se / std::abs(truth),
        std::abs(err) / e.se);
  }
};

}  // namespace

// Exciting drives, several seeds: theta_5, D1, D2 and a1..a4 (from theta and direct) within
// 3 %, and the +-1.96 se intervals cover the truth at a plausible rate.
TEST(IdentifySim, ExcitingDriveRecoversParametersWithCoveringErrors) {
  const auto tc = truthConfig();
  const Truth tr = truthOf(tc);
  const config::WheelchairConfig nominal;  // what the identification is told
  IdentificationOptions opt;
  Check chk;
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    const auto rec = sim(tc, true, seed, 120);
    const auto res = identification::identify({rec}, nominal, opt, {"excite"});
    std::printf(
        "seed %lu: used %zu samples, cond(scaled) full %.3g, identifiable %.3g, rank %d, "
        "n_eff/n %.3f, omegadot SNR %.0f\n",
        (unsigned long)seed, res.n_used, res.theta_regression.condition_number,
        res.theta_regression.condition_number_identifiable, res.theta_regression.rank,
        res.theta_regression.residual.n_effective / double(res.theta_regression.residual.n_rows),
        res.excitation[3].snr);
    EXPECT_EQ(res.theta_regression.rank, 3);
    EXPECT_EQ(res.null_directions.size(), 2u);
    for (int j = 0; j < 4; ++j) EXPECT_FALSE(res.theta[j].identifiable) << j;
    chk.add("theta_5", res.theta[4], tr.theta5, seed);
    chk.add("D1", res.D1, tr.D1, seed);
    chk.add("D2", res.D2, tr.D2, seed);
    const double ta[4] = {tr.a.a1, tr.a.a2, tr.a.a3, tr.a.a4};
    const char* nt[4] = {"a1", "a2", "a3", "a4"};
    const char* nd[4] = {"a1 direct", "a2 direct", "a3 direct", "a4 direct"};
    for (int k = 0; k < 4; ++k) chk.add(nt[k], res.a_from_theta[k], ta[k], seed);
    for (int k = 0; k < 4; ++k) chk.add(nd[k], res.a_direct[k], ta[k], seed);
  }
  const double frac = double(chk.covered) / chk.n;
  std::printf("coverage of +-1.96 se: %d / %d = %.2f; worst relative error %.2f %%\n", chk.covered,
              chk.n, frac, 100 * chk.worst_rel);
  EXPECT_GE(frac, 0.75);
}

// A drive that only goes straight (three stop-and-go runs): the yaw
// parameters are reported as not identifiable, never as numbers.
TEST(IdentifySim, StraightDriveReportsYawParametersNotIdentifiable) {
  const auto tc = truthConfig();
  const Truth tr = truthOf(tc);
  const auto rec = sim(tc, false, 3, 60);
  const auto res = identification::identify({rec}, config::WheelchairConfig(), {}, {"straight"});
  EXPECT_FALSE(res.excitation[3].excited) << "omegadot SNR " << res.excitation[3].snr;
  EXPECT_FALSE(res.D2.identifiable);
  EXPECT_FALSE(res.theta[3].identifiable);
  EXPECT_FALSE(res.a_from_theta[1].identifiable);
  EXPECT_FALSE(res.a_from_theta[3].identifiable);
  EXPECT_FALSE(res.a_direct[1].identifiable);
  EXPECT_FALSE(res.a_direct[3].identifiable);
  EXPECT_NE(res.theta[3].reason.find("angular acceleration"), std::string::npos)
      << res.theta[3].reason;
  const auto j = res.toJson();
  EXPECT_TRUE(j["theta"]["theta_4"]["value"].is_null());
  EXPECT_TRUE(j["ode"]["from_theta"]["a2"]["value"].is_null());
  EXPECT_FALSE(j["ode"]["from_theta"]["a2"]["reason"].get<std::string>().empty());
  bool yaw_direction = false;
  for (const auto& nd : res.null_directions)
    yaw_direction = yaw_direction || nd.description.find("yaw") != std::string::npos ||
                    nd.description.find("angular acceleration") != std::string::npos;
  EXPECT_TRUE(yaw_direction);
  // The straight-line quantities still come back.
  ASSERT_TRUE(res.D1.identifiable) << res.D1.reason;
  ASSERT_TRUE(res.theta[4].identifiable) << res.theta[4].reason;
  std::printf(
      "straight: D1 %.4g (truth %.4g, se %.2g), theta_5 %.4g (truth %.4g, se %.2g), "
      "omegadot SNR %.2f, rank %d\n",
      res.D1.value, tr.D1, res.D1.se, res.theta[4].value, tr.theta5, res.theta[4].se,
      res.excitation[3].snr, res.theta_regression.rank);
  EXPECT_NEAR(res.D1.value, tr.D1, 0.05 * tr.D1);
  EXPECT_NEAR(res.theta[4].value, tr.theta5, 0.05 * tr.theta5);
}

// One motor's k_m 10 % larger (and its viscous friction 10 % larger): the per-motor constants
// see the difference.
TEST(IdentifySim, PerMotorConstantsSeeTenPercentDifference) {
  auto tc = truthConfig();
  const double k = tc.vehicle.torque_constant_Nm_A;
  const auto rec = sim(tc, false, 11, 60, [](model::DriveTrain& d) {
    d.side[0].torque_constant_Nm_A *= 1.1;
    d.side[0].motor_viscous_Nm_s_rad *= 1.1;
  });
  const auto res = identification::identify({rec}, config::WheelchairConfig(), {}, {"straight"});
  const auto& R = res.motor[0];
  const auto& L = res.motor[1];
  ASSERT_TRUE(R.back_emf_k.identifiable) << R.back_emf_k.reason;
  ASSERT_TRUE(L.back_emf_k.identifiable) << L.back_emf_k.reason;
  std::printf(
      "segments %zu (right %d, left %d); back-EMF k right %.5f left %.5f (truth %.5f, "
      "%.5f), ratio %.4f; k/eta right %.5f left %.5f\n",
      res.segments.size(), R.n_segments, L.n_segments, R.back_emf_k.value, L.back_emf_k.value,
      1.1 * k, k, R.back_emf_k.value / L.back_emf_k.value, R.k_over_eta.value, L.k_over_eta.value);
  EXPECT_NEAR(R.back_emf_k.value, 1.1 * k, 0.02 * k);
  EXPECT_NEAR(L.back_emf_k.value, k, 0.02 * k);
  EXPECT_NEAR(R.back_emf_k.value / L.back_emf_k.value, 1.1, 0.02);
  // eq. (4): k/eta = U/omega_m >= k (it includes the R_m i losses); same asymmetry.
  ASSERT_TRUE(R.k_over_eta.identifiable && L.k_over_eta.identifiable);
  EXPECT_GT(R.k_over_eta.value, R.back_emf_k.value);
  EXPECT_GT(L.k_over_eta.value, L.back_emf_k.value);
  EXPECT_GT(R.k_over_eta.value / L.k_over_eta.value, 1.05);
}

TEST(IdentifySim, PerSideRegressionSeesFrictionAsymmetry) {
  const auto tc = truthConfig();
  const Truth tr = truthOf(tc);
  const auto rec =
      sim(tc, true, 21, 120, [](model::DriveTrain& d) { d.side[1].motor_viscous_Nm_s_rad *= 1.1; });
  const auto res = identification::identify({rec}, config::WheelchairConfig(), {}, {"x"});
  const auto& R = res.motor[0].theta5;
  const auto& L = res.motor[1].theta5;
  ASSERT_TRUE(R.identifiable && L.identifiable);
  std::printf("per-side theta_5: right %.5g +- %.2g, left %.5g +- %.2g (truth %.5g, %.5g)\n",
              R.value, R.se, L.value, L.se, tr.theta5, 1.1 * tr.theta5);
  EXPECT_NEAR(R.value, tr.theta5, 0.03 * tr.theta5);
  EXPECT_NEAR(L.value, 1.1 * tr.theta5, 0.03 * tr.theta5);
}

// The written configuration reproduces the identified a1..a4 through the model's own
// Appendix formulas, and keeps geometry and masses.
TEST(IdentifySim, WrittenConfigReproducesIdentifiedCoefficients) {
  const auto tc = truthConfig();
  const Truth tr = truthOf(tc);
  const auto rec = sim(tc, true, 5, 120);
  const config::WheelchairConfig nominal;
  const auto res = identification::identify({rec}, nominal, {}, {"x"});
  std::vector<std::string> changes;
  const auto out = identification::identifiedConfig(nominal, res, &changes);
  for (const auto& c : changes) std::printf("  %s\n", c.c_str());
  const auto a = model::odeCoefficients(out.vehicle.geom, model::lumpedTheta(out.vehicle));
  EXPECT_NEAR(a.a1, res.a_from_theta[0].value, 1e-9);
  EXPECT_NEAR(a.a2, res.a_from_theta[1].value, 1e-9);
  EXPECT_NEAR(a.a3, res.a_from_theta[2].value, 1e-9);
  EXPECT_NEAR(a.a4, res.a_from_theta[3].value, 1e-9);
  EXPECT_NEAR(a.a2, tr.a.a2, 0.03 * tr.a.a2);
  EXPECT_EQ(out.vehicle.geom.body_mass_kg, nominal.vehicle.geom.body_mass_kg);
  EXPECT_EQ(out.vehicle.motor_inertia_kg_m2, nominal.vehicle.motor_inertia_kg_m2);
  EXPECT_NEAR(out.vehicle.yaw_inertia_kg_m2, 9.5, 0.1 * 9.5);
  EXPECT_NEAR(out.vehicle.torque_constant_Nm_A, 0.09, 0.02 * 0.09);
  EXPECT_NEAR(out.ini().read_double("identified", "a1", 0), a.a1, 1e-6 * a.a1);
  // Round trip through text.
  const auto back = config::WheelchairConfig::fromText(out.text(), "round trip");
  EXPECT_NEAR(back.vehicle.yaw_inertia_kg_m2, out.vehicle.yaw_inertia_kg_m2,
              1e-9 * out.vehicle.yaw_inertia_kg_m2);
}
