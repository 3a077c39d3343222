// Sensor-fault detectors of `wheelchair diagnose` (libwheelchair/diagnosis/SensorFaults.h):
// clean simulated drives report no fault (and no finding at all); each simulated fault is
// named alone, as a fault (is_fault), with its parameters; a fault adds no physics finding.
#include "DiagnoseTestUtil.h"

#include "libwheelchair/diagnosis/Diagnosis.h"
#include "libwheelchair/simulation/Simulator.h"

#include <gtest/gtest.h>

using namespace wheelchair;

namespace {

// diagnose() of one recording, nominal vehicle, default options.
const auto run = diagnosis::testutil::diagnoseOne;

io::Recording sim(const std::string& scenario, uint64_t seed, double dur,
                  const std::vector<std::string>& effects) {
  return diagnosis::testutil::simulateWith(scenario, seed, dur, effects).recording;
}

std::string names(const diagnosis::DiagnosisReport& r) {
  std::string s;
  for (auto& f : r.findings) s += f.effect + ": " + f.description + "\n";
  return s;
}

}  // namespace

TEST(SensorFaults, CleanDrivesReportNoFault) {
  // three_task: one obstacle (sonar mostly 0 = no echo); obstacles: posts in view all the
  // time; excite / square: no obstacles. Pozyx on all.
  const std::vector<std::pair<std::string, double>> cases = {
      {"three_task", 0}, {"obstacles", 60}, {"excite", 90}, {"square", 0}};
  for (const auto& [sc, dur] : cases)
    for (uint64_t seed : {31, 32}) {
      const auto r = run(sim(sc, seed, dur, {}));
      EXPECT_TRUE(r.findings.empty()) << sc << " seed " << seed << ":\n" << names(r);
      EXPECT_TRUE(r.info["sensor_faults"].contains("pozyx")) << sc;
      EXPECT_TRUE(r.info["sensor_faults"].contains("sonar")) << sc;
    }
}

TEST(SensorFaults, SonarDropoutNamedWithParameters) {
  const auto rec = sim("obstacles", 2, 60, {"sonar_dropout:probability=0.1"});
  const auto r = run(rec);
  ASSERT_EQ(r.findings.size(), 1u) << names(r);
  const auto& f = r.findings[0];
  EXPECT_EQ(f.effect, "sonar_dropout");
  EXPECT_TRUE(f.is_fault);
  EXPECT_EQ(f.channels, std::vector<std::string>{"sonar"});
  // The realised failure fraction of this recording (every 0 here is a dropout: the posts are
  // always in view) is what the detector must recover.
  std::size_t zeros = 0;
  for (auto& s : rec.sonar) zeros += s.range_m == 0;
  const double realised = double(zeros) / rec.sonar.size();
  EXPECT_NEAR(f.parameters["probability"].get<double>(), realised, 0.01);
  EXPECT_NEAR(f.parameters["probability"].get<double>(), 0.1, 0.06);
  EXPECT_GT(f.parameters["burst_length"].get<double>(), 1.5);
  EXPECT_LT(f.parameters["burst_length"].get<double>(), 6.0);
  EXPECT_FALSE(f.segments.empty());
  EXPECT_TRUE(f.uncertainty.contains("probability"));
  EXPECT_TRUE(f.effectText().rfind("sonar_dropout:", 0) == 0);
  // Faults are not model extensions.
  EXPECT_TRUE(diagnosis::findingsAsEffects(r).empty());
}

TEST(SensorFaults, PozyxOutliersNamedWithParameters) {
  const auto r = run(sim("excite", 5, 90, {"pozyx_outliers:rate=0.05,magnitude_m=1"}));
  ASSERT_EQ(r.findings.size(), 1u) << names(r);
  const auto& f = r.findings[0];
  EXPECT_EQ(f.effect, "pozyx_outliers");
  EXPECT_TRUE(f.is_fault);
  EXPECT_NEAR(f.parameters["rate"].get<double>(), 0.05, 0.015);
  EXPECT_NEAR(f.parameters["magnitude_m"].get<double>(), 1.0, 0.3);
  EXPECT_TRUE(f.evidence.contains("outlier_times_s"));
  EXPECT_FALSE(f.segments.empty());
}

TEST(SensorFaults, FaultAddsNoPhysicsFinding) {
  // Physics + fault: exactly the physics effect and the fault, nothing else.
  const auto r =
      run(sim("excite", 21, 90,
              {"gyro_bias:bias_rad_s=0.006", "pozyx_outliers:rate=0.03,magnitude_m=1.5"}));
  ASSERT_EQ(r.findings.size(), 2u) << names(r);
  ASSERT_TRUE(r.find("gyro_bias")) << names(r);
  ASSERT_TRUE(r.find("pozyx_outliers")) << names(r);
  EXPECT_FALSE(r.find("gyro_bias")->is_fault);
  EXPECT_NEAR(r.find("gyro_bias")->parameters["bias_rad_s"].get<double>(), 0.006, 0.0015);
  const auto fx = diagnosis::findingsAsEffects(r);
  ASSERT_EQ(fx.size(), 1u);
  EXPECT_EQ(fx[0].id, "gyro_bias");
}

TEST(SensorFaults, ThreeTaskSonarDropoutWhereTheObstacleIsInView) {
  // Only the first leg sees the obstacle: dropouts there are found, the no-echo stretches
  // (0 readings on a healthy sensor) are not counted.
  const auto r = run(sim("three_task", 6, 0, {"sonar_dropout:probability=0.15,burst_length=2"}));
  for (const auto& f : r.findings) EXPECT_EQ(f.effect, "sonar_dropout") << names(r);
  ASSERT_TRUE(r.find("sonar_dropout")) << names(r);
  EXPECT_TRUE(r.find("sonar_dropout")->is_fault);
}

// diagnose() on recordings it may release (the CLI's path: IMU, motor and joystick samples
// freed once the streams are made, encoders, Pozyx and ground truth once the odometric
// calibration has read them; the Pozyx check then reads the streams) gives the same
// report, bit for bit but the run time, as on recordings it must keep: here with a Pozyx fault,
// a sonar fault and physics, fit/held-out split and --validate recordings.
TEST(SensorFaults, ReleasedRecordingsGiveTheSameReport) {
  const std::vector<std::string> effects{"pozyx_outliers:rate=0.05,magnitude_m=1",
                                         "sonar_dropout:probability=0.15,burst_length=3",
                                         "encoder_scale:side=left,scale=0.97"};
  const io::Recording a = sim("excite", 5, 90, effects), b = sim("excite", 6, 60, effects);
  const config::WheelchairConfig cfg;
  const diagnosis::DiagnosisOptions opt;
  auto json = [](const diagnosis::DiagnosisReport& r) {
    nlohmann::json j = r.toJson();
    j["info"].erase("runtime_s");
    return j.dump();
  };
  const std::vector<io::Recording> fit{a}, val{b};
  for (bool with_val : {false, true}) {
    const auto kept =
        diagnosis::diagnose(fit, with_val ? val : std::vector<io::Recording>{}, cfg, opt);
    std::vector<io::Recording> fit2 = fit, val2 = with_val ? val : std::vector<io::Recording>{};
    const auto released = diagnosis::diagnose(std::move(fit2), std::move(val2), cfg, opt);
    EXPECT_TRUE(fit2[0].imu.empty() && fit2[0].motors.empty() && fit2[0].encoders.empty() &&
                fit2[0].pozyx.empty());               // released indeed
    EXPECT_EQ(fit2[0].sonar.size(), a.sonar.size());  // what is read last (sonar) kept
    EXPECT_EQ(json(kept), json(released)) << "with --validate: " << with_val;
    bool pozyx = false;
    for (const auto& f : released.findings) pozyx |= f.effect == "pozyx_outliers";
    EXPECT_TRUE(pozyx) << names(released);
  }
}
