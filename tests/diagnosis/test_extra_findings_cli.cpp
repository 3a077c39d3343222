// Extra findings on MuJoCo drives through the CLI (issue 16, "drives with any false or extra
// finding <= 2 %"; docs/discovery.md, "Extra findings: the gyro against the truth, ...").
//  - The gyro scale is decided against the ground-truth heading (EncoderSide.h,
//    gyroScaleAgainstTruth): with a concealed encoder scale, stage 1 (gyro vs encoders) reads
//    the multibody's effective odometric yaw scale (-0.18 %: tyre creep) as a gyro scale; the
//    truth says the gyro is right, so no `gyro_scale` is named. Without ground truth the
//    ambiguity is stated in info.cannot_tell. A real gyro scale is confirmed and named.
//  - `wheel_geometry` reports only parameters outside their own uncertainty
//    (KinematicCalibration.h, kEstablishedZ): on a clean drive the radii -0.05 % +- 0.06 % are
//    not reported; what is reported lies in the engine's measured effective geometry.
//  - A catalogue term whose realised held-out likelihood ratio is significantly negative is
//    rejected even when its predicted gain is too small to "test" it (Stages.cpp,
//    heldOutCheck): model engine, heading-dependent yaw moment (out of catalogue), where
//    `motor_asymmetry` made the held-out prediction worse (LR -19 for a predicted +8).
#include "libwheelchair/simulation/MujocoTruth.h"
#include "libwheelchair/simulation/Simulator.h"

#include "../common/TestUtil.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace {

using wheelchair::test::cli;
using wheelchair::test::readFile;
using wheelchair::test::TempDir;

// `simulate_args` simulated (90-s excite unless given) and diagnosed with defaults: the JSON.
// The recording (and its truth, rec + ".truth.json") goes to `rec` if given, else to a
// temporary directory.
nlohmann::json simulateAndDiagnose(const std::string& simulate_args, std::string rec = "") {
  const TempDir d;
  const std::string json = d / "x.json";
  if (rec.empty()) rec = d / "x.rawlog";
  const auto sim = cli("simulate " + simulate_args + " -o " + rec);
  EXPECT_EQ(sim.exit_code, 0) << sim.out;
  const auto diag = cli("diagnose " + rec + " --json " + json);
  EXPECT_EQ(diag.exit_code, 0) << diag.out;
  return nlohmann::json::parse(readFile(json));
}

const nlohmann::json* findingOf(const nlohmann::json& j, const std::string& effect) {
  for (const auto& f : j["findings"])
    if (f["effect"] == effect) return &f;
  return nullptr;
}

// Every radius / track change a wheel_geometry finding reports lies in the multibody's measured
// effective geometry (range widened by 25 %, as the campaign scores it).
void expectEngineGeometry(const nlohmann::json& f, const wheelchair::simulation::MujocoTruth& t) {
  auto within = [](double x, double lo, double hi) {
    const double tol = 0.25 * std::max(std::abs(lo), std::abs(hi));
    return x >= lo - tol && x <= hi + tol;
  };
  const auto& p = f["parameters"];
  for (const char* k : {"wheel_radius_right_rel", "wheel_radius_left_rel"})
    if (const double x = p[k].get<double>(); x != 0)
      EXPECT_TRUE(within(x, t.radius_rel_min, t.radius_rel_max)) << k << " " << f.dump();
  if (const double x = p["track_rel"].get<double>(); x != 0)
    EXPECT_TRUE(within(x, t.track_rel_min, t.track_rel_max)) << f.dump();
}

}  // namespace

TEST(ExtraFindingsCli, MujocoConcealedEncoderScaleIsNotAGyroScaleWhenTheTruthSaysSo) {
  const std::string drive =
      "--engine mujoco --scenario excite --seed 647984 --duration 90 "
      "--effect encoder_scale:scale=0.96312,side=right";
  const auto j = simulateAndDiagnose(drive + " --ground-truth-stream");
  const auto* enc = findingOf(j, "encoder_scale");
  ASSERT_NE(enc, nullptr) << j["findings"].dump();
  EXPECT_EQ((*enc)["parameters"]["side"], "right");
  EXPECT_NEAR((*enc)["parameters"]["scale"].get<double>(), 0.96312, 0.25 * 0.03688);
  EXPECT_EQ(findingOf(j, "gyro_scale"), nullptr) << j["findings"].dump();
  ASSERT_TRUE(j["info"].contains("gyro_scale_by_truth")) << j["info"].dump();
  const auto& g = j["info"]["gyro_scale_by_truth"];
  EXPECT_EQ(g["verdict"], "encoder_geometry");
  EXPECT_NEAR(g["scale_vs_truth"].get<double>(), 1.0, 3 * g["scale_vs_truth_sd"].get<double>());
  const wheelchair::config::WheelchairConfig cfg;
  const auto truth = wheelchair::simulation::measureMujocoTruth(cfg, {});
  if (const auto* w = findingOf(j, "wheel_geometry")) expectEngineGeometry(*w, truth);

  // Without ground truth the gyro-vs-encoder comparison cannot tell: whatever it names, the
  // ambiguity is said.
  const auto n = simulateAndDiagnose(drive);
  EXPECT_FALSE(n["info"].contains("gyro_scale_by_truth"));
  if (findingOf(n, "gyro_scale")) {
    ASSERT_TRUE(n["info"].contains("cannot_tell")) << n["info"].dump();
    EXPECT_NE(n["info"]["cannot_tell"].dump().find("ground-truth poses"), std::string::npos);
  }
}

TEST(ExtraFindingsCli, MujocoCleanDriveReportsOnlyEstablishedWheelGeometry) {
  const auto j = simulateAndDiagnose(
      "--engine mujoco --scenario excite --seed 661751 --duration 90 --ground-truth-stream");
  const auto& kc = j["info"]["kinematic_calibration"];
  ASSERT_TRUE(kc["tested"].get<bool>());
  // the candidate cross-validation chose ("wheels") had radii inside their uncertainty
  ASSERT_TRUE(kc.contains("not_established")) << kc.dump();
  const auto* w = findingOf(j, "wheel_geometry");
  ASSERT_NE(w, nullptr);
  EXPECT_LT(kc["heldout_after"]["odometry_mean_position_error_m"].get<double>(),
            kc["heldout_before"]["odometry_mean_position_error_m"].get<double>());
  const wheelchair::config::WheelchairConfig cfg;
  expectEngineGeometry(*w, wheelchair::simulation::measureMujocoTruth(cfg, {}));
  for (const auto& f : j["findings"])
    EXPECT_TRUE(f["effect"] == "wheel_geometry" || f["effect"] == "unmodeled") << f.dump();
}

TEST(ExtraFindingsCli, SignificantlyNegativeHeldOutGainRejectsAnUntestableCatalogueTerm) {
  const auto j = simulateAndDiagnose(
      "--scenario excite --seed 918012 --duration 90 "
      "--effect heading_yaw_torque:heading_deg=-84.36,torque_Nm=1.274");
  EXPECT_EQ(findingOf(j, "motor_asymmetry"), nullptr) << j["findings"].dump();
  bool rejected = false;
  for (const auto& [name, ch] : j["channels"].items()) {
    if (!ch.contains("rejected_candidates")) continue;
    for (const auto& r : ch["rejected_candidates"]) {
      const std::string s = r.get<std::string>();
      rejected |= s.rfind("motor_asymmetry", 0) == 0 &&
                  s.find("makes the held-out prediction significantly worse") != std::string::npos;
    }
  }
  EXPECT_TRUE(rejected) << j["channels"].dump();
}

// A real gyro scale (-1.6 %) on the same engine is still named: the truth confirms it.
TEST(ExtraFindingsCli, MujocoConcealedGyroScaleIsConfirmedByTheTruth) {
  const auto j = simulateAndDiagnose(
      "--engine mujoco --scenario square --seed 871605 --effect gyro_scale:scale=0.98379 "
      "--ground-truth-stream");
  const auto* g = findingOf(j, "gyro_scale");
  ASSERT_NE(g, nullptr) << j["findings"].dump();
  EXPECT_NEAR((*g)["parameters"]["scale"].get<double>(), 0.98379, 0.25 * 0.01621);
  const auto& t = j["info"]["gyro_scale_by_truth"];
  EXPECT_NE(t["verdict"], "encoder_geometry");
  EXPECT_NEAR(t["scale_vs_truth"].get<double>(), 0.98379, 0.001);
}

// One observable, one name (KinematicCalibration.h, foldRadiusIntoEncoderScale): with a
// concealed left encoder scale the stage-1 estimate is 0.04 % off and the increment-domain
// calibration put that 0.04 % into the left wheel's radius (-0.069 % against the right's
// -0.113 %; the engine rolls both at -0.127 %). A wheel's metres per tick are its radius over
// its encoder's scale: the difference goes into the named encoder scale, which gets closer to
// the concealed one, and both radii report the engine's common rolling radius.
TEST(ExtraFindingsCli, MujocoWheelRadiusOfANamedEncoderIsFoldedIntoItsScale) {
  const auto j = simulateAndDiagnose(
      "--engine mujoco --scenario excite --seed 368766 --duration 90 "
      "--effect encoder_scale:scale=1.01839,side=left --ground-truth-stream");
  const auto* enc = findingOf(j, "encoder_scale");
  ASSERT_NE(enc, nullptr) << j["findings"].dump();
  EXPECT_EQ((*enc)["parameters"]["side"], "left");
  // main: 1.01876 (the radius' share left out); folded: 1.01831
  EXPECT_NEAR((*enc)["parameters"]["scale"].get<double>(), 1.01839, 0.0002) << enc->dump();
  const auto& kc = j["info"]["kinematic_calibration"];
  ASSERT_TRUE(kc.contains("folded_into_encoder_scale")) << kc.dump();
  EXPECT_EQ(kc["folded_into_encoder_scale"]["side"], "left");
  const auto* w = findingOf(j, "wheel_geometry");
  ASSERT_NE(w, nullptr) << j["findings"].dump();
  EXPECT_NEAR((*w)["parameters"]["wheel_radius_left_rel"].get<double>(),
              (*w)["parameters"]["wheel_radius_right_rel"].get<double>(), 1e-9);
  const wheelchair::config::WheelchairConfig cfg;
  expectEngineGeometry(*w, wheelchair::simulation::measureMujocoTruth(cfg, {}));
}

// A slope turns the chair downhill (KinematicCalibration.h, slopeYawCreep): MuJoCo excite
// 653117 on a 1.53 deg slope, where the heading creeps by ~0.001 rad/s x sin(downhill -
// heading). The whole-run calibration folded that creep into a track 0.57 % wider (the engine's
// effective track is +0.05..+0.35 %); with the slope named by the dynamics, the creep is tested
// on the heading increments against the ground truth: significant, so no geometry is reported
// and info.cannot_tell says what would tell them apart.
TEST(ExtraFindingsCli, MujocoSlopeYawCreepIsNotReportedAsWheelGeometry) {
  const auto j = simulateAndDiagnose(
      "--engine mujoco --scenario excite --seed 653117 --duration 90 "
      "--effect gyro_bias:bias_rad_s=-0.012837 "
      "--effect ground_slope:angle_deg=1.52922,downhill_heading_deg=10.3465 "
      "--ground-truth-stream");
  ASSERT_NE(findingOf(j, "ground_slope"), nullptr) << j["findings"].dump();
  EXPECT_EQ(findingOf(j, "wheel_geometry"), nullptr) << j["findings"].dump();
  const auto& kc = j["info"]["kinematic_calibration"];
  ASSERT_TRUE(kc.contains("slope_creep")) << kc.dump();
  EXPECT_TRUE(kc["slope_creep"]["significant"].get<bool>()) << kc.dump();
  EXPECT_GT(kc["slope_creep"]["creep_rad_s"].get<double>(), 0) << kc.dump();
  ASSERT_TRUE(j["info"].contains("cannot_tell")) << j["info"].dump();
  EXPECT_NE(j["info"]["cannot_tell"].dump().find("slope's yaw creep"), std::string::npos);
}

// The geometry a drive realises (MujocoTruth.h, realisedGeometry; issue 16, "wheel_geometry
// from an increment-domain candidate outside the engine's measured geometry"): on MuJoCo excite
// 799554 (a gyro bias only) the increment-domain calibration reports radii -0.100 / -0.094 %
// and a track +0.07 %; the steady 3 / 6 A drives of measureMujocoTruth roll -0.127 %, so the
// campaign scored the finding as false. Measured on the multibody's exact pose and hinge
// angles in this very drive (no sensor, no diagnosis), the chair rolls -0.10 % short with a
// track +0.07 % wider: the finding is the drive's own geometry, within the campaign's 25 %.
TEST(ExtraFindingsCli, MujocoWheelGeometryIsTheGeometryTheDriveRealises) {
  const TempDir d;
  const std::string rec = d / "x.rawlog";
  const auto j = simulateAndDiagnose(
      "--engine mujoco --scenario excite --seed 799554 --duration 90 "
      "--effect gyro_bias:bias_rad_s=0.0192724 --ground-truth-stream",
      rec);
  ASSERT_NE(findingOf(j, "gyro_bias"), nullptr) << j["findings"].dump();
  const auto* w = findingOf(j, "wheel_geometry");
  ASSERT_NE(w, nullptr) << j["findings"].dump();

  const auto truth = wheelchair::simulation::readTruth(rec + ".truth.json").truth.samples;
  const wheelchair::config::WheelchairConfig cfg;
  const auto g = wheelchair::simulation::realisedGeometry(cfg, truth);
  ASSERT_GT(g.windows, 100);
  const auto steady = wheelchair::simulation::measureMujocoTruth(cfg, {});
  // the drive rolls measurably less short than the steady straight drives
  EXPECT_GT(g.radius_rel, steady.radius_rel_max + 1e-4) << g.radius_rel;
  EXPECT_LT(g.radius_rel, 0);
  EXPECT_GT(g.track_rel, 0);
  const auto& p = (*w)["parameters"];
  for (const char* k : {"wheel_radius_right_rel", "wheel_radius_left_rel"})
    EXPECT_NEAR(p[k].get<double>(), g.radius_rel, 0.25 * std::abs(g.radius_rel)) << k;
  EXPECT_NEAR(p["track_rel"].get<double>(), g.track_rel, 0.25 * std::abs(g.track_rel));
}
