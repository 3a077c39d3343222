// Command-response discovery (libwheelchair/diagnosis/CommandResponse.h):
//  - synthetic recordings whose drive has a known delay, lag and turn-in-place gain: the terms
//    are found with their parameters and the open-loop drift improves on held-out recordings;
//  - a nominal drive (velocities equal the commands): nothing is reported (false alarms);
//  - the bundled MRCLAM slice (datasets/mrclam): runs on real data, JSON contract;
//  - the full dataset (all five robots, two splits) when WHEELCHAIR_MRCLAM_REPORT is set:
//    prints the numbers of docs/real-data.md (skipped otherwise: it takes ~1 min).
#include "libwheelchair/diagnosis/CommandResponse.h"
#include "libwheelchair/io/MrclamImport.h"
#include "libwheelchair/model/CommandDriven.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <random>
#include <set>

namespace wheelchair::diagnosis {
namespace {

namespace fs = std::filesystem;

// Commands like MRCLAM's: piecewise-constant segments of straight, arc and turn-in-place at
// 100 Hz with (0,0) blips once a second; ground truth from `truth` at 60 Hz.
io::Recording synthetic(const model::CommandResponseParams& truth, unsigned seed, double T_s,
                        bool blips_ignored) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(0, 1);
  io::Recording rec;
  double t = 0, seg_end = 0;
  double v = 0, w = 0;
  while (t < T_s) {
    if (t >= seg_end) {
      const double r = U(rng);
      if (r < 0.35)
        v = 0.05 + 0.1 * U(rng), w = 0;
      else if (r < 0.7)
        v = 0.05 + 0.1 * U(rng), w = (U(rng) - 0.5) * 1.0;
      else if (r < 0.85)
        v = 0, w = (U(rng) < 0.5 ? -1 : 1) * (0.3 + 0.5 * U(rng));
      else
        v = 0, w = 0;
      seg_end = t + 1 + 4 * U(rng);
    }
    const bool blip = std::fmod(t, 1.0) < 0.015;
    rec.joystick.push_back({t, blip ? 0.0 : v, blip ? 0.0 : w});
    t += 0.01;
  }
  model::CommandSignalOptions so;
  so.drop_short_zero_runs = blips_ignored;
  std::vector<model::CommandSample> rows;
  for (const auto& j : rec.joystick) rows.push_back({j.t_s, j.v_cmd_m_s, j.omega_cmd_rad_s});
  const model::CommandSignal sig(rows, so);
  const model::CommandDrivenModel m(truth);
  model::CommandState x = model::CommandState::Zero();
  const double dt = 0.001;
  double next_gt = 0;
  for (double tt = 0; tt < T_s; tt += dt) {
    if (tt >= next_gt) {
      rec.ground_truth.push_back({tt, x(0), x(1), std::remainder(x(2), 2 * M_PI)});
      next_gt += 1.0 / 60;
    }
    x = m.step(x, m.target(sig, tt + dt / 2), dt);
  }
  return rec;
}

model::CommandResponseParams drive() {
  model::CommandResponseParams p;
  p.v.delay_s = 0.2;
  p.v.time_constant_s = 0.3;
  p.omega.delay_s = 0.25;
  p.omega.time_constant_s = 0.15;
  p.omega_gain[static_cast<int>(model::CommandKind::TurnInPlace)] = 0.7;
  return p;
}

const CommandResponseFinding* find(const CommandResponseResult& r, const std::string& effect,
                                   const std::string& channel, const std::string& kind = "") {
  for (const auto& f : r.findings)
    if (f.effect == effect && f.channel == channel && (kind.empty() || f.kind == kind)) return &f;
  return nullptr;
}

TEST(CommandResponse, FindsDelayLagAndTurnInPlaceScaleAndImprovesHeldOut) {
  const auto truth = drive();
  const auto fit = {synthetic(truth, 1, 240, true), synthetic(truth, 2, 240, true)};
  const auto val = {synthetic(truth, 3, 240, true)};
  const auto r = diagnoseCommandResponse(fit, val, {});
  std::cout << r.toJson().dump(2) << "\n";
  const auto* lv = find(r, "actuator_lag", "v");
  const auto* lw = find(r, "actuator_lag", "omega");
  ASSERT_TRUE(lv && lw);
  EXPECT_NEAR(lv->parameters.at("delay_s"), 0.2, 0.02);
  EXPECT_NEAR(lv->parameters.at("time_constant_s"), 0.3, 0.03);
  EXPECT_NEAR(lw->parameters.at("delay_s"), 0.25, 0.02);
  EXPECT_NEAR(lw->parameters.at("time_constant_s"), 0.15, 0.03);
  const auto* g = find(r, "command_gain", "omega", "turn_in_place");
  ASSERT_TRUE(g);
  EXPECT_NEAR(g->parameters.at("scale"), 0.7, 0.03);
  EXPECT_TRUE(find(r, "ignored_zero_commands", "v+omega"));
  EXPECT_FALSE(find(r, "command_gain", "v"));
  EXPECT_FALSE(find(r, "deadband", "v"));
  EXPECT_LT(r.fit_after.drift_10s_m, 0.5 * r.fit_before.drift_10s_m);
  EXPECT_LT(r.fit_after.heading_drift_10s_deg, 0.5 * r.fit_before.heading_drift_10s_deg);
  const auto j = r.toJson();
  for (const char* k :
       {"drift_10s_m", "drift_60s_m", "heading_drift_10s_deg", "heading_drift_60s_deg"}) {
    EXPECT_TRUE(j["fit_before"].contains(k));
    EXPECT_TRUE(j["fit_after"].contains(k));
  }
}

// "Never a false or extra finding": the drive has a lag on both channels, a turn-in-place
// gain and ignores the blips -- nothing else. Noise-free ground truth used to give extra terms
// (command_gain omega arc = 1.000003, unmodeled omega_cmd = -2e-6): the likelihood ratio on the
// residual sum of squares is scale-free, so numerical residue of 1e-6 rad/s was "significant".
// The window measurement model now carries its noise floor (differenced motion-capture noise +
// the time resolution of the model's window means; compareNestedWithFloor).
void expectExactlyTheDrivesTerms(const CommandResponseResult& r) {
  std::set<std::string> got;
  for (const auto& f : r.findings) got.insert(f.effect + "/" + f.channel + "/" + f.kind);
  const std::set<std::string> want = {"actuator_lag/v/", "actuator_lag/omega/",
                                      "command_gain/omega/turn_in_place",
                                      "ignored_zero_commands/v+omega/"};
  EXPECT_EQ(got, want);
}

TEST(CommandResponse, NoExtraFindingsNoiseFree) {
  const auto truth = drive();
  const auto r =
      diagnoseCommandResponse({synthetic(truth, 1, 240, true), synthetic(truth, 2, 240, true)},
                              {synthetic(truth, 3, 240, true)}, {});
  expectExactlyTheDrivesTerms(r);
  for (const auto& f : r.findings) {
    EXPECT_TRUE(f.validated) << f.effect;
    EXPECT_FALSE(f.uncertainty.empty() && f.effect != "ignored_zero_commands") << f.effect;
  }
}

TEST(CommandResponse, NoExtraFindingsWithMotionCaptureNoise) {
  // Vicon-like noise: 1 mm in position, 0.3 deg in heading, on every pose.
  const auto truth = drive();
  auto noisy = [&](unsigned seed) {
    auto rec = synthetic(truth, seed, 240, true);
    std::mt19937 rng(seed + 100);
    std::normal_distribution<double> n(0, 1);
    for (auto& g : rec.ground_truth) {
      g.x_m += 0.001 * n(rng);
      g.y_m += 0.001 * n(rng);
      g.phi_rad = std::remainder(g.phi_rad + 0.3 * M_PI / 180 * n(rng), 2 * M_PI);
    }
    return rec;
  };
  const auto r = diagnoseCommandResponse({noisy(1), noisy(2)}, {noisy(3)}, {});
  expectExactlyTheDrivesTerms(r);
  EXPECT_GT(r.noise_floor_omega_rad_s, 0.01);
  const auto* lw = find(r, "actuator_lag", "omega");
  ASSERT_TRUE(lw);
  EXPECT_NEAR(lw->parameters.at("delay_s"), 0.25, 0.02);
  // The reported 1-sigma covers the error (3 sigma).
  EXPECT_LT(std::abs(lw->parameters.at("delay_s") - 0.25),
            3 * lw->uncertainty.at("delay_s") + 0.005);
}

TEST(CommandResponse, NominalDriveGivesNoFindings) {
  const model::CommandResponseParams nominal;
  const auto r = diagnoseCommandResponse({synthetic(nominal, 4, 180, false)},
                                         {synthetic(nominal, 5, 120, false)}, {});
  for (const auto& f : r.findings) ADD_FAILURE() << "false alarm: " << f.effect << " " << f.channel;
  EXPECT_LT(r.fit_before.drift_10s_m, 1e-3);
}

TEST(CommandResponse, RejectsRecordingsWithoutGroundTruth) {
  io::Recording a;
  a.joystick.push_back({0, 0, 0});
  EXPECT_THROW(diagnoseCommandResponse({a}, {a}, {}), std::invalid_argument);
}

TEST(CommandResponse, BundledMrclamSlice) {
  const std::string dir = std::string(WHEELCHAIR_SOURCE_DIR) + "/datasets/mrclam";
  const auto r3 = io::importMrclam(dir, 3), r4 = io::importMrclam(dir, 4);
  const auto r = diagnoseCommandResponse({r3}, {r4}, {});
  std::cout << r.toJson().dump(2) << "\n";
  EXPECT_GT(r.fit_windows, 100u);
  EXPECT_GT(r.fit_before.n_10s, 3u);
  // Real data: the nominal unicycle is visibly wrong (findings). 50 s of one robot is too
  // little to show a held-out drift improvement (docs/real-data.md); the full-data report does.
  EXPECT_FALSE(r.findings.empty());
  EXPECT_TRUE(std::isfinite(r.fit_after.drift_10s_m));
}

// Full data: WHEELCHAIR_MRCLAM_REPORT=1 ./test_diagnosis --gtest_filter='*FullDataset*'
TEST(CommandResponse, FullDatasetReport) {
  const std::string dir = "/work/shared/datasets/mrclam/MRCLAM_Dataset6";
  if (!std::getenv("WHEELCHAIR_MRCLAM_REPORT") || !fs::is_directory(dir))
    GTEST_SKIP() << "set WHEELCHAIR_MRCLAM_REPORT=1 with the full dataset at " << dir;
  std::vector<io::Recording> R;
  for (int i = 1; i <= 5; ++i) R.push_back(io::importMrclam(dir, i));
  const std::vector<std::pair<std::vector<int>, std::vector<int>>> splits = {
      {{1, 2, 3}, {4, 5}}, {{3, 4, 5}, {1, 2}}, {{2, 4}, {1, 3, 5}}};
  for (const auto& [fi, vi] : splits) {
    std::vector<io::Recording> F, V;
    for (int i : fi) F.push_back(R[i - 1]);
    for (int i : vi) V.push_back(R[i - 1]);
    const auto r = diagnoseCommandResponse(F, V, {});
    std::cout << "=== fit";
    for (int i : fi) std::cout << " " << i;
    std::cout << " validate";
    for (int i : vi) std::cout << " " << i;
    std::cout << "\n" << r.toJson().dump(2) << "\n";
    // Measured (docs/real-data.md): heading drift improves on held-out robots; position
    // drift does not reliably (the v response depends on |omega|: reported `unmodeled`).
    EXPECT_LT(r.fit_after.heading_drift_10s_deg, r.fit_before.heading_drift_10s_deg);
  }
}

}  // namespace
}  // namespace wheelchair::diagnosis
