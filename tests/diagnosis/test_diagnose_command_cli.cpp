// `wheelchair diagnose` on command-driven recordings (MRCLAM imports: JOYSTICK commands +
// GROUND_TRUTH Vicon poses, no motor currents) through the CLI: the command-response analyser
// runs and writes the issue-7 JSON (mismatch, findings with effect / description / channels /
// segments / parameters / uncertainty / evidence / fit_before / fit_after, config_written),
// with the held-out open-loop drift keys; --write-config writes [mrclam_response], which the
// command-driven EKF reads back. Full data (/work/shared/datasets/mrclam, not in the repo or
// CI): fit on robots 1-3, validate on 4-5 -> the held-out heading drift improves.
#include "libwheelchair/estimation/CommandDrivenEkf.h"

#include "../common/TestUtil.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

namespace {

namespace fs = std::filesystem;

int sh(const std::string& cmd) {
  return std::system((cmd + " > /dev/null 2>&1").c_str());
}

nlohmann::json readJson(const fs::path& p) {
  std::ifstream f(p);
  return nlohmann::json::parse(f);
}

void expectSchema(const nlohmann::json& j) {
  for (const char* k : {"mismatch", "findings", "config_written", "fit_before", "fit_after"})
    EXPECT_TRUE(j.contains(k)) << k;
  for (const char* k :
       {"drift_10s_m", "drift_60s_m", "heading_drift_10s_deg", "heading_drift_60s_deg"}) {
    EXPECT_TRUE(j["fit_before"].contains(k)) << k;
    EXPECT_TRUE(j["fit_after"].contains(k)) << k;
  }
  for (const auto& f : j["findings"]) {
    for (const char* k : {"effect", "description", "channels", "segments", "parameters",
                          "uncertainty", "evidence", "fit_before", "fit_after"})
      EXPECT_TRUE(f.contains(k)) << k << " in " << f.dump();
    EXPECT_FALSE(f["description"].get<std::string>().empty());
    for (const char* k : {"drift_10s_m", "heading_drift_10s_deg"}) {
      EXPECT_TRUE(f["fit_before"].contains(k)) << f["effect"];
      EXPECT_TRUE(f["fit_after"].contains(k)) << f["effect"];
    }
    if (f["effect"] == "actuator_lag") {
      EXPECT_TRUE(f["parameters"].contains("delay_s"));
      EXPECT_TRUE(f["parameters"].contains("time_constant_s"));
      EXPECT_TRUE(f["uncertainty"].contains("delay_s"));
    }
  }
}

// Issue 16: no reported finding makes its own held-out prediction worse (window residual of
// its channel, open-loop drift at 10 s and 60 s, position and heading).
// Every finding carries its held-out prediction (at least the 10-s drift and its channel's
// window residual, with and without it).
void expectHeldOutRule(const nlohmann::json& j) {
  for (const auto& f : j["findings"]) {
    int carried = 0;
    for (const char* k : {"drift_10s_m", "drift_60s_m", "heading_drift_10s_deg",
                          "heading_drift_60s_deg", "validation_rms_m_s", "validation_rms_rad_s"}) {
      if (!f["fit_before"].contains(k) || !f["fit_after"].contains(k)) continue;
      const auto &b = f["fit_before"][k], &a = f["fit_after"][k];
      if (!b.is_number() || !a.is_number()) continue;  // NaN (no 60-s window) is written as null
      ++carried;
      EXPECT_LE(a.get<double>(), b.get<double>() + 1e-9) << f["effect"] << " " << k;
    }
    EXPECT_GE(carried, 2) << "no held-out prediction carried by " << f.dump();
  }
}

}  // namespace

TEST(DiagnoseCommandCli, BundledMrclamSliceSchema) {
  const std::string cli = WHEELCHAIR_CLI;
  const std::string data = std::string(WHEELCHAIR_SOURCE_DIR) + "/datasets/mrclam";
  const wheelchair::test::TempDir tmp;
  const fs::path& d = tmp.path();
  for (int r : {3, 4})
    ASSERT_EQ(sh(cli + " import --format mrclam " + data + " --robot " + std::to_string(r) +
                 " -o " + (d / ("r" + std::to_string(r) + ".rawlog")).string()),
              0);
  const fs::path json = d / "out.json", ini = d / "corrected.ini";
  ASSERT_EQ(sh(cli + " diagnose " + (d / "r3.rawlog").string() + " --validate " +
               (d / "r4.rawlog").string() + " --config " + WHEELCHAIR_SOURCE_DIR +
               "/config/mrclam.ini --json " + json.string() + " --write-config " + ini.string()),
            0);
  const auto j = readJson(json);
  expectSchema(j);
  EXPECT_TRUE(j["mismatch"].get<bool>());  // the nominal unicycle is visibly wrong
  // The turn-rate lag is found: a finding, or (46 s, 8 held-out 10-s windows) a term that
  // lowers the left-out window residual but fails the held-out trajectory gate -- then it is
  // listed with its numbers and is not in the corrected model.
  bool lag = false, lag_rejected = false;
  for (const auto& f : j["findings"]) lag |= f["effect"] == "actuator_lag";
  for (const auto& f : j["info"].value("command_response_rejected", nlohmann::json::array()))
    if (f["effect"] == "actuator_lag" && f["channel"] == "omega") {
      lag_rejected = true;
      const auto& cv = f["heldout"]["cross_validation"];
      EXPECT_LT(cv["window_rss_with"].get<double>(), cv["window_rss_without"].get<double>());
      EXPECT_FALSE(f["heldout"]["validation"].empty());
    }
  EXPECT_TRUE(lag || lag_rejected);
  expectHeldOutRule(j);
  EXPECT_EQ(j["config_written"], ini.string());
  EXPECT_EQ(j["info"]["analyser"], "command_response");
  // What could and could not be tested (issue 16 item 1): commands vs motion only; the others
  // name the missing streams (MRCLAM: no encoders, no gyro, no motor currents).
  for (const auto& c : j["info"]["comparisons"]) {
    const bool cmd = c["comparison"] == "commands vs motion";
    EXPECT_EQ(c["tested"].get<bool>(), cmd) << c.dump();
    if (!cmd) {
      EXPECT_NE(c["why"].get<std::string>().find("no "), std::string::npos) << c.dump();
    }
  }
  EXPECT_EQ(j["info"]["comparisons"].size(), 6u);
  // The corrected model is what the command-driven EKF reads (nominal when nothing passed).
  const auto eo = wheelchair::estimation::loadCommandDrivenEkfOptions(ini.string());
  EXPECT_EQ(eo.response.isNominal(), !lag);
  EXPECT_NEAR(eo.response.omega.delay_s,
              j["validation"]["command_response"]["model"]["omega"]["delay_s"].get<double>(), 1e-4);
  // Without --validate: held-out last part of each recording.
  const fs::path json2 = d / "out2.json";
  ASSERT_EQ(sh(cli + " diagnose " + (d / "r3.rawlog").string() + " " + (d / "r4.rawlog").string() +
               " --json " + json2.string()),
            0);
  expectSchema(readJson(json2));
}

TEST(DiagnoseCommandCli, FullDatasetHeldOutDriftImproves) {
  const std::string full = "/work/shared/datasets/mrclam/MRCLAM_Dataset6";
  if (!fs::is_directory(full)) GTEST_SKIP() << "full MRCLAM data not at " << full;
  const std::string cli = WHEELCHAIR_CLI;
  const wheelchair::test::TempDir tmp;
  const fs::path& d = tmp.path();
  for (int r = 1; r <= 5; ++r)
    ASSERT_EQ(sh(cli + " import --format mrclam " + full + " --robot " + std::to_string(r) +
                 " -o " + (d / ("r" + std::to_string(r) + ".rawlog")).string()),
              0);
  auto p = [&](int r) { return (d / ("r" + std::to_string(r) + ".rawlog")).string(); };
  // Both directions (docs/discovery.md, issue 16): robots 1-3 -> 4-5 and 4-5 -> 1-3.
  const std::vector<std::pair<std::vector<int>, std::vector<int>>> splits = {{{1, 2, 3}, {4, 5}},
                                                                             {{4, 5}, {1, 2, 3}}};
  for (const auto& [fit, val] : splits) {
    std::string args;
    for (int r : fit) args += " " + p(r);
    for (int r : val) args += " --validate " + p(r);
    const fs::path json = d / "out.json";
    ASSERT_EQ(sh(cli + " diagnose" + args + " --json " + json.string()), 0);
    const auto j = readJson(json);
    expectSchema(j);
    expectHeldOutRule(j);
    // Open-loop drift on the robots not used for fitting: 10 s down by >= 30 %, 60 s and
    // heading better too.
    EXPECT_LT(j["fit_after"]["drift_10s_m"].get<double>(),
              0.7 * j["fit_before"]["drift_10s_m"].get<double>());
    for (const char* k : {"drift_60s_m", "heading_drift_10s_deg", "heading_drift_60s_deg"})
      EXPECT_LT(j["fit_after"][k].get<double>(), j["fit_before"][k].get<double>()) << k;
  }
}
