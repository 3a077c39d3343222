// The discovery campaign of `wheelchair diagnose` (docs/discovery.md): simulated drives with
// concealed catalogue effects at small random magnitudes, scored for correct naming,
// parameter error and false alarms.
//
//   build-diag/bench/discovery_campaign [--runs N] [--pairs N] [--clean N] [--seed S]
//        [--duration S] [--effects a,b,...] [--config F] [--json OUT] [-v]
#include "libwheelchair/diagnosis/Campaign.h"

#include <fstream>
#include <iostream>
#include <sstream>

using namespace wheelchair;

int main(int argc, char** argv) {
  diagnosis::CampaignOptions o;
  std::string cfg_path, json_path;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::runtime_error("missing value after " + a);
      return argv[++i];
    };
    if (a == "--runs")
      o.runs_per_effect = std::stoi(next());
    else if (a == "--pairs")
      o.pair_runs = std::stoi(next());
    else if (a == "--clean")
      o.clean_runs = std::stoi(next());
    else if (a == "--seed")
      o.seed = std::stoull(next());
    else if (a == "--duration")
      o.duration_s = std::stod(next());
    else if (a == "--config")
      cfg_path = next();
    else if (a == "--json")
      json_path = next();
    else if (a == "--scenarios" || a == "--effects") {
      std::vector<std::string> v;
      std::stringstream ss(next());
      for (std::string t; std::getline(ss, t, ',');) v.push_back(t);
      (a == "--effects" ? o.effects : o.scenarios) = v;
    } else if (a == "-v")
      o.verbose = true;
    else {
      std::cerr << "usage: discovery_campaign [--runs N] [--pairs N] [--clean N] [--seed S] "
                   "[--duration S] "
                   "[--effects a,b] [--scenarios a,b] [--config F] [--json OUT] [-v]\n";
      return 2;
    }
  }
  auto cfg =
      cfg_path.empty() ? config::WheelchairConfig() : config::WheelchairConfig::load(cfg_path);
  diagnosis::DiagnosisOptions dopt;
  dopt.loadFromConfig(cfg.ini());
  auto res = diagnosis::runCampaign(cfg, o, dopt);
  nlohmann::json summary = res;
  summary.erase("cases");
  std::cout << summary.dump(2) << "\n";
  if (!json_path.empty()) std::ofstream(json_path) << res.dump(1) << "\n";
  return 0;
}
