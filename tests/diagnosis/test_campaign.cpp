// A small seeded discovery campaign (the full one: bench/discovery_campaign, docs/discovery.md).
#include "libwheelchair/diagnosis/Campaign.h"
#include "libwheelchair/diagnosis/KinematicCalibration.h"
#include "libwheelchair/simulation/MujocoTruth.h"
#include "libwheelchair/simulation/Simulator.h"
#include "libwheelchair/simulation/UnknownEffects.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <iostream>

using namespace wheelchair;

namespace {

/// A 90-s MuJoCo `excite` drive (seed, concealed effects as "id:key=value" texts) with its
/// ground truth, diagnosed with the shipped configuration and default options.
diagnosis::DiagnosisReport diagnoseMujocoExcite(unsigned seed,
                                                const std::vector<std::string>& effect_texts = {}) {
  const config::WheelchairConfig cfg;
  simulation::SimulationOptions so;
  so.loadFromConfig(cfg.ini());
  so.engine = "mujoco";
  so.record_ground_truth = true;
  std::vector<effects::EffectSpec> fx;
  for (const auto& e : effect_texts) fx.push_back(effects::parseValidEffect(e));
  const auto sim = simulation::simulate(cfg, "excite", seed, 90, fx, so);
  return diagnosis::diagnose({sim.recording}, {}, cfg, diagnosis::DiagnosisOptions{});
}

}  // namespace

TEST(DiagnoseCampaign, SmallSeededCampaign) {
  config::WheelchairConfig cfg;
  diagnosis::CampaignOptions o;
  o.seed = 7;
  o.runs_per_effect = 1;
  o.pair_runs = 2;
  o.clean_runs = 2;
  o.duration_s = 90;
  o.verbose = true;
  diagnosis::DiagnosisOptions d;
  auto res = diagnosis::runCampaign(cfg, o, d);
  std::cout << res["single"].dump() << "\n"
            << res["pairs"].dump() << "\n"
            << res["clean"].dump() << "\n";
  EXPECT_GE(res["single_rate"].get<double>(), 0.75);
  EXPECT_EQ(res["clean"]["false_alarms"].get<int>(), 0);
}

// The scorer's engine truth is measured on the multibody, not taken from the diagnosis: the
// nominal MuJoCo chair rolls about 0.12 % short, its centre of mass is ~6 cm ahead of the
// axle, and only findings that match those numbers (and the right sign per motor) count as
// the engine's physics; the model engine has none.
TEST(DiagnoseCampaign, MujocoEngineTruthScoresOnlyTheEnginesOwnPhysics) {
  const config::WheelchairConfig cfg;
  const simulation::MujocoTruth t = simulation::measureMujocoTruth(cfg, {});
  EXPECT_LT(t.radius_rel_max, -0.0005);
  EXPECT_GT(t.radius_rel_min, -0.002);
  EXPECT_GT(t.track_rel_max, 0.0);
  EXPECT_NEAR(t.mass_moment_kg_m / t.mass_kg, 0.063, 0.01);
  const double k = t.vOmegaCurrentCoefficient(cfg);
  EXPECT_NEAR(k, 2.06, 0.2);  // A per (m/s rad/s): the yaw moment m d v omega per motor
  const nlohmann::json truth = {{"radius_rel", {t.radius_rel_min, t.radius_rel_max}},
                                {"track_rel", {t.track_rel_min, t.track_rel_max}},
                                {"v_omega_A", k},
                                {"omega2_A", t.omegaSquaredCurrentCoefficient(cfg)},
                                {"omegadot_A", t.omegadot_A},
                                {"slope_cos_A", 0.0},
                                {"slope_sin_A", 0.0}};
  diagnosis::Finding g;
  g.effect = diagnosis::kWheelGeometryEffect;
  g.parameters = {{"model", "scale+track"},
                  {"wheel_radius_right_rel", t.radius_rel_min},
                  {"wheel_radius_left_rel", t.radius_rel_min},
                  {"track_rel", t.track_rel_max}};
  EXPECT_TRUE(diagnosis::engineTruthFinding(g, truth));
  g.parameters["wheel_radius_left_rel"] = 0.004;  // a real 0.4 % wheel: not the engine's
  EXPECT_FALSE(diagnosis::engineTruthFinding(g, truth));
  EXPECT_FALSE(diagnosis::engineTruthFinding(g, nlohmann::json()));  // model engine
  diagnosis::Finding u;
  u.effect = "unmodeled";
  u.parameters = {{"channel", "current_right"}, {"v*omega", 1.1 * k}};
  EXPECT_TRUE(diagnosis::engineTruthFinding(u, truth));
  u.parameters["channel"] = "current_left";  // the left motor's term has the other sign
  EXPECT_FALSE(diagnosis::engineTruthFinding(u, truth));
  u.parameters["v*omega"] = -k;
  EXPECT_TRUE(diagnosis::engineTruthFinding(u, truth));
  u.parameters["omegadot"] = -t.omegadot_A;  // the yaw-inertia term, left motor: opposite sign
  EXPECT_TRUE(diagnosis::engineTruthFinding(u, truth));
  u.parameters["omegadot"] = t.omegadot_A;
  EXPECT_FALSE(diagnosis::engineTruthFinding(u, truth));
  u.parameters["omegadot"] = -t.omegadot_A;
  u.parameters["i_other"] = 0.5;  // a term the engine truth does not contain
  EXPECT_FALSE(diagnosis::engineTruthFinding(u, truth));
  u.parameters = {{"channel", "gyro_vs_encoders"}, {"v*omega", -k}};
  EXPECT_FALSE(diagnosis::engineTruthFinding(u, truth));
}

// An acceleration term (`vdot`, `omegadot`) is the engine's only against the term the
// multibody realises in the drive's own motion, per motor (Campaign.cpp
// realisedAccelerationTerms: MuJoCo against its model-engine twin; clean `square`: vdot
// +0.052, omegadot +0.116 right / -0.052 left), never the step from rest (vdot +0.005), and a
// vdot term never without that measurement.
TEST(DiagnoseCampaign, AccelerationTermsAreScoredAgainstTheDrivesRealisedValues) {
  nlohmann::json truth = {{"radius_rel", {-0.00127, -0.00126}},
                          {"track_rel", {0.0005, 0.0035}},
                          {"v_omega_A", 2.06},
                          {"omega2_A", -0.567},
                          {"omegadot_A", 0.071},
                          {"vdot_A", 0.005},
                          {"slope_cos_A", 0.0},
                          {"slope_sin_A", 0.0}};
  diagnosis::Finding u;
  u.effect = "unmodeled";
  u.parameters = {{"channel", "current_left"}, {"omega^2", -0.55}, {"vdot", 0.055}};
  EXPECT_FALSE(diagnosis::engineTruthFinding(u, truth));  // not measured: an extra
  truth["vdot_in_drive_A"] = {0.052, 0.052};
  truth["omegadot_in_drive_A"] = {0.116, -0.052};
  EXPECT_TRUE(diagnosis::engineTruthFinding(u, truth));
  u.parameters["channel"] = "current_right";
  EXPECT_TRUE(diagnosis::engineTruthFinding(u, truth));
  u.parameters["vdot"] = 0.072;  // 38 % above the realised value
  EXPECT_FALSE(diagnosis::engineTruthFinding(u, truth));
  // the right motor's omegadot on a `square` drive: 0.127 (the step from rest: 0.071)
  u.parameters = {{"channel", "current_right"}, {"omega^2", -0.49}, {"omegadot", 0.127}};
  EXPECT_TRUE(diagnosis::engineTruthFinding(u, truth));
  truth.erase("omegadot_in_drive_A");
  EXPECT_FALSE(diagnosis::engineTruthFinding(u, truth));
  truth["omegadot_in_drive_A"] = {0.116, -0.052};
  u.parameters = {{"channel", "current_left"}, {"omega^2", -0.55}, {"omegadot", -0.127}};
  EXPECT_FALSE(diagnosis::engineTruthFinding(u, truth));  // the left motor realises -0.052
}

// On a clean MuJoCo drive the chassis' yaw trails its wheels by ~2.5 ms (tyre creep): shorter
// than one gyro sample, it is stated as undecidable, not named a sensor delay; a concealed
// 50 ms gyro delay on the same engine is still named.
TEST(DiagnoseCampaign, MujocoSubSampleGyroLagIsNotNamedARealDelayIs) {
  auto delays = [](const diagnosis::DiagnosisReport& rep) {
    int n = 0;
    for (const auto& f : rep.findings) n += f.effect == "sensor_delay";
    return n;
  };
  const auto rc = diagnoseMujocoExcite(580752);
  EXPECT_EQ(delays(rc), 0);
  ASSERT_TRUE(rc.info.contains("cannot_tell")) << rc.info.dump();
  EXPECT_NE(rc.info["cannot_tell"][0].get<std::string>().find("sample period"), std::string::npos);
  const auto rl = diagnoseMujocoExcite(580752, {"sensor_delay:sensor=imu,delay_s=0.05"});
  ASSERT_EQ(delays(rl), 1);
  for (const auto& f : rl.findings)
    if (f.effect == "sensor_delay")
      EXPECT_NEAR(f.parameters["delay_s"].get<double>(), 0.05, 0.0125);
}

// The acceptance gates of `unmodeled` terms on a MuJoCo drive with concealed Coulomb friction
// (issue 16): the multibody's stiction-like friction leaves a sgn(u) term beyond the
// catalogue's tanh on the left motor, and a vdot term (+0.09 A s^2/m) whose held-out
// contribution is below the structure the model still leaves unexplained. Neither is a new
// `unmodeled` finding: a sgn(u) is the friction's shape (in the Coulomb finding), a vdot below
// the unexplained structure is stated as undecidable; the centre-of-mass terms are reported.
TEST(DiagnoseCampaign, MujocoFrictionShapeAndTermsBelowMisspecificationAreNotFindings) {
  const auto rep = diagnoseMujocoExcite(939493, {"coulomb_friction:current_A=0.311229"});
  const diagnosis::Finding* friction = rep.find("coulomb_friction");
  ASSERT_NE(friction, nullptr);
  // Fitted jointly with the centre-of-mass terms (jointDynamicFit) the catalogue term takes
  // the stiction; a sgn(u) left beyond it belongs to the friction law's shape, never to an
  // `unmodeled` finding (checked below).
  if (friction->evidence.contains("friction_shape"))
    EXPECT_NE(friction->description.find("shape of the friction law"), std::string::npos);
  int com_terms = 0;
  for (const auto& f : rep.findings) {
    if (f.effect != "unmodeled") continue;
    for (const char* t : {"1", "sgn(u)", "|u|", "u^2", "vdot"})
      EXPECT_FALSE(f.parameters.contains(t)) << t << " in " << f.parameters.dump();
    com_terms += f.parameters.contains("v*omega");
  }
  // The centre of mass ahead of the axle: after the merge of the joint catalogue fit
  // (jointDynamicFit) only the right motor's v*omega survives the gates on this drive (the
  // left one did before); the vdot term no longer appears at all (neither as a finding nor in
  // info.cannot_tell).
  EXPECT_GE(com_terms, 1);
}

// Coulomb friction on a MuJoCo drive (stiction constraint on the wheel joints; the chassis'
// centre of mass 6 cm ahead of the axle costs -0.57 A omega^2 on both motors, which model (6)
// lacks). Fitted alone the catalogue term absorbed part of the omega^2 current (0.392 A for
// 0.443 A) and the rest came out as an `unmodeled` sgn(u); fitted jointly with the
// out-of-catalogue terms it is within 7.5 % and those terms are the centre of mass' own.
TEST(DiagnoseCampaign, MujocoCoulombFrictionFittedJointlyWithTheCentreOfMassTerms) {
  const auto rep = diagnoseMujocoExcite(309517, {"coulomb_friction:current_A=0.443344"});
  int coulomb = 0, other = 0;
  for (const auto& f : rep.findings) {
    if (f.effect == "coulomb_friction") {
      ++coulomb;
      // Alone the catalogue term read 0.392 A (11.6 % low); jointly 0.419 A (5.5 % low) once
      // the acceptance gates (heldOutPrune, belowMisspecification) leave one centre-of-mass
      // term out of the joint fit.
      EXPECT_NEAR(f.parameters["current_A"].get<double>(), 0.443344, 0.075 * 0.443344);
    } else if (f.effect == "unmodeled") {
      EXPECT_FALSE(f.parameters.contains("sgn(u)")) << f.description;
      EXPECT_TRUE(f.parameters.contains("v*omega")) << f.description;
    } else if (f.effect != "wheel_geometry") {
      ++other;
    }
  }
  EXPECT_EQ(coulomb, 1);
  EXPECT_EQ(other, 0);
}

// The unmodeled-term library is not a basis (u^2 = v^2 +- l_w v omega + l_w^2 omega^2 / 4 per
// motor, v*|v| = v^2 while driving forward). On the clean MuJoCo drive 891441 the sparse search
// ended with the centre of mass' current as +3.56 u^2 -3.48 v*|v| -0.78 omega^2 on both motors
// (two nearly collinear columns with large opposite coefficients, not the engine's physics);
// preferring the same structure in fewer terms (sparserEquivalent) gives the engine truth's
// terms: v*omega (+2.06 right, -2.06 left) and omega^2 (-0.57), each within 25 %.
TEST(DiagnoseCampaign, MujocoCentreOfMassCurrentInItsFewestTerms) {
  const auto rep = diagnoseMujocoExcite(891441);
  int com = 0;
  for (const auto& f : rep.findings) {
    ASSERT_EQ(f.effect, "unmodeled") << f.description;
    for (const char* t : {"u^2", "v*|v|"})
      EXPECT_FALSE(f.parameters.contains(t)) << t << " in " << f.parameters.dump();
    if (!f.parameters.contains("v*omega")) continue;
    ++com;
    const double sign = f.parameters["channel"] == "current_right" ? 1.0 : -1.0;
    EXPECT_NEAR(f.parameters["v*omega"].get<double>(), sign * 2.06, 0.25 * 2.06);
  }
  EXPECT_EQ(com, 2);
}

// The centre of mass' turn across a slope is one heading-dependent current A sin(h - phi) per
// motor: cos(phi) and sin(phi) together (amplitude and phase). On this MuJoCo slope drive (1.73
// deg, downhill heading 84.75 deg) the sparse search dropped sin(phi) alone and kept cos(phi)
// -0.572 with a u^2 +0.816 on the right motor (not the engine's physics; slope error 7.1 %);
// thresholded and pruned as one term, both halves stay, the u^2 goes, and the slope is within 1 %.
TEST(DiagnoseCampaign, MujocoSlopeHeadingTermKeepsItsPhase) {
  const auto rep =
      diagnoseMujocoExcite(599833, {"ground_slope:angle_deg=1.73202,downhill_heading_deg=84.7509"});
  const diagnosis::Finding* slope = rep.find("ground_slope");
  ASSERT_NE(slope, nullptr);
  EXPECT_NEAR(slope->parameters["angle_deg"].get<double>(), 1.73202, 0.03 * 1.73202);
  for (const auto& f : rep.findings) {
    if (f.effect != "unmodeled") continue;
    EXPECT_EQ(f.parameters.contains("cos(phi)"), f.parameters.contains("sin(phi)"))
        << f.parameters.dump();
    EXPECT_FALSE(f.parameters.contains("u^2")) << f.parameters.dump();
  }
}

// A gyro delay on a `square` drive (model engine: no physics beyond the model). The held-out
// last 30 % of the drive is a straight side without turns: with the gyro's single samples as
// the delay regressor their noise made the held-out part look able to test the delay (predicted
// gain 23 > 9) while the realised gain was negative, and a 43 ms delay was rejected. With the
// gyro averaged over +-one window at each end that stretch is seen as not testing it.
TEST(DiagnoseCampaign, GyroDelayOnSquareDriveIsNamed) {
  const config::WheelchairConfig cfg;
  simulation::SimulationOptions so;
  so.loadFromConfig(cfg.ini());
  so.record_ground_truth = true;
  const auto sim = simulation::simulate(
      cfg, "square", 824834, 0,
      {effects::parseValidEffect("sensor_delay:sensor=imu,delay_s=0.0427091")}, so);
  const auto rep = diagnosis::diagnose({sim.recording}, {}, cfg, diagnosis::DiagnosisOptions{});
  const diagnosis::Finding* d = rep.find("sensor_delay");
  ASSERT_NE(d, nullptr) << rep.channels["gyro_vs_encoders"]["rejected_candidates"].dump();
  EXPECT_EQ(d->parameters["sensor"], "imu");
  EXPECT_NEAR(d->parameters["delay_s"].get<double>(), 0.0427091, 0.1 * 0.0427091);
  EXPECT_EQ(rep.findings.size(), 1u);
}

// Exploration: DIAG_RUNS=n DIAG_EFFECTS=a,b ./test_diagnosis --gtest_also_run_disabled_tests
// --gtest_filter=*Explore*
TEST(DiagnoseCampaign, DISABLED_Explore) {
  config::WheelchairConfig cfg;
  diagnosis::CampaignOptions o;
  o.seed = std::getenv("DIAG_SEED") ? std::atoi(std::getenv("DIAG_SEED")) : 1;
  o.runs_per_effect = std::getenv("DIAG_RUNS") ? std::atoi(std::getenv("DIAG_RUNS")) : 3;
  o.pair_runs = std::getenv("DIAG_PAIRS") ? std::atoi(std::getenv("DIAG_PAIRS")) : 0;
  o.clean_runs = std::getenv("DIAG_CLEAN") ? std::atoi(std::getenv("DIAG_CLEAN")) : 0;
  if (std::getenv("DIAG_EFFECTS")) {
    o.effects.clear();
    std::string s = std::getenv("DIAG_EFFECTS");
    for (size_t a = 0, b; a < s.size(); a = b + 1) {
      b = s.find(',', a);
      if (b == std::string::npos) b = s.size();
      o.effects.push_back(s.substr(a, b - a));
    }
  }
  o.verbose = true;
  diagnosis::DiagnosisOptions d;
  auto res = diagnosis::runCampaign(cfg, o, d);
  res.erase("cases");
  std::cout << res.dump(1) << "\n";
}

// `--unknown-only` (CampaignOptions::unknown_only): the catalogue and clean drives are drawn
// from the random stream but not run, so the unknown drives and their scores are exactly those
// of the full command (docs/discovery.md measures the out-of-catalogue rows this way).
TEST(DiagnoseCampaign, UnknownOnlyRunsTheFullCommandsUnknownDrives) {
  const config::WheelchairConfig cfg;
  diagnosis::CampaignOptions o;
  o.seed = 2024;
  o.runs_per_effect = 1;
  o.pair_runs = 1;
  o.triple_runs = 0;
  o.clean_runs = 1;
  o.unknown_runs = 2;
  o.effects = {"gyro_bias", "payload_mass"};
  o.unknown_effects = [](std::mt19937_64& rng) {
    return std::vector<effects::EffectSpec>{simulation::randomUnknownEffect("model", rng)};
  };
  const diagnosis::DiagnosisOptions d;
  const nlohmann::json full = diagnosis::runCampaign(cfg, o, d);
  o.unknown_only = true;
  const nlohmann::json only = diagnosis::runCampaign(cfg, o, d);
  auto unknownCases = [](const nlohmann::json& r) {
    nlohmann::json u = nlohmann::json::array();
    for (const auto& c : r["cases"])
      if (c["kind"] == "unknown") u.push_back(c);
    return u;
  };
  const nlohmann::json uf = unknownCases(full), uo = unknownCases(only);
  EXPECT_EQ(full["cases"].size(), 2u + 1u + 1u + 2u);  // singles, pair, clean, unknown
  EXPECT_EQ(only["cases"].size(), 2u);                 // only the unknown drives ran
  ASSERT_EQ(uf.size(), 2u);
  ASSERT_EQ(uo.size(), 2u);
  for (std::size_t k = 0; k < uf.size(); ++k) {
    EXPECT_EQ(uf[k]["scenario"], uo[k]["scenario"]);
    EXPECT_EQ(uf[k]["seed"], uo[k]["seed"]);
    EXPECT_EQ(uf[k]["truth"], uo[k]["truth"]);
    EXPECT_EQ(uf[k]["unknown_score"], uo[k]["unknown_score"]);
  }
  EXPECT_EQ(full["unknown"]["described"], only["unknown"]["described"]);
}

TEST(DiagnoseCampaign, MujocoUnknownScoreSetsAsideOnlyTheCentreOfMassReadings) {
  // A centre of mass ahead of the axle costs a forward force -m d omega^2 (the same current on
  // both motors) and a yaw moment m d v omega (opposite currents): those readings are the
  // multibody's own on every MuJoCo drive and are set aside. A YAW omega^2 is not the centre of
  // mass: on a `square` drive, whose turns go one way at one rate, a yaw viscous moment reads
  // as one, ambiguous with omega (MuJoCo square 290234, yaw viscous friction 3.1 N m s/rad).
  const auto truth = std::vector<effects::EffectSpec>{
      effects::parseEffect("yaw_viscous_friction:c_N_m_s_rad=3.107")};
  auto component = [](const std::string& channel, const std::string& term) {
    return nlohmann::json{
        {"channel", channel},
        {"term", term},
        {"dependence", "rate_product"},
        {"ambiguous_with", {{{"channel", channel}, {"dependence", "rate"}, {"term", "omega"}}}}};
  };
  auto findings = [&](const std::string& channel, const std::string& term) {
    return nlohmann::json::array(
        {{{"effect", "unmodeled"}, {"physics", {component(channel, term)}}}});
  };
  const auto yaw = diagnosis::unknownEffectScore(truth, findings("yaw", "omega^2"), "mujoco");
  EXPECT_TRUE(yaw["described"].get<bool>()) << yaw.dump();
  EXPECT_TRUE(yaw["described_in_group"].get<bool>()) << yaw.dump();
  // the centre of mass' own readings, on the forward channel or one motor's current: set aside
  for (const auto& [ch, term] : std::vector<std::pair<std::string, std::string>>{
           {"forward", "omega^2"}, {"yaw", "v*omega"}, {"current_left", "omega^2"}}) {
    const auto s = diagnosis::unknownEffectScore(truth, findings(ch, term), "mujoco");
    EXPECT_FALSE(s["located"].get<bool>()) << ch << " " << term << " " << s.dump();
    EXPECT_TRUE(s["components"].empty()) << s.dump();
  }
  // the model engine has no centre of mass off the axle: nothing is set aside there
  const auto model = diagnosis::unknownEffectScore(truth, findings("yaw", "v*omega"), "model");
  EXPECT_TRUE(model["located"].get<bool>()) << model.dump();
}

// A `wheel_geometry` finding is scored against the geometry the multibody realises in the
// drive itself (Campaign.cpp widenToRealisedGeometry, MujocoTruth.h realisedGeometry) as well
// as at the steady operating points: MuJoCo excite 799554 (a gyro bias) rolls -0.10 % short in
// its own motion (the steady 3 / 6 A drives: -0.127 %), which is what the kinematic
// calibration finds (-0.100 / -0.094 %); it used to be scored a false finding.
TEST(DiagnoseCampaign, MujocoWheelGeometryIsScoredAgainstTheDrivesRealisedGeometry) {
  const config::WheelchairConfig cfg;
  const auto c = diagnosis::runCase(cfg, "excite", 799554, 90,
                                    {effects::parseValidEffect("gyro_bias:bias_rad_s=0.0192724")},
                                    diagnosis::DiagnosisOptions{}, "mujoco");
  ASSERT_TRUE(c.engine_truth.contains("geometry_in_drive")) << c.engine_truth.dump();
  const double r = c.engine_truth["geometry_in_drive"]["radius_rel"].get<double>();
  EXPECT_NEAR(r, -0.0010, 0.0001);
  EXPECT_NEAR(c.engine_truth["radius_rel"][1].get<double>(), r, 1e-12);  // the range's top
  EXPECT_LT(c.engine_truth["radius_rel"][0].get<double>(), -0.0012);     // steady drives kept
  bool geometry = false;
  for (const auto& f : c.findings)
    if (f["effect"] == diagnosis::kWheelGeometryEffect) {
      geometry = true;
      EXPECT_TRUE(f["engine_truth"].get<bool>()) << f.dump();
    }
  EXPECT_TRUE(geometry);
  EXPECT_FALSE(c.false_finding);
  EXPECT_TRUE(c.engine_correct);
}
