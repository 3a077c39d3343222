// The live model-health monitor through the CLI (`wheelchair filter --health`,
// estimation/HealthMonitor.h): a left encoder that goes 5 % short (or a right one 5 % long) in
// the middle of a simulated three-task drive (`simulate --effect encoder_scale:...,from_s=8`)
// is detected at once, estimated, and reported with its side and direction within 5 s of the
// turn that reveals the side.
#include "../common/TestUtil.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

using namespace wheelchair;
using test::cli;
using test::TempDir;

namespace {

/// A step fault of one encoder at 8 s (`scale` on `side`) on the three-task drive, filtered
/// with the SHIPPED configuration: detected at once (the scales open), estimated, and reported
/// with its side and direction within 5 s of the turn that reveals them; `word` is "short" or
/// "long" (no direction is assumed: encoder_fault_prior = either).
void checkStepFault(const std::string& side, double scale, const std::string& word) {
  SCOPED_TRACE(side + " encoder x" + std::to_string(scale));
  TempDir tmp;
  const std::string rec = tmp / "step.rawlog", truth = tmp / "step.truth.json";
  const double step_s = 8.0;
  const auto sim =
      cli("simulate --scenario three_task --seed 7 --effect encoder_scale:scale=" +
          std::to_string(scale) + ",side=" + side + ",from_s=8 -o " + rec + " --truth " + truth);
  ASSERT_EQ(sim.exit_code, 0) << sim.out;
  const std::string shipped = std::string(WHEELCHAIR_SOURCE_DIR) + "/config/wheelchair.ini";
  const auto f = cli("filter " + rec + " --config " + shipped + " --no-progress --health " +
                     (tmp / "h.jsonl"));
  ASSERT_EQ(f.exit_code, 0) << f.out;
  EXPECT_NE(f.out.find(side + " encoder reads "), std::string::npos) << f.out;
  EXPECT_NE(f.out.find("% " + word + " (+-"), std::string::npos) << f.out;
  EXPECT_EQ(f.out.find("note: --health switches"), std::string::npos) << f.out;  // shipped: on
  const std::string other = side == "left" ? "right" : "left";

  // The first turn after the step (truth): the motion that tells which encoder it is.
  const nlohmann::json tj = nlohmann::json::parse(test::readFile(truth));
  const auto& t = tj["trajectory"]["t_s"];
  const auto& w = tj["trajectory"]["omega_rad_s"];
  double turn_s = -1;
  for (std::size_t i = 0; i < t.size(); ++i)
    if (t[i].get<double>() > step_s && std::abs(w[i].get<double>()) > 0.1) {
      turn_s = t[i].get<double>();
      break;
    }
  ASSERT_GT(turn_s, step_s);

  std::ifstream in(tmp / "h.jsonl");
  std::string line;
  std::vector<nlohmann::json> ev;
  while (std::getline(in, line)) ev.push_back(nlohmann::json::parse(line));
  ASSERT_FALSE(ev.empty());
  bool detected = false, reported = false, sonar = false;
  for (const auto& e : ev) {
    for (const char* k : {"t_s", "sensor", "kind", "parameter", "value", "sd", "since_s", "text"})
      ASSERT_TRUE(e.contains(k)) << e.dump();
    if (e["kind"] == "inconsistent" && !detected) {
      detected = true;
      EXPECT_EQ(e["sensor"], "encoders");
      EXPECT_NEAR(e["since_s"].get<double>(), step_s, 0.5) << e.dump();  // onset estimate
      EXPECT_LT(e["t_s"].get<double>(), step_s + 1.0) << e.dump();       // straight driving
    }
    if (e["kind"] == "estimate" && e["side"] == side && !reported) {
      reported = true;
      EXPECT_EQ(e["effect"], "encoder_scale");  // diagnose's effect words
      EXPECT_EQ(e["parameter"], "scale");
      EXPECT_NEAR(e["value"].get<double>(), scale, std::max(3 * e["sd"].get<double>(), 0.005));
      EXPECT_LT(e["t_s"].get<double>(), turn_s + 5.0) << e.dump();
      EXPECT_NEAR(e["since_s"].get<double>(), step_s, 0.5) << e.dump();
    }
    if (e["kind"] == "estimate" && e["side"] == other) ADD_FAILURE() << e.dump();
    if (e["sensor"] == "sonar") sonar = true;
  }
  EXPECT_TRUE(detected);
  EXPECT_TRUE(reported);
  EXPECT_TRUE(sonar);  // its no-echo episodes are counted
}

}  // namespace

TEST(HealthCli, AMidDriveEncoderScaleStepIsDetectedEstimatedAndReported) {
  checkStepFault("left", 0.95, "short");
}

TEST(HealthCli, AMidDriveEncoderReadingLongIsNamedLongNotBlamedOnTheOtherWheel) {
  checkStepFault("right", 1.05, "long");
}

TEST(HealthCli, CleanDriveReportsNoEncoderFaultAndBadPathFailsFirst) {
  TempDir tmp;
  const std::string rec = tmp / "clean.rawlog";
  ASSERT_EQ(cli("simulate --scenario three_task --seed 7 -o " + rec).exit_code, 0);
  const auto f = cli("filter " + rec + " --no-progress --health " + (tmp / "h.jsonl"));
  ASSERT_EQ(f.exit_code, 0) << f.out;
  EXPECT_EQ(f.out.find("encoder reads"), std::string::npos) << f.out;
  EXPECT_EQ(f.out.find("inconsistent"), std::string::npos) << f.out;
  const std::string text = test::readFile(tmp / "h.jsonl");
  EXPECT_EQ(text.find("\"encoders\""), std::string::npos) << text;
  const auto bad =
      cli("filter " + rec + " --no-progress --health " + (tmp / "no/such/dir/h.jsonl"));
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_EQ(bad.out.find("health:"), std::string::npos) << bad.out;
}

TEST(HealthCli, AGyroBiasIsBlamedOnTheGyroAtStandstillAndEstimated) {
  // A 0.02 rad/s gyro bias: while the chair stands (no encoder tick) omega = 0 is known, so
  // the disagreement is the gyro's (not the encoders'); with the bias state on it is
  // re-estimated and reported in diagnose's words (effect gyro_bias).
  TempDir tmp;
  const std::string rec = tmp / "gb.rawlog", ini = tmp / "gb.ini";
  ASSERT_EQ(
      cli("simulate --scenario three_task --seed 7 --effect gyro_bias:bias_rad_s=0.02 -o " + rec)
          .exit_code,
      0);
  // The shipped configuration estimates the bias (closed until the gyro's alarm).
  const std::string cfg =
      test::readFile(std::string(WHEELCHAIR_SOURCE_DIR) + "/config/wheelchair.ini");
  ASSERT_NE(cfg.find("\nestimate_gyro_bias = 1\n"), std::string::npos);
  test::writeFile(ini, cfg);
  const auto f =
      cli("filter " + rec + " --config " + ini + " --no-progress --health " + (tmp / "h.jsonl"));
  ASSERT_EQ(f.exit_code, 0) << f.out;
  EXPECT_NE(f.out.find("gyro reads higher than the standing chair's 0"), std::string::npos)
      << f.out;
  // The value is checked against the truth with its sd in the JSON below (the first report
  // comes from the first standstill: +0.018 +- 0.003 rad/s).
  EXPECT_NE(f.out.find("too high (bias) since t = 0.3 s"), std::string::npos) << f.out;
  EXPECT_EQ(f.out.find("encoders inconsistent"), std::string::npos) << f.out;
  bool estimated = false;
  std::istringstream lines(test::readFile(tmp / "h.jsonl"));
  for (std::string line; std::getline(lines, line);) {
    const auto e = nlohmann::json::parse(line);
    if (e["sensor"] == "gyro" && e["kind"] == "estimate") {
      estimated = true;
      EXPECT_EQ(e["effect"], "gyro_bias");
      EXPECT_NEAR(e["value"].get<double>(), 0.02, 3 * e["sd"].get<double>());
      EXPECT_LT(e["t_s"].get<double>(), 5.0) << e.dump();  // from the first standstill
    }
  }
  EXPECT_TRUE(estimated);
}

namespace {

/// The paper's faulty chair (encoder fault present from the start, right gearbox friction
/// x1.3, failing sonar) with the fault on `side` reading `scale`, filtered with the SHIPPED
/// configuration (encoder_fault_prior = either: no direction assumed): the side and direction
/// are reported BEFORE the first turn (from the motor currents, WheelchairEkf's
/// encoderFaultDirection; before it the turn at ~15 s decided them, and the first leg was
/// driven at the symmetric common scale, 2.5 % off), within 5 s of the alarm, and the online
/// trajectory error is that of a known side (ATE 0.05 -> 0.01 m on 40 seeds).
///
/// `learn`: the shipped configuration with learn_healthy_encoder_scales set to it ("none", as
/// shipped, or "both": the radii learned from t = 0, which absorbs part of a fault present
/// from the start before the alarm; the healthy wheel must still never be blamed).
void checkFaultFromTheStart(const std::string& side, double scale, const std::string& word,
                            const std::string& learn = "none") {
  SCOPED_TRACE(side + " encoder x" + std::to_string(scale) + ", learn " + learn);
  TempDir tmp;
  const std::string rec = tmp / "f.rawlog", truth = tmp / "f.truth.json";
  const auto sim =
      cli("simulate --scenario three_task --seed 11 --ground-truth-stream --effect "
          "encoder_scale:scale=" +
          std::to_string(scale) + ",side=" + side +
          " --effect motor_asymmetry:side=right,friction_ratio=1.3 --effect "
          "sonar_dropout:probability=0.15,burst_length=3 -o " +
          rec + " --truth " + truth);
  ASSERT_EQ(sim.exit_code, 0) << sim.out;
  std::string ini = test::readFile(std::string(WHEELCHAIR_SOURCE_DIR) + "/config/wheelchair.ini");
  ASSERT_NE(ini.find("\nencoder_fault_prior = either\n"), std::string::npos);
  const std::string key = "\nlearn_healthy_encoder_scales = ";
  const auto at = ini.find(key);
  ASSERT_NE(at, std::string::npos);
  const auto value = at + key.size();
  ini.replace(value, ini.find('\n', value) - value, learn);
  const std::string config = tmp / "wheelchair.ini";
  test::writeFile(config, ini);
  const auto f =
      cli("filter " + rec + " --config " + config + " --no-progress --health " + (tmp / "h.jsonl"));
  ASSERT_EQ(f.exit_code, 0) << f.out;
  const nlohmann::json tj = nlohmann::json::parse(test::readFile(truth));
  const auto& t = tj["trajectory"]["t_s"];
  const auto& w = tj["trajectory"]["omega_rad_s"];
  double turn_s = -1;
  for (std::size_t i = 0; i < t.size(); ++i)
    if (std::abs(w[i].get<double>()) > 0.1) {
      turn_s = t[i].get<double>();
      break;
    }
  ASSERT_GT(turn_s, 10.0);
  double alarm_s = -1, sided_s = -1;
  std::istringstream lines(test::readFile(tmp / "h.jsonl"));
  for (std::string line; std::getline(lines, line);) {
    const auto e = nlohmann::json::parse(line);
    if (e["sensor"] == "encoders" && e["kind"] == "inconsistent" && alarm_s < 0)
      alarm_s = e["t_s"].get<double>();
    if (e["kind"] == "estimate" && e["side"] == (side == "left" ? "right" : "left"))
      ADD_FAILURE() << e.dump();  // the healthy wheel is never blamed
    if (e["kind"] == "estimate" && e["side"] == side && sided_s < 0) {
      sided_s = e["t_s"].get<double>();
      EXPECT_NE(e["text"].get<std::string>().find("% " + word + " (+-"), std::string::npos)
          << e.dump();
      EXPECT_NEAR(e["value"].get<double>(), scale, std::max(3 * e["sd"].get<double>(), 0.01));
    }
  }
  ASSERT_GT(alarm_s, 0) << f.out;
  ASSERT_GT(sided_s, 0) << f.out;
  EXPECT_LT(sided_s, turn_s) << f.out;         // before the turn that used to decide it
  EXPECT_LT(sided_s, alarm_s + 5.0) << f.out;  // within 5 s of the detection
  // Online trajectory error against the simulator's truth (evaluate's ATE, SE2 alignment).
  const auto ev = cli("evaluate " + rec + " --config " + config + " -q --no-baseline --csv -");
  ASSERT_EQ(ev.exit_code, 0) << ev.out;
  std::istringstream rows(ev.out);
  std::string header, row;
  ASSERT_TRUE(static_cast<bool>(std::getline(rows, header)));
  std::vector<std::string> cols;
  for (std::istringstream hs(header); std::getline(hs, row, ',');) cols.push_back(row);
  const auto ate_col = std::find(cols.begin(), cols.end(), "ate_rmse_m") - cols.begin();
  ASSERT_LT(ate_col, static_cast<long>(cols.size())) << header;
  bool ekf = false;
  while (std::getline(rows, row)) {
    std::vector<std::string> c;
    for (std::istringstream rs(row); std::getline(rs, header, ',');) c.push_back(header);
    if (c.size() > static_cast<std::size_t>(ate_col) &&
        std::find(c.begin(), c.end(), "ekf") != c.end()) {
      ekf = true;
      EXPECT_LT(std::stod(c[ate_col]), 0.02) << row;  // 0.05 m with the side decided at the turn
    }
  }
  EXPECT_TRUE(ekf) << ev.out;
}

}  // namespace

TEST(HealthCli, AnEncoderFaultFromTheStartIsSidedFromTheMotorCurrentsBeforeTheTurn) {
  checkFaultFromTheStart("left", 0.95, "short");
}

TEST(HealthCli, AnEncoderReadingLongFromTheStartIsSidedLongBeforeTheTurn) {
  checkFaultFromTheStart("right", 1.05, "long");
}

TEST(HealthCli, AFaultFromTheStartPartlyLearnedAsAHealthyRadiusBlamesTheFaultyWheel) {
  // learn_healthy_encoder_scales = both: k_d is learned from t = 0, so by the alarm (1.7 s) it
  // holds ~2.6 % of the 5 % fault, split symmetrically by the healthy prior of k_s. That is
  // the healthy hypothesis, not a fault estimate: before the fix the monitor reported it as
  // "right encoder reads 1.3 % long since t = 0.0 s" for a left wheel 5 % short (and later
  // reported the right wheel back at 0.0 %). Only the open fault group is reported.
  checkFaultFromTheStart("left", 0.95, "short", "both");
  checkFaultFromTheStart("right", 1.05, "long", "both");
}

namespace {

/// A recording directory of a chair that stands for 3 s and then turns on the spot at
/// 0.01 rad/s (rim speed 2.75 mm/s: a 0.146 mm tick every ~50 ms, so most 20 ms encoder
/// intervals have no tick on either wheel although the chair turns), its gyro reading
/// omega + bias + N(0, 0.005), zero motor currents, a sonar without echo.
std::string writeSlowSpin(const TempDir& tmp, double gyro_bias_rad_s) {
  const std::string dir = tmp / "spin";
  const double dpsi = 2 * M_PI * 30 / (2000.0 * 110), r = 0.17, l = 0.55, w = 0.01;
  auto angle = [&](double t) { return w * std::max(0.0, t - 3.0) * l / 2 / r; };  // rad
  std::ostringstream enc, imu, mot, son;
  enc << "t,right_ticks,left_ticks\n";
  for (int k = 0; k < 1000; ++k) {  // 50 Hz, the wheels' tick phases 0.5 and 0.13 apart
    const double t = 0.01 + 0.02 * k;
    enc << t << ',' << std::floor(angle(t) / dpsi + 0.5) << ','
        << std::floor(-angle(t) / dpsi + 0.13) << '\n';
  }
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.005);
  imu << "t,gyro_z\n";
  mot << "t,current_right,current_left,vrc_right,vrc_left\n";
  for (int k = 0; k < 2000; ++k) {  // 100 Hz
    const double t = 0.005 + 0.01 * k;
    imu << t << ',' << (t > 3 ? w : 0.0) + gyro_bias_rad_s + noise(rng) << '\n';
    mot << t + 0.003 << ",0,0,0,0\n";
  }
  son << "t,range\n";
  for (int k = 0; k < 200; ++k) son << 0.03 + 0.1 * k << ",0\n";
  std::filesystem::create_directories(dir);
  test::writeFile(dir + "/encoders.csv", enc.str());
  test::writeFile(dir + "/imu.csv", imu.str());
  test::writeFile(dir + "/motors.csv", mot.str());
  test::writeFile(dir + "/sonar.csv", son.str());
  return dir;
}

}  // namespace

TEST(HealthCli, WheelsTurningSlowerThanATickPerIntervalAreNotAStandstillForTheGyro) {
  // A tick-free encoder interval is also a slow turn (or a wheel passing through zero speed).
  // Taken as standstill, the turning chair's gyro read as a bias: 12 false gyro alarms in
  // these 17 s on main (and one at 1786 s of the one-hour excite drive). A standstill is a
  // tick-free run of 0.25 s; a real bias is still found during the first 3 s at rest.
  const std::string shipped = std::string(WHEELCHAIR_SOURCE_DIR) + "/config/wheelchair.ini";
  for (const double bias : {0.0, 0.02}) {
    SCOPED_TRACE("gyro bias " + std::to_string(bias));
    TempDir tmp;
    const std::string rec = tmp / "spin.rawlog";
    const auto imp =
        cli("import " + writeSlowSpin(tmp, bias) + " -o " + rec + " --config " + shipped);
    ASSERT_EQ(imp.exit_code, 0) << imp.out;
    const auto f = cli("filter " + rec + " --config " + shipped + " --no-progress --health " +
                       (tmp / "h.jsonl"));
    ASSERT_EQ(f.exit_code, 0) << f.out;
    int gyro_alarms = 0;
    std::istringstream lines(test::readFile(tmp / "h.jsonl"));
    for (std::string line; std::getline(lines, line);) {
      const auto e = nlohmann::json::parse(line);
      if (e["sensor"] == "gyro" && e["kind"] == "inconsistent") {
        ++gyro_alarms;
        EXPECT_LT(e["t_s"].get<double>(), 3.0) << e.dump();  // only while really standing
      }
      EXPECT_NE(e["sensor"], "encoders") << e.dump();
    }
    if (bias == 0) {
      EXPECT_EQ(gyro_alarms, 0) << f.out;
    } else {  // found at rest and estimated
      EXPECT_GE(gyro_alarms, 1) << f.out;
      EXPECT_NE(f.out.find("gyro reads +0.0"), std::string::npos) << f.out;  // +0.019..+0.021
      EXPECT_NE(f.out.find("too high (bias)"), std::string::npos) << f.out;
    }
  }
}
