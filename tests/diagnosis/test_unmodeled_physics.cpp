// Physics outside the catalogue, located and described (issue 16 item 3; diagnosis/
// UnmodeledPhysics.h, simulation/UnknownEffects.h). Three seeded campaign drives of the model
// engine, each with one effect the diagnosis has no name for, simulated and diagnosed through
// the CLI: the `unmodeled` finding must carry a physics component on the effect's channel with
// its dependence class (the truth the generator states, unknownEffectTruth), the fitted value
// within 10 % of the injected one, a positive held-out gain, and no catalogue name for it.
#include "../common/TestUtil.h"
#include "libwheelchair/effects/Effect.h"
#include "libwheelchair/simulation/UnknownEffects.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <map>
#include <string>

namespace {

using namespace wheelchair;
using wheelchair::test::cli;
using wheelchair::test::readFile;
using wheelchair::test::TempDir;

/// where_excited: diagnose with `[diagnosis] unmodeled_judge_where_excited = true` (the
/// shipped configuration with that one line changed).
nlohmann::json diagnoseWith(const std::string& effect, int seed,
                            const std::string& scenario = "excite --duration 90",
                            bool where_excited = false) {
  const TempDir d;
  const std::string rec = d / "u.rawlog", json = d / "u.json", ini = d / "u.ini";
  const auto sim = cli("simulate --scenario " + scenario + " --seed " + std::to_string(seed) +
                       (effect.empty() ? "" : " --effect " + effect) + " -o " + rec);
  EXPECT_EQ(sim.exit_code, 0) << sim.out;
  std::string config;
  if (where_excited) {
    std::string text = readFile(wheelchair::test::sourcePath("config/wheelchair.ini"));
    // (the shipped default since docs/discovery.md "Out of catalogue: traces, realised laws,
    // where excited"; kept explicit so that these tests do not depend on the default)
    const std::string key = "unmodeled_judge_where_excited = false";
    if (const auto at = text.find(key); at != std::string::npos)
      text.replace(at, key.size(), "unmodeled_judge_where_excited = true");
    EXPECT_NE(text.find("unmodeled_judge_where_excited = true"), std::string::npos);
    wheelchair::test::writeFile(ini, text);
    config = " --config " + ini;
  }
  const auto diag = cli("diagnose " + rec + config + " --no-progress --json " + json);
  EXPECT_EQ(diag.exit_code, 0) << diag.out;
  return nlohmann::json::parse(readFile(json));
}

/// The physics component of an unmodeled finding on the effect's true channel and dependence
/// (null if none).
nlohmann::json componentFor(const nlohmann::json& j, const std::string& effect) {
  const auto truth = simulation::unknownEffectTruth(effects::parseEffect(effect));
  for (const auto& f : j["findings"]) {
    if (f["effect"] != "unmodeled") continue;
    for (const auto& c : f.value("physics", nlohmann::json::array()))
      if (c["channel"] == truth.channel && c["dependence"] == truth.dependence) return c;
  }
  return nullptr;
}

void expectNoCatalogueName(const nlohmann::json& j, const std::vector<std::string>& names) {
  for (const auto& f : j["findings"])
    for (const auto& n : names) EXPECT_NE(f["effect"], n) << f.dump();
}

TEST(UnmodeledPhysics, YawDryFrictionIsAYawMomentOfConstantSize) {
  const std::string e = "yaw_dry_friction:torque_Nm=1.146";
  const auto j = diagnoseWith(e, 907103);
  const auto c = componentFor(j, e);
  ASSERT_FALSE(c.is_null()) << j["findings"].dump();
  EXPECT_EQ(c["term"], "sgn(omega)");
  EXPECT_NEAR(c["physical"]["value"].get<double>(), 1.146, 0.115);
  EXPECT_EQ(c["physical"]["unit"], "N m");
  EXPECT_GT(c["physical"]["sd"].get<double>(), 0);
  EXPECT_GT(c["heldout_gain_A"].get<double>(), 0);
  expectNoCatalogueName(j, {"coulomb_friction", "motor_asymmetry"});
}

TEST(UnmodeledPhysics, QuadraticDragIsAForwardForceGrowingWithSpeedSquared) {
  const std::string e = "forward_quadratic_drag:c_N_s2_m2=9.841";
  const auto j = diagnoseWith(e, 760316);
  const auto c = componentFor(j, e);
  ASSERT_FALSE(c.is_null()) << j["findings"].dump();
  EXPECT_EQ(c["term"], "v*|v|");
  EXPECT_NEAR(c["physical"]["value"].get<double>(), 9.841, 0.98);
  EXPECT_GT(c["heldout_gain_A"].get<double>(), 0);
  // Coulomb friction + (6)'s viscous term nearly span v|v| over the speeds driven; the
  // library term predicts better (blocked cross-validation) and is not forced onto them.
  expectNoCatalogueName(j, {"coulomb_friction", "motor_asymmetry"});
}

TEST(UnmodeledPhysics, OneMotorOffsetOnSquareIsNotThatMotorsCoulombFriction) {
  // `square`: the right wheel never reverses, so a constant and its Coulomb friction sgn(u_R)
  // differ only while standing; the catalogue, tried first, took it (coulomb_friction right
  // 0.290 A and a 3.6 ms encoder delay). Blocked cross-validation prefers the constant.
  const std::string e = "current_offset:offset_A=0.2853,side=right";
  const auto j = diagnoseWith(e, 654499, "square");
  const auto c = componentFor(j, e);
  ASSERT_FALSE(c.is_null()) << j["findings"].dump();
  EXPECT_EQ(c["term"], "1");
  EXPECT_NEAR(c["coefficient"].get<double>(), 0.2853, 0.029);
  for (const auto& f : j["findings"]) EXPECT_EQ(f["effect"], "unmodeled") << f.dump();
}

TEST(UnmodeledPhysics, YawInertiaOnSquareIsFoundWhereTheDriveTurns) {
  // The held-out last 30 % of a `square` drive barely turns: there the omegadot term
  // contributed 0.0013 A against 0.0064 A of unexplained structure and was never reported.
  // With unmodeled_judge_where_excited the misspecification bound measures both out of
  // sample on all rows.
  const std::string e = "yaw_inertia:extra_kg_m2=2.515";
  const auto j = diagnoseWith(e, 247162, "square", true);
  const auto c = componentFor(j, e);
  ASSERT_FALSE(c.is_null()) << j["findings"].dump();
  EXPECT_EQ(c["term"], "omegadot");
  EXPECT_NEAR(c["physical"]["value"].get<double>(), 2.515, 0.25);
  EXPECT_EQ(c["physical"]["unit"], "kg m^2");
  for (const auto& f : j["findings"]) EXPECT_EQ(f["effect"], "unmodeled") << f.dump();
}

TEST(UnmodeledPhysics, HeadingYawMomentOnSquareIsAMomentFixedInTheWorld) {
  // M = 1.192 sin(phi - 69.62 deg): largest to the left at phi = 159.6 deg. The last side of
  // the `square` runs at phi = -90 deg, where cos(phi) = 0: the held-out pruning removed
  // cos(phi) (its removal cost nothing there) and then sin(phi) alone; nothing was reported
  // (before unmodeled_judge_where_excited became the default).
  const std::string e = "heading_yaw_torque:heading_deg=69.62,torque_Nm=1.192";
  const auto j = diagnoseWith(e, 403257, "square", true);
  const auto c = componentFor(j, e);
  ASSERT_FALSE(c.is_null()) << j["findings"].dump();
  EXPECT_EQ(c["physical"]["unit"], "N m");
  EXPECT_NEAR(c["physical"]["value"].get<double>(), 1.192, 0.12);
  EXPECT_NEAR(c["physical"]["towards_heading_deg"].get<double>(), 159.6, 10);
  EXPECT_TRUE(j["mismatch"].get<bool>());
}

TEST(UnmodeledPhysics, CurrentSensorOffsetIsOneMotorConstant) {
  const std::string e = "current_offset:offset_A=-0.3874,side=left";
  const auto j = diagnoseWith(e, 573010);
  const auto c = componentFor(j, e);
  ASSERT_FALSE(c.is_null()) << j["findings"].dump();
  EXPECT_EQ(c["term"], "1");
  EXPECT_NEAR(c["coefficient"].get<double>(), -0.3874, 0.039);
  EXPECT_GT(c["heldout_gain_A"].get<double>(), 0);
  // Not a load on both motors: no forward or yaw component with a constant.
  for (const auto& f : j["findings"])
    for (const auto& p : f.value("physics", nlohmann::json::array()))
      if (p["dependence"] == "constant") EXPECT_EQ(p["channel"], "current_left") << p.dump();
}

// Catalogue terms beside the multibody's own out-of-catalogue loads (MuJoCo, issue 16 item 4).
// The finding of `effect` in j (null if none).
nlohmann::json findingOf(const nlohmann::json& j, const std::string& effect) {
  for (const auto& f : j["findings"])
    if (f["effect"] == effect) return f;
  return nullptr;
}

TEST(UnmodeledPhysics, MujocoMotorAsymmetryIsNamedBesideTheCentreOfMassCurrents) {
  // The out-of-catalogue re-selection compared u_R with a right-motor u^2 without the centre of
  // mass' v*omega / omega^2 currents, which u^2 partly carries: u^2 won (LR 11.8 > 10.4), the
  // asymmetry was described as `+1.08 v +0.31 omega` on the right motor (u_R itself) and not
  // named. The joint search does not keep u^2: the asymmetry is named again.
  const auto j = diagnoseWith("motor_asymmetry:friction_ratio=1.38688,side=right", 428469,
                              "excite --duration 90 --engine mujoco");
  const auto f = findingOf(j, "motor_asymmetry");
  ASSERT_FALSE(f.is_null()) << j["findings"].dump();
  EXPECT_EQ(f["parameters"]["side"], "right");
  EXPECT_NEAR(f["parameters"]["friction_ratio"].get<double>(), 1.38688, 0.05);
  for (const auto& u : j["findings"])
    if (u["effect"] == "unmodeled")
      for (const char* k : {"v", "omega", "u^2"})
        EXPECT_FALSE(u["parameters"].contains(k)) << u.dump();
}

TEST(UnmodeledPhysics, MujocoSlopeTurnMomentIsOneHeadingTermOnBothMotors) {
  // On a slope the centre of mass ahead of the axle turns the chair across it: -A sin(h - phi)
  // on the right motor, +A on the left. The left motor's search found sin(phi) only; the joint
  // fit put cos(phi) on the right alone (-0.33, truth -0.18) and the slope read 1.85 deg.
  const auto j = diagnoseWith(
      "ground_slope:angle_deg=1.96801,downhill_heading_deg=14.7493 --effect "
      "encoder_scale:scale=1.01388,side=left",
      771974, "square --engine mujoco");
  const auto s = findingOf(j, "ground_slope");
  ASSERT_FALSE(s.is_null()) << j["findings"].dump();
  EXPECT_NEAR(s["parameters"]["angle_deg"].get<double>(), 1.968, 0.1);
  std::map<std::string, nlohmann::json> motor;
  for (const auto& u : j["findings"])
    if (u["effect"] == "unmodeled") motor[u["parameters"]["channel"]] = u["parameters"];
  ASSERT_TRUE(motor.count("current_right") && motor.count("current_left")) << j.dump();
  for (const char* k : {"cos(phi)", "sin(phi)"}) {
    ASSERT_TRUE(motor["current_right"].contains(k) && motor["current_left"].contains(k)) << k;
    EXPECT_NEAR(motor["current_right"][k].get<double>(), -motor["current_left"][k].get<double>(),
                1e-9);
  }
  // The engine's measured truth (measureMujocoTruth): right -0.177 cos(phi) +0.671 sin(phi).
  EXPECT_NEAR(motor["current_right"]["cos(phi)"].get<double>(), -0.177, 0.06);
  EXPECT_NEAR(motor["current_right"]["sin(phi)"].get<double>(), 0.671, 0.1);
}

TEST(UnmodeledPhysics, MujocoSlopeHeadingTermOnOneMotorIsTheYawMomentNotPartOfTheSlope) {
  // The search found the slope's turn moment on the left motor only; as a one-motor column
  // (half forward, half yaw) it took part of the slope: `cos(phi)` -1.42 on the left motor,
  // slope towards -95.5 deg (truth -83.5). Next to the slope it is the yaw moment.
  const auto j = diagnoseWith(
      "ground_slope:angle_deg=2.14949,downhill_heading_deg=-83.5413 --effect "
      "encoder_scale:scale=1.02375,side=right",
      567332, "square --engine mujoco");
  const auto s = findingOf(j, "ground_slope");
  ASSERT_FALSE(s.is_null()) << j["findings"].dump();
  EXPECT_NEAR(s["parameters"]["angle_deg"].get<double>(), 2.149, 0.11);
  EXPECT_NEAR(s["parameters"]["downhill_heading_deg"].get<double>(), -83.54, 3);
  for (const auto& u : j["findings"])
    for (const auto& p : u.value("physics", nlohmann::json::array()))
      if (p["dependence"] == "heading") EXPECT_EQ(p["channel"], "yaw") << p.dump();
}

TEST(UnmodeledPhysics, MujocoCastorFrictionIsAYawMomentWhileTheCastorsSwivel) {
  // Swivel friction of MuJoCo's castors: a 10-30 sigma trace in the currents, bursts while the
  // castors turn round at turn starts. No term of the library spanned it (omegadot R^2 0.33
  // here) and nothing was found; the castors' swivel moment (castorSwivelMoment) does.
  const std::string e = "castor_friction:swivel_friction_Nm=1.0";
  const auto j = diagnoseWith(e, 673968, "square --engine mujoco");
  const auto c = componentFor(j, e);
  ASSERT_FALSE(c.is_null()) << j["findings"].dump();
  EXPECT_EQ(c["term"], "castor_swivel");
  EXPECT_EQ(c["physical"]["unit"], "N m");
  // The swivel friction, read through a free castor's kinematics: the right size and sign
  // (the castors' lag under friction is not modelled: within a factor of two).
  EXPECT_GT(c["physical"]["value"].get<double>(), 0.5);
  EXPECT_LT(c["physical"]["value"].get<double>(), 2.0);
  EXPECT_GT(c["heldout_gain_A"].get<double>(), 0);
  expectNoCatalogueName(j, {"coulomb_friction", "motor_asymmetry", "sensor_delay"});
}

TEST(UnmodeledPhysics, MujocoQuadraticDragOnBothMotorsIsNoMotorAsymmetry) {
  // A drag along the heading loads both motors alike. The forward selection rejected both
  // motor asymmetries; the out-of-catalogue terms then spanned the right motor's u_R and
  // addSpannedTerms named `motor_asymmetry` right 1.086, although the left motor's asymmetry
  // column, fitted beside it, takes the same coefficient: an equal extra load on both motors is
  // no asymmetry (symmetricSpareAsymmetry). The drag is described instead.
  const std::string e = "forward_quadratic_drag:c_N_s2_m2=5.135";
  const auto j = diagnoseWith(e, 220317, "excite --duration 90 --engine mujoco");
  expectNoCatalogueName(j, {"motor_asymmetry", "coulomb_friction"});
  const auto c = componentFor(j, e);
  ASSERT_FALSE(c.is_null()) << j["findings"].dump();
  EXPECT_EQ(c["term"], "v*|v|");
  EXPECT_GT(c["physical"]["value"].get<double>(), 0);  // a drag: opposing the motion
}

TEST(UnmodeledPhysics, MujocoViscousDragAcceptedOnOneMotorIsNoMotorAsymmetry) {
  // A viscous drag is +8 % viscous friction on both motors at the drive's speed. The forward
  // selection accepted the left motor's asymmetry (1.081) and rejected the right's on its
  // held-out check, so the rule for both sides accepted did not apply: fitted beside the left,
  // the right motor's column takes the same coefficient, and the asymmetry is not named.
  const auto j =
      diagnoseWith("forward_viscous_drag:c_N_s_m=3.041", 699374, "square --engine mujoco");
  expectNoCatalogueName(j, {"motor_asymmetry"});
  bool said = false;
  for (const auto& l : j["channels"]["current_left"]["rejected_candidates"])
    said |= l.get<std::string>().rfind("motor_asymmetry: not named, the same", 0) == 0;
  EXPECT_TRUE(said) << j["channels"]["current_left"]["rejected_candidates"].dump();
}

TEST(UnmodeledPhysics, MujocoSoftTyreIsARollingRadiusGrowingWithSpeedSquared) {
  // A tyre whose rolling radius grows with its rim speed, r = r0 + g u^2: each wheel rolls
  // further per radian than the odometry says, so the chassis turns (g / r0) (u_R^3 - u_L^3) /
  // l_w faster than the wheels' nominal yaw rate (kinematicLibraryValue). Without that column
  // the gyro-vs-encoder search read it as v*omega ("the chassis slipping sideways in turns").
  const std::string e = "soft_tyre:growth_m=0.005288";
  const auto j = diagnoseWith(e, 610899, "excite --duration 90 --engine mujoco");
  const auto c = componentFor(j, e);
  ASSERT_FALSE(c.is_null()) << j["findings"].dump();
  EXPECT_EQ(c["term"], "(u_R^3-u_L^3)/l_w");
  // g / r0 with the shipped wheel radius 0.17 m: 0.0311 per (m/s)^2
  EXPECT_NEAR(c["coefficient"].get<double>(), 0.005288 / 0.17, 0.25 * 0.005288 / 0.17);
  expectNoCatalogueName(j, {"gyro_scale", "encoder_scale"});
}

TEST(UnmodeledPhysics, MujocoQuadraticDragOnSquareTermWorseOnHeldOutRowsIsLeftOut) {
  // A quadratic drag of 4.32 N s^2/m^2 on a `square` drive (a 0.94-sigma current trace). The
  // search on the left motor finds omega^2 (the multibody's centre of mass) and a forward rate
  // term `v` (the drag at the one speed of a `square` side; its held-out gain -0.006 A). Each
  // component of an `unmodeled` finding is judged on the held-out rows on its own (issue 16
  // item 2): `v` predicts them worse (realised likelihood ratio -20 where +18 was predicted)
  // and is left out, said in info.rejected_heldout. (Before: `v` was reported, the finding as
  // a whole predicting the held-out rows better.) Not forced onto a catalogue name either.
  const auto j =
      diagnoseWith("forward_quadratic_drag:c_N_s2_m2=4.32", 785894, "square --engine mujoco");
  expectNoCatalogueName(j, {"motor_asymmetry", "coulomb_friction"});
  for (const auto& f : j["findings"]) {
    EXPECT_FALSE(f["parameters"].contains("v")) << f.dump();
    for (const auto& c : f.value("physics", nlohmann::json::array()))
      EXPECT_GE(c["heldout_gain_A"].get<double>(), -1e-3) << c.dump();
  }
  bool said = false;
  for (const auto& r : j["info"].value("rejected_heldout", nlohmann::json::array()))
    said = said || (r.value("term", "") == "v" &&
                    r["reason"].get<std::string>().find("held-out prediction gets worse") !=
                        std::string::npos);
  EXPECT_TRUE(said) << j["info"].dump();
}

TEST(UnmodeledPhysics, MujocoCleanDriveHasNoCastorTerm) {
  // The same drive without the friction: free castors swivel too, but cost nothing.
  const auto j = diagnoseWith("", 673968, "square --engine mujoco");
  for (const auto& f : j["findings"])
    for (const auto& p : f.value("physics", nlohmann::json::array()))
      EXPECT_NE(p["dependence"], "castor_swivel") << p.dump();
}

}  // namespace

TEST(UnmodeledPhysics, ForwardViscousDragOnSquareIsOneAmbiguousGroup) {
  // A `square` drive runs its sides at one speed: v, v*|v| (and each wheel's u^2) are nearly
  // collinear there, and STLSQ kept whichever survived thresholding (this drive was read as
  // `wheels: |u|`). The component names the readings the data cannot tell apart (issue 16
  // item 5) and what to drive to tell them.
  const std::string e = "forward_viscous_drag:c_N_s_m=6.0";
  const auto j = diagnoseWith(e, 350225, "square");
  bool grouped = false;
  for (const auto& f : j["findings"]) {
    EXPECT_EQ(f["effect"], "unmodeled") << f.dump();
    for (const auto& c : f.value("physics", nlohmann::json::array())) {
      if (!c.contains("ambiguous_with")) continue;
      std::string readings =
          c["channel"].get<std::string>() + ":" + c["dependence"].get<std::string>();
      for (const auto& a : c["ambiguous_with"])
        readings +=
            " " + a["channel"].get<std::string>() + ":" + a["dependence"].get<std::string>();
      EXPECT_NE(readings.find("forward:rate "), std::string::npos) << readings;
      EXPECT_NE(readings.find("forward:rate_squared"), std::string::npos) << readings;
      EXPECT_NE(c["ambiguity"].get<std::string>().find("tells them apart"), std::string::npos);
      grouped = true;
    }
  }
  EXPECT_TRUE(grouped) << j["findings"].dump();
}

TEST(UnmodeledPhysics, MujocoAsymmetryNamedFromOutOfCatalogueTermsMustPredictInTheirPlace) {
  // Slope 2.4 deg + Coulomb 0.55 A: the out-of-catalogue terms (the centre of mass' heading,
  // v*omega and omega^2 currents) nearly span a left-motor viscous column, so the asymmetry was
  // named (1.033) although the forward selection had found it insignificant (p = 0.26) and,
  // fitted with the catalogue alone, it predicts no left-out time block better
  // (unconfirmedNamedTerm: mean gain > 0 and |coefficient| >= 2.58 block-to-block sd, in
  // their place -0.28 +- 0.19): not reported, and the reason is in rejected_candidates
  // (since the symmetric-load rule, symmetricSpareAsymmetry, the right motor's asymmetry column
  // fitted beside it takes an equal coefficient and it is not named in the first place).
  const auto j = diagnoseWith(
      "ground_slope:angle_deg=2.36059,downhill_heading_deg=47.2917 --effect "
      "coulomb_friction:current_A=0.547386",
      607097, "excite --duration 90 --engine mujoco");
  EXPECT_TRUE(findingOf(j, "motor_asymmetry").is_null()) << j["findings"].dump();
  EXPECT_FALSE(findingOf(j, "ground_slope").is_null()) << j["findings"].dump();
  EXPECT_FALSE(findingOf(j, "coulomb_friction").is_null()) << j["findings"].dump();
  bool said = false;
  for (const auto& r : j["channels"]["current_right"]["rejected_candidates"])
    said = said ||
           r.get<std::string>().find(
               "motor_asymmetry/left: named from the out-of-catalogue terms, but not kept") == 0 ||
           r.get<std::string>().find(
               "motor_asymmetry/left: described by the out-of-catalogue "
               "terms, but not named") == 0;
  EXPECT_TRUE(said) << j["channels"]["current_right"]["rejected_candidates"].dump();
  // A real asymmetry named the same way predicts in their place: kept (left 1.246 alone, named
  // from the out-of-catalogue terms; in their place P(gain <= 0) = 0.002, coefficient 5 sd: a
  // bootstrap P required below the Bonferroni level 0.0013 had dropped it).
  const auto k = diagnoseWith("motor_asymmetry:friction_ratio=1.2457,side=left", 134237,
                              "excite --duration 90 --engine mujoco");
  const auto a = findingOf(k, "motor_asymmetry");
  ASSERT_FALSE(a.is_null()) << k["findings"].dump();
  EXPECT_EQ(a["parameters"]["side"], "left");
  EXPECT_NEAR(a["parameters"]["friction_ratio"].get<double>(), 1.2457, 0.25 * 0.2457);
  bool named = false;
  for (const auto& r : k["channels"]["current_left"]["rejected_candidates"])
    named = named || r.get<std::string>() ==
                         "motor_asymmetry/left: described in full by the out-of-catalogue terms "
                         "found: named";
  EXPECT_TRUE(named) << k["channels"]["current_left"]["rejected_candidates"].dump();
}

TEST(UnmodeledPhysics, MujocoOmegaAndOmegaSquaredOnASquareAreOneLawOnBothMotors) {
  // On `square` the turns on the spot go one way at one rate: omega and omega^2 are the same
  // column (|cosine| 0.989). The per-motor search put omega on the right motor and omega^2 on
  // the left (two laws, a yaw-rate term the engine does not have); harmoniseUntold reports
  // one law on both motors (the multibody's centre-of-mass omega^2, -0.567 A s^2/rad^2 by
  // measureMujocoTruth) and says what could not be told.
  const auto j = diagnoseWith("gyro_scale:scale=0.988425", 846539, "square --engine mujoco");
  EXPECT_FALSE(findingOf(j, "gyro_scale").is_null()) << j["findings"].dump();
  int motors = 0;
  for (const auto& u : j["findings"]) {
    if (u["effect"] != "unmodeled") continue;
    ++motors;
    EXPECT_FALSE(u["parameters"].contains("omega")) << u.dump();
    ASSERT_TRUE(u["parameters"].contains("omega^2")) << u.dump();
    EXPECT_NEAR(u["parameters"]["omega^2"].get<double>(), -0.567, 0.25 * 0.567) << u.dump();
  }
  EXPECT_EQ(motors, 2) << j["findings"].dump();
  bool said = false;
  for (const auto& c : j["info"]["cannot_tell"])
    said = said || c.get<std::string>().find("which one acts cannot be told") != std::string::npos;
  EXPECT_TRUE(said) << j["info"].dump();
}

TEST(UnmodeledPhysics, MujocoOneSidedAsymmetryBesideAPoorlyDeterminedOtherSideIsNamed) {
  // Left motor asymmetry 1.49 with a 189 kg payload and a gyro 4.5 % short: fitted beside the
  // accepted left asymmetry, the right motor's column takes 0.073 +- 0.099 against the left's
  // 0.465 +- 0.103, within 3 sigma of their difference, and the asymmetry was taken for a load
  // on both motors and dropped. A load on the left motor alone fits the two far better (chi^2
  // 0.55 against 7.5, loadOnBothMotorsFitsBetter): named, within 25 %.
  const auto j = diagnoseWith(
      "motor_asymmetry:friction_ratio=1.4945,side=left --effect payload_mass:body_mass_kg=188.684 "
      "--effect gyro_scale:scale=0.95511",
      976019, "excite --duration 90 --engine mujoco");
  const auto a = findingOf(j, "motor_asymmetry");
  ASSERT_FALSE(a.is_null()) << j["findings"].dump();
  EXPECT_EQ(a["parameters"]["side"], "left");
  EXPECT_NEAR(a["parameters"]["friction_ratio"].get<double>(), 1.4945, 0.25 * 0.4945);
  EXPECT_FALSE(findingOf(j, "payload_mass").is_null()) << j["findings"].dump();
  EXPECT_FALSE(findingOf(j, "gyro_scale").is_null()) << j["findings"].dump();
}

TEST(UnmodeledPhysics, MujocoOneMotorAsymmetryIsComparedWithALoadOnBothBesideTheOtherPhysics) {
  // Right motor asymmetry 1.166 alone (MuJoCo seed 7 campaign single 132242). Fitted beside
  // the catalogue alone, the two motors' asymmetry columns took right 0.129 +- 0.056, left
  // 0.066 +- 0.040 (the multibody's v*omega, omega^2 currents in the residual): "a load on
  // both motors" fitted them better (chi^2 0.83 against 2.7), the asymmetry was not named and
  // the right motor's search reported `v` 0.51 (its viscous term) as out-of-catalogue physics.
  // Compared beside the out-of-catalogue terms found but the rates v, omega
  // (symmetricSpareAsymmetry in addSpannedTerms), one motor: named within 25 %, and no `v` is
  // left on either motor's unmodeled finding.
  const auto j = diagnoseWith("motor_asymmetry:friction_ratio=1.16552,side=right", 132242,
                              "excite --duration 90 --engine mujoco");
  const auto a = findingOf(j, "motor_asymmetry");
  ASSERT_FALSE(a.is_null()) << j["findings"].dump();
  EXPECT_EQ(a["parameters"]["side"], "right");
  EXPECT_NEAR(a["parameters"]["friction_ratio"].get<double>(), 1.16552, 0.25 * 0.16552);
  for (const auto& f : j["findings"])
    if (f["effect"] == "unmodeled") EXPECT_FALSE(f["parameters"].contains("v")) << f.dump();
}

TEST(UnmodeledPhysics, MujocoDragOnBothMotorsOrOneMotorAsymmetryIsSaidCannotTell) {
  // A viscous drag along the heading 1.5 N s/m (out of the catalogue). Beside the other
  // physics, the right motor's asymmetry column takes 0.048 +- 0.003 and the left's a poorly
  // determined value: "a load on both motors" (chi^2 0.16) and "the right motor alone" (chi^2
  // 3.1) both fit (neither above chi^2_1(0.95) = 3.84). Not named, and said: info.cannot_tell
  // and the printed text carry both readings and what to drive to tell them apart
  // (untoldAsymmetryOrLoad).
  const TempDir d;
  const std::string rec = d / "q.rawlog", json = d / "q.json";
  const auto sim =
      cli("simulate --scenario excite --duration 90 --engine mujoco --seed 12 --effect "
          "forward_viscous_drag:c_N_s_m=1.5 -o " +
          rec);
  ASSERT_EQ(sim.exit_code, 0) << sim.out;
  const auto diag = cli("diagnose " + rec + " --no-progress --json " + json);
  ASSERT_EQ(diag.exit_code, 0) << diag.out;
  const auto j = nlohmann::json::parse(readFile(json));
  EXPECT_TRUE(findingOf(j, "motor_asymmetry").is_null()) << j["findings"].dump();
  bool said = false;
  for (const auto& c : j["info"]["cannot_tell"]) {
    const std::string s = c.get<std::string>();
    said = said || (s.rfind("motor_asymmetry/", 0) == 0 &&
                    s.find("a load on both motors") != std::string::npos &&
                    s.find("To tell: straight runs at several speeds") != std::string::npos);
  }
  EXPECT_TRUE(said) << j["info"].dump();
  EXPECT_NE(diag.out.find("cannot tell: motor_asymmetry/"), std::string::npos) << diag.out;
}
