// The discovery campaign of `wheelchair diagnose` (docs/discovery.md): simulated drives with
// concealed catalogue effects at small random magnitudes, scored for correct naming,
// parameter error and false alarms.
//
//   build-diag/bench/discovery_campaign [--runs N] [--pairs N] [--triples N] [--clean N]
//        [--unknown N] [--seed S] [--duration S] [--effects a,b,...] [--engine model|mujoco]
//        [--config F] [--json OUT] [--check-named-rate R] [--check-false-alarms N]
//        [--check-described-rate R] [-v]
//   build-diag/bench/discovery_campaign --case SCENARIO:SEED [--effect SPEC ...] [--engine E]
//
// --case: re-runs ONE campaign drive (the `scenario` and `seed` of a case in the JSON, its
// `truth` effects each as --effect) and prints that case's JSON with the same scoring
// (`engine_correct`, `engine_truth`), e.g.
//   discovery_campaign --engine mujoco --case square:50402
//
// --check-named-rate R: exit 1 unless at least a fraction R of the single-effect drives has
// the concealed effect named (and nothing else of the catalogue; `unmodeled` findings set
// aside); the CTest discovery_campaign_mujoco_smoke runs a small seeded MuJoCo campaign so.
// --check-false-alarms N: exit 1 if any clean drive has a catalogue finding, or more than N
// clean drives have any finding that is not the truth engine's own physics (`engine_false_alarms`:
// on MuJoCo its effective wheel geometry and centre-of-mass current terms, measured on the
// multibody, simulation/MujocoTruth.h, are not false; on the model engine every finding is); CTest
// discovery_campaign_mujoco_clean.
// --check-described-rate R: exit 1 unless a fraction R of the --unknown drives has the effect
// located on its channel and described with its dependence class (CTest
// discovery_campaign_unknown_described).
//
// --engine mujoco: the drives come from the MuJoCo multibody (docs/simulation.md), whose
// physics is not the model the diagnosis fits. --unknown N: N drives with one effect outside
// the catalogue at a random magnitude (simulation/UnknownEffects.h: forward drags, yaw
// frictions, a heading-dependent moment, yaw inertia, a current-sensor offset; on MuJoCo also
// the engine's own castor friction, tyre scrub, rolling resistance, soft tyre, low grip); the
// diagnosis does not know these names. Scored: flagged, located (a reported unmodeled term on
// the effect's channel) and described (with the effect's dependence class), against the
// truth the generator states (unknownEffectTruth). --case with one such effect (the MuJoCo
// engine's own too) adds its `unknown_score`. --unknown-only: the catalogue and clean
// drives of the same command are drawn (same random stream) but not run, so the unknown drives
// are those of the full command, in a fraction of its time.
#include "libwheelchair/diagnosis/Campaign.h"
#include "libwheelchair/simulation/MujocoEngine.h"
#include "libwheelchair/simulation/UnknownEffects.h"

#include <fmt/format.h>

#include <fstream>
#include <iostream>
#include <sstream>

using namespace wheelchair;

int main(int argc, char** argv) {
  diagnosis::CampaignOptions o;
  std::string cfg_path, json_path;
  double check_named_rate = -1, check_described_rate = -1;
  int check_false_alarms = -1;
  std::string one_case;                  // --case SCENARIO:SEED
  std::vector<std::string> one_effects;  // --effect texts, parsed for --engine below
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
    else if (a == "--triples")
      o.triple_runs = std::stoi(next());
    else if (a == "--unknown")
      o.unknown_runs = std::stoi(next());
    else if (a == "--unknown-only")
      o.unknown_only = true;
    else if (a == "--engine")
      o.engine = next();
    else if (a == "--check-named-rate")
      check_named_rate = std::stod(next());
    else if (a == "--check-described-rate")
      check_described_rate = std::stod(next());
    else if (a == "--check-false-alarms")
      check_false_alarms = std::stoi(next());
    else if (a == "--clean")
      o.clean_runs = std::stoi(next());
    else if (a == "--seed")
      o.seed = std::stoull(next());
    else if (a == "--duration")
      o.duration_s = std::stod(next());
    else if (a == "--case")
      one_case = next();
    else if (a == "--effect")
      one_effects.push_back(next());
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
      std::cerr
          << "usage: discovery_campaign [--runs N] [--pairs N] [--triples N] "
             "[--clean N] [--unknown N] [--unknown-only] [--seed S] [--duration S] [--effects a,b] "
             "[--scenarios a,b] [--engine model|mujoco] [--config F] [--json OUT] "
             "[--check-named-rate R] [--check-false-alarms N] [--check-described-rate R] [-v]\n"
             "       discovery_campaign --case SCENARIO:SEED [--effect SPEC ...] [--engine E]\n";
      return 2;
    }
  }
  if (o.engine != "model" && o.engine != "mujoco") {
    std::cerr << "discovery_campaign: --engine must be model or mujoco\n";
    return 2;
  }
  // Physics outside the catalogue, at random magnitudes, with its truth
  // (simulation/UnknownEffects.h).
  o.unknown_effects = [engine = o.engine](std::mt19937_64& rng) {
    return std::vector<effects::EffectSpec>{simulation::randomUnknownEffect(engine, rng)};
  };
  auto cfg =
      cfg_path.empty() ? config::WheelchairConfig() : config::WheelchairConfig::load(cfg_path);
  diagnosis::DiagnosisOptions dopt;
  dopt.loadFromConfig(cfg.ini());
  if (!one_case.empty()) {
    const auto colon = one_case.find(':');
    if (colon == std::string::npos) {
      std::cerr << "discovery_campaign: --case wants SCENARIO:SEED, got " << one_case << "\n";
      return 2;
    }
    const std::string sc = one_case.substr(0, colon);
    const uint64_t seed = std::stoull(one_case.substr(colon + 1));
    // The engine's own effects (castor_friction, tyre_scrub, ...) and those outside the
    // catalogue are valid here too, as in the campaign's `truth`.
    std::vector<effects::EffectSpec> es;
    try {
      for (const auto& t : one_effects) es.push_back(simulation::parseEngineEffect(t, o.engine));
    } catch (const std::invalid_argument& e) {
      std::cerr << "discovery_campaign: --effect: " << e.what() << "\n";
      return 1;
    }
    const auto c = diagnosis::runCase(cfg, sc, seed, o.duration_s, es, dopt, o.engine);
    nlohmann::json j = c.toJson();
    j["scenario"] = sc, j["seed"] = seed;
    if (es.size() == 1) try {  // one effect outside the catalogue: scored as the campaign does
        j["unknown_score"] = diagnosis::unknownEffectScore(es, c.findings, o.engine);
      } catch (const std::invalid_argument&) {  // a catalogue effect: no such score
      }
    std::cout << j.dump(1) << "\n";
    return 0;
  }
  auto res = diagnosis::runCampaign(cfg, o, dopt);
  nlohmann::json summary = res;
  summary.erase("cases");
  std::cout << summary.dump(2) << "\n";
  if (!json_path.empty()) std::ofstream(json_path) << res.dump(1) << "\n";
  int status = 0;
  if (check_false_alarms >= 0) {
    const int fa = res["clean"]["engine_false_alarms"].get<int>();
    const int named = res["clean"]["catalogue_false_alarms"].get<int>();
    const bool bad = fa > check_false_alarms || named > 0;
    std::cerr << "check " << (bad ? "FAILED" : "passed") << ": " << named
              << " clean drive(s) with a catalogue name (none allowed), " << fa
              << " with any finding that is not the engine's physics (at most "
              << check_false_alarms << ")\n";
    if (bad) status = 1;
  }
  if (check_named_rate >= 0) {
    const double rate = res["single_named_rate"].get<double>();
    if (rate < check_named_rate) {
      std::cerr << "check FAILED: named rate " << rate << " < " << check_named_rate << "\n";
      return 1;
    }
    std::cerr << "check passed: named rate " << rate << " >= " << check_named_rate << "\n";
  }
  if (check_described_rate >= 0 && res.contains("unknown")) {
    const double rate = res["unknown"]["described_rate"].get<double>();
    const bool bad = rate < check_described_rate;
    std::cerr << "check " << (bad ? "FAILED" : "passed") << ": out-of-catalogue effects located "
              << "and described " << rate << (bad ? " < " : " >= ") << check_described_rate << "\n";
    if (bad) status = 1;
  }
  return status;
}
