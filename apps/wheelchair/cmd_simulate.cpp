// wheelchair simulate --scenario NAME --seed N [--duration S] [--effect ID:key=value,...]...
//                     [--format rawlog|csv] [--config F] [--supervisory on|off]
//                     [--truth PATH] [--engine model|mujoco] -o OUT
// Runs the truth simulator (libwheelchair/simulation) and writes the recording (a rawlog,
// or a plain-text recording directory) plus the truth (OUT.truth.json unless --truth).
#include "Command.h"

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/RawlogStream.h"
#include "libwheelchair/io/TextFormat.h"
#include "libwheelchair/simulation/MujocoEngine.h"
#include "libwheelchair/simulation/Simulator.h"
#include "libwheelchair/simulation/StreamedRun.h"
#include "libwheelchair/util/OutputDir.h"

#include <fmt/core.h>

#include <array>
#include <iostream>
#include <memory>

namespace wheelchair::cli {
namespace {

struct SimulateOptions {
  std::string scenario, output, truth, config_path, format = "rawlog", supervisory;
  std::string engine = "model";
  uint64_t seed = 1;
  double duration_s = 0;
  std::vector<std::string> effects;
  bool list = false, ground_truth = false;
};

void printCatalogue() {
  fmt::print("scenarios:");
  for (const auto& s : simulation::scenarioNames()) fmt::print(" {}", s);
  fmt::print("\neffects (--effect ID:key=value,...; docs/effects.md):\n");
  for (const auto& e : effects::effectCatalogue()) {
    fmt::print("  {}\n", e.id);
    for (const auto& p : e.params)
      fmt::print("      {:<22} {:<9} {}{}\n", p.name, p.unit, p.description,
                 p.default_value.empty() ? (p.optional ? " (optional)" : " (required)")
                                         : " (default " + p.default_value + ")");
  }
  fmt::print("effects of --engine mujoco only (docs/simulation.md):\n");
  for (const auto& e : simulation::mujocoEffectCatalogue()) {
    fmt::print("  {}\n", e.id);
    for (const auto& p : e.params)
      fmt::print("      {:<22} {:<9} {}{}\n", p.name, p.unit, p.description,
                 p.optional ? " (optional)" : " (required)");
  }
}

int runSimulate(const SimulateOptions& o) {
  if (o.list) {
    printCatalogue();
    return kExitOk;
  }
  if (o.scenario.empty() || o.output.empty()) {
    std::cerr << "wheelchair simulate: --scenario and -o are required (see --help)\n";
    return kExitUsage;
  }
  std::vector<effects::EffectSpec> effects;
  try {
    for (const auto& t : o.effects) effects.push_back(simulation::parseEngineEffect(t, o.engine));
    bool known = false;
    for (const auto& s : simulation::scenarioNames()) known |= s == o.scenario;
    if (!known) (void)simulation::makeScenario(o.scenario, 0, {});  // throws with the list
  } catch (const std::invalid_argument& e) {
    std::cerr << "wheelchair simulate: " << e.what() << "\n";
    return kExitUsage;
  }
  const auto cfg = o.config_path.empty() ? config::WheelchairConfig()
                                         : config::WheelchairConfig::load(o.config_path);
  simulation::SimulationOptions opt;
  opt.loadFromConfig(cfg.ini(), "simulation");
  if (o.supervisory == "on") opt.supervisory.enabled = true;
  if (o.supervisory == "off") opt.supervisory.enabled = false;
  if (o.ground_truth) opt.record_ground_truth = true;
  opt.engine = o.engine;

  const std::string truth_path = o.truth.empty() ? o.output + ".truth.json" : o.truth;
  // A rawlog and the truth are written as the run produces them (memory flat in the drive's
  // length, simulation/StreamedRun.h); the text format holds the recording.
  simulation::SimulationResult res;
  std::array<std::size_t, io::kNumStreams> n{};
  if (o.format == "rawlog") {
    auto run = simulation::simulateToFiles(cfg, o.scenario, o.seed, o.duration_s, effects, opt,
                                           o.output, truth_path);
    res = std::move(run.result);
    n = run.counts;
  } else {
    res = simulation::simulate(cfg, o.scenario, o.seed, o.duration_s, effects, opt);
    util::RemoveUnlessKept outputs;  // a failed truth file removes the recording again
    io::writeTextRecording(res.recording, o.output);
    outputs.add(o.output);
    res.writeTruth(truth_path);
    outputs.keep();
    n = io::summarize(res.recording).counts;
  }

  using io::StreamKind;
  const auto count = [&](StreamKind k) { return n[static_cast<int>(k)]; };
  fmt::print("simulated '{}' seed {} (engine {}): {:.2f} s, supervisory control {}\n", o.scenario,
             o.seed, res.engine, res.duration_s, res.supervisory ? "on" : "off");
  fmt::print("  samples: encoders {}, imu {}, motors {}, sonar {}, pozyx {}, joystick {}\n",
             count(StreamKind::Encoders), count(StreamKind::Imu), count(StreamKind::Motors),
             count(StreamKind::Sonar), count(StreamKind::Pozyx), count(StreamKind::Joystick));
  if (effects.empty()) fmt::print("  effects: none\n");
  for (const auto& e : effects) fmt::print("  effect: {}\n", effects::formatEffect(e));
  const auto& end = res.truth.samples.back();
  fmt::print("  end pose (start frame): x {:.3f} m, y {:.3f} m, phi {:.3f} rad\n", end.x_m, end.y_m,
             end.phi_rad);
  fmt::print("  collisions: {}\n", res.collisions);
  fmt::print("  wrote {} ({}) and truth {}\n", o.output, o.format, truth_path);
  return kExitOk;
}

const RegisterCommand reg{Command{
    "simulate", "Simulate a drive of the chair (truth simulator with effects) into a recording",
    [](CLI::App& sub) -> std::function<int()> {
      auto o = std::make_shared<SimulateOptions>();
      sub.add_option("--scenario", o->scenario,
                     "three_task | excite | square | obstacles (required, no default)");
      sub.add_option("--seed", o->seed, "Random seed (noise, jitter, Pozyx anchor frame)")
          ->default_val(1);
      sub.add_option("--duration", o->duration_s, "Duration in s (default: the scenario's)")
          ->check(CLI::NonNegativeNumber);
      sub.add_option("--effect", o->effects,
                     "Effect ID:key=value,... (repeatable; see --list and docs/effects.md)")
          ->take_all();
      sub.add_option("--format", o->format, "Output format")
          ->check(CLI::IsMember({"rawlog", "csv"}))
          ->default_val("rawlog");
      sub.add_option("--config", o->config_path,
                     "Configuration INI (default: the nominal vehicle); [simulation] options");
      sub.add_option("--supervisory", o->supervisory,
                     "Assist-as-needed supervisory control (default: [simulation] supervisory)")
          ->check(CLI::IsMember({"on", "off"}));
      sub.add_option("--engine", o->engine,
                     "Truth engine: model (torque balance, default) or mujoco (multibody)")
          ->check(CLI::IsMember({"model", "mujoco"}))
          ->default_val("model");
      sub.add_flag("--ground-truth-stream", o->ground_truth,
                   "Also store the true pose as a GROUND_TRUTH stream in the recording");
      sub.add_option("--truth", o->truth, "Truth file (default OUT.truth.json; .csv = table)");
      sub.add_option("-o,--output", o->output, "Output rawlog file or recording directory (csv)");
      sub.add_flag("--list", o->list, "List scenarios and effects, then exit");
      return [o] { return runSimulate(*o); };
    }}};

}  // namespace
}  // namespace wheelchair::cli
