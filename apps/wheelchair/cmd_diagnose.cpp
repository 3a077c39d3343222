// wheelchair diagnose FILE.rawlog... [--config F] [--validate OTHER.rawlog ...]
//                     --json OUT.json [--write-config CORRECTED.ini] [--report DIR]
// Finds the physics the nominal model leaves out (docs/discovery.md): compares the model with
// the recording channel by channel, locates and names the mismatch from the effect catalogue
// (docs/effects.md), fits its parameters and shows the fit improve on held-out data.
#include "Command.h"
#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/diagnosis/Diagnosis.h"
#include "libwheelchair/io/RawlogIO.h"

#include <fmt/core.h>

#include <filesystem>
#include <fstream>
#include <iostream>

namespace wheelchair::cli {
namespace {

struct DiagnoseOptions {
  std::vector<std::string> inputs, validate;
  std::string config_path, json_path, write_config, report_dir;
};

void writeAtomic(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp);
    if (!f) throw std::runtime_error(fmt::format("{}: cannot write", path));
    f << text;
    if (!f) throw std::runtime_error(fmt::format("{}: write failed", path));
  }
  std::filesystem::rename(tmp, path);
}

int runDiagnose(const DiagnoseOptions& o) {
  const auto cfg = o.config_path.empty() ? config::WheelchairConfig()
                                         : config::WheelchairConfig::load(o.config_path);
  diagnosis::DiagnosisOptions opt;
  opt.loadFromConfig(cfg.ini());
  std::vector<io::Recording> fit, val;
  for (const auto& p : o.inputs) fit.push_back(io::readRawlog(p));
  for (const auto& p : o.validate) val.push_back(io::readRawlog(p));
  auto rep = diagnosis::diagnose(fit, val, cfg, opt);
  if (!o.write_config.empty()) {
    diagnosis::correctedConfig(cfg, rep).save(o.write_config);
    rep.config_written = o.write_config;
  }
  auto j = rep.toJson();
  j["inputs"] = o.inputs;
  j["validate"] = o.validate;
  j["config"] = o.config_path.empty() ? "<nominal>" : o.config_path;
  writeAtomic(o.json_path, j.dump(2) + "\n");
  std::string text;
  text += fmt::format("mismatch: {}\n", rep.mismatch ? "yes" : "no");
  for (const auto& f : rep.findings) {
    text += fmt::format("- {}: {}\n", f.effect, f.description);
    if (!f.effectText().empty()) text += fmt::format("    as effect: {}\n", f.effectText());
  }
  for (const char* ch : {"gyro_vs_encoders", "current_right", "current_left"})
    if (rep.channels.contains(ch) && rep.channels[ch]["before"].contains("rms"))
      text += fmt::format("  {} validation rms: before {:.4g}, after {:.4g}\n", ch,
                          rep.channels[ch]["before"]["rms"].get<double>(),
                          rep.channels[ch]["after"]["rms"].get<double>());
  if (rep.validation.contains("trajectory_full_recordings")) {
    auto& t = rep.validation["trajectory_full_recordings"];
    for (size_t k = 0; k < t["before"].size(); ++k)
      text += fmt::format(
          "  recording {}: odometry terminal error {:.3f} m -> {:.3f} m, encoder+gyro {:.3f} m -> "
          "{:.3f} m\n",
          k, t["before"][k]["odometry_terminal_m"].get<double>(),
          t["after"][k]["odometry_terminal_m"].get<double>(),
          t["before"][k]["encoder_gyro_terminal_m"].get<double>(),
          t["after"][k]["encoder_gyro_terminal_m"].get<double>());
  }
  if (!rep.config_written.empty()) text += fmt::format("wrote {}\n", rep.config_written);
  text += fmt::format("wrote {}\n", o.json_path);
  std::cout << text;
  if (!o.report_dir.empty()) {
    std::filesystem::create_directories(o.report_dir);
    writeAtomic(o.report_dir + "/summary.txt", text);
    writeAtomic(o.report_dir + "/diagnosis.json", j.dump(2) + "\n");
  }
  return kExitOk;
}

const RegisterCommand reg{Command{
    "diagnose",
    "Find the physics the model leaves out: locate, name, fit and validate model extensions",
    [](CLI::App& sub) -> std::function<int()> {
      auto o = std::make_shared<DiagnoseOptions>();
      sub.add_option("inputs", o->inputs, "Recording(s) of one vehicle to fit on")->required();
      sub.add_option(
          "--config", o->config_path,
          "Configuration INI (default: the nominal vehicle); [diagnosis] holds the options");
      sub.add_option("--validate", o->validate,
                     "Held-out recording(s) for the before/after comparison (default: the last 30% "
                     "of each input)");
      sub.add_option("--json", o->json_path, "Write the findings as JSON here")->required();
      sub.add_option("--write-config", o->write_config,
                     "Write the configuration with a [model_extensions] section here");
      sub.add_option("--report", o->report_dir,
                     "Write a summary and the full JSON into this directory");
      return [o] { return runDiagnose(*o); };
    }}};

}  // namespace
}  // namespace wheelchair::cli
