// A small seeded discovery campaign (the full one: bench/discovery_campaign, docs/discovery.md).
#include "libwheelchair/diagnosis/Campaign.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <iostream>

using namespace wheelchair;

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
