// wheelchair config --dump | --check FILE...
// The configuration keys as the program knows them (config/Options.h): --dump prints every
// registered section with each key's help, unit, range and default as commented INI (the
// reference the config/*.ini templates are checked against); --check loads each FILE
// strictly (unknown sections/keys, malformed or out-of-range values: exit 1 naming file,
// line and key) and loads every options struct from it (their checks across keys too).
#include "Command.h"
#include "libwheelchair/config/Options.h"
#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/diagnosis/Diagnosis.h"
#include "libwheelchair/estimation/CommandDrivenEkf.h"
#include "libwheelchair/estimation/EkfOptions.h"
#include "libwheelchair/identification/Identification.h"
#include "libwheelchair/simulation/Simulator.h"

#include <fmt/core.h>

#include <iostream>

namespace wheelchair::cli {
namespace {

struct ConfigOptions {
  bool dump = false;
  std::vector<std::string> check;
};

int runConfig(const ConfigOptions& o) {
  if (o.dump) {
    std::string out = "# libwheelchair: every configuration key (wheelchair config --dump)\n";
    for (const auto& t : config::registeredOptions()) out += "\n" + t.dump();
    std::cout << out;
  }
  for (const auto& path : o.check) {
    const auto cfg = config::WheelchairConfig::load(path);  // names, numbers, ranges
    // The checks across keys that each struct makes when it is loaded.
    estimation::EkfOptions ekf;
    ekf.loadFromConfig(cfg.ini());
    simulation::SimulationOptions sim;
    sim.loadFromConfig(cfg.ini());
    identification::IdentificationOptions ident;
    ident.loadFromConfig(cfg.ini());
    diagnosis::DiagnosisOptions diag;
    diag.loadFromConfig(cfg.ini());
    estimation::loadCommandDrivenEkfOptions(cfg.ini());
    std::cout << fmt::format("{}: ok\n", path);
  }
  return kExitOk;
}

const RegisterCommand reg{Command{
    "config", "Print every configuration key (--dump) or check configuration files (--check)",
    [](CLI::App& sub) -> std::function<int()> {
      auto o = std::make_shared<ConfigOptions>();
      auto* d = sub.add_flag("--dump", o->dump,
                             "Print every section and key with help, range and default (INI)");
      auto* c = sub.add_option("--check", o->check,
                               "Load these configuration files strictly; exit 1 on the first "
                               "problem, naming file, line and key");
      d->excludes(c);
      sub.require_option(1);
      return [o] { return runConfig(*o); };
    }}};

}  // namespace
}  // namespace wheelchair::cli
