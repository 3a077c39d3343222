// wheelchair identify FILE.rawlog... [--config F] [--cutoff-hz X] [--omega-source S]
//                     --json OUT.json [--write-config OUT.ini]
// Least-squares identification of the drive model (paper eq. (2)-(6)) from one or several
// recordings stacked together; see docs/identification.md.
#include "Command.h"

#include "libwheelchair/util/AtomicFile.h"
#include "libwheelchair/util/OutputDir.h"

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/identification/Identification.h"
#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/RawlogStream.h"

#include <fmt/core.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>

namespace wheelchair::cli {
namespace {

struct IdentifyOptions {
  std::vector<std::string> inputs;
  std::string config_path, json_path, write_config;
  double cutoff_hz = std::nan("");
  std::string omega_source;
  bool salvage = false;
};

std::string fmtEstimate(const identification::Estimate& e, double z) {
  if (!e.identifiable) return "not identifiable";
  if (!std::isfinite(e.se)) return fmt::format("{:.5g} (se n/a)", e.value);
  return fmt::format("{:.5g} +- {:.2g} ({:.1f} %)", e.value, z * e.se,
                     100 * z * e.se / std::abs(e.value));
}

int runIdentify(const IdentifyOptions& o) {
  const auto cfg = o.config_path.empty() ? config::WheelchairConfig()
                                         : config::WheelchairConfig::load(o.config_path);
  identification::IdentificationOptions opt;
  opt.loadFromConfig(cfg.ini());
  if (std::isfinite(o.cutoff_hz)) opt.cutoff_hz = o.cutoff_hz;
  if (!o.omega_source.empty()) opt.omega_source = o.omega_source;
  opt.validate("command line / [identification]");
  // Files in time order (what import, simulate and capture write) are read as a stream: memory
  // does not grow with the drive (docs/benchmarks.md "Memory"); others are loaded whole.
  bool in_order = true;
  for (const auto& p : o.inputs) {
    std::string warning;
    const io::RecordingSummary sum = io::scanRawlogSalvaging(p, o.salvage, &warning);
    if (!warning.empty()) std::cerr << "wheelchair identify: warning: " << warning << "\n";
    in_order = in_order && sum.lateness_s == 0;
  }
  const std::size_t n_recordings = o.inputs.size();
  identification::IdentificationResult res;
  if (in_order) {
    res = identification::identifyStreamed(o.inputs, cfg, opt, o.inputs);
  } else {
    std::vector<io::Recording> recs;
    for (const auto& p : o.inputs) recs.push_back(io::readRawlogSalvaging(p, true, nullptr));
    res = identification::identify(std::move(recs), cfg, opt, o.inputs);
  }
  auto j = res.toJson();
  j["config"] = o.config_path.empty() ? "<nominal>" : o.config_path;
  std::vector<std::string> changes;
  std::optional<config::WheelchairConfig> out_cfg;
  if (!o.write_config.empty()) {
    out_cfg = identification::identifiedConfig(cfg, res, &changes);
    j["written_config"] = {{"path", o.write_config}, {"changes", changes}};
  }
  util::RemoveUnlessKept outputs;  // a failed config write removes the JSON again
  util::writeFileAtomically(o.json_path, [&](std::ostream& f) { f << j.dump(2) << "\n"; });
  outputs.add(o.json_path);
  if (out_cfg) out_cfg->save(o.write_config);
  outputs.keep();

  const double z = res.z;
  fmt::print(
      "identified from {} recording(s), {} samples used ({} standstill excluded), "
      "cut-off {} Hz; intervals +-{:.2f} se ({:.0f} %)\n",
      n_recordings, res.n_used, res.n_standstill, opt.cutoff_hz, z, 100 * opt.confidence);
  fmt::print("condition number (scaled): full {:.3g}, identifiable subspace {:.3g}; rank {}/5\n",
             res.theta_regression.condition_number,
             res.theta_regression.condition_number_identifiable, res.theta_regression.rank);
  for (int k = 0; k < 5; ++k) fmt::print("  theta_{} = {}\n", k + 1, fmtEstimate(res.theta[k], z));
  fmt::print("  D1 = {}\n  D2 = {}\n", fmtEstimate(res.D1, z), fmtEstimate(res.D2, z));
  for (int k = 0; k < 4; ++k)
    fmt::print("  a{} = {} (direct: {})\n", k + 1, fmtEstimate(res.a_from_theta[k], z),
               fmtEstimate(res.a_direct[k], z));
  const char* sn[2] = {"right", "left"};
  for (int i = 0; i < 2; ++i)
    fmt::print("  {} motor: k/eta = {}, back-EMF k = {} ({} quasi-steady segments)\n", sn[i],
               fmtEstimate(res.motor[i].k_over_eta, z), fmtEstimate(res.motor[i].back_emf_k, z),
               res.motor[i].n_segments);
  for (const auto& nd : res.null_directions) fmt::print("  not identifiable: {}\n", nd.description);
  for (const auto& n : res.notes) fmt::print("  note: {}\n", n);
  fmt::print("wrote {}\n", o.json_path);
  if (out_cfg) {
    for (const auto& c : changes) fmt::print("  {}\n", c);
    fmt::print("wrote {}\n", o.write_config);
  }
  return kExitOk;
}

const RegisterCommand reg{Command{
    "identify",
    "Least-squares identification of the drive model (theta, a1..a4, per-motor constants)",
    [](CLI::App& sub) -> std::function<int()> {
      auto o = std::make_shared<IdentifyOptions>();
      sub.add_option("inputs", o->inputs, "Input rawlog(s), stacked")->required();
      sub.add_option("--config", o->config_path,
                     "Configuration INI (default: the nominal vehicle); [identification] "
                     "section holds the options");
      sub.add_option("--cutoff-hz", o->cutoff_hz,
                     "Zero-phase Butterworth cut-off (Hz), overrides [identification] cutoff_hz");
      sub.add_option("--omega-source", o->omega_source,
                     "Angular velocity from: encoders | gyro (default: [identification] "
                     "omega_source, else encoders)")
          ->check(CLI::IsMember({"encoders", "gyro"}));
      sub.add_option("--json", o->json_path, "Write the full result as JSON here")->required();
      sub.add_option("--write-config", o->write_config,
                     "Write the input configuration with the identified values here");
      sub.add_flag("--salvage", o->salvage, kSalvageHelp);
      return [o] { return runIdentify(*o); };
    }}};

}  // namespace
}  // namespace wheelchair::cli
