// wheelchair diagnose FILE.rawlog... [--config F] [--validate OTHER.rawlog ...]
//                     --json OUT.json [--write-config CORRECTED.ini] [--report DIR]
// Finds the physics the nominal model leaves out (docs/discovery.md): compares the model with
// the recording channel by channel, locates and names the mismatch from the effect catalogue
// (docs/effects.md), fits its parameters and shows the fit improve on held-out data.
// Command-driven recordings (JOYSTICK + GROUND_TRUTH, no motor currents, e.g. MRCLAM imports)
// go to the command-response analyser (diagnosis/CommandResponse.h): actuator_lag etc., with
// the held-out open-loop drift in fit_before / fit_after and [mrclam_response] written.
#include "Command.h"
#include "FullProgram.h"
#include "Progress.h"
#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/diagnosis/CommandResponse.h"
#include "libwheelchair/diagnosis/Comparisons.h"
#include "libwheelchair/diagnosis/Diagnosis.h"
#include "libwheelchair/diagnosis/HeldOut.h"
#include "libwheelchair/diagnosis/RawlogInput.h"
#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/RawlogStream.h"
#include "libwheelchair/util/AtomicFile.h"
#include "libwheelchair/util/Memory.h"
#include "libwheelchair/util/OutputDir.h"
#include "libwheelchair/visualization/DiagnosisFigures.h"

#include <fmt/core.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <tuple>

#include <unistd.h>

namespace wheelchair::cli {
namespace {

struct DiagnoseOptions {
  std::vector<std::string> inputs, validate;
  std::string config_path, json_path, write_config, report_dir;
  bool salvage = false;
  bool no_progress = false;
};

// The fit and validation rawlogs, scanned (io::scanRawlogSalvaging: the salvage rule, the
// counts per stream), and the configuration text the first input records. Recordings with
// motor currents are read as streams later, once the configuration is known
// (analyseStreamed(), diagnosis/RawlogInput.h: memory); the others (command-driven recordings
// such as MRCLAM imports, drives without motor currents) are loaded whole here.
struct Inputs {
  std::vector<io::RecordingSummary> fit_sums, val_sums;
  std::vector<io::Recording> fit, val;  ///< loaded whole (!streamed)
  bool streamed = false;
  std::string recorded_config;
};

Inputs readInputs(const DiagnoseOptions& o, Progress& progress) {
  Inputs in;
  const double n_steps = 2.0 * double(o.inputs.size() + o.validate.size());
  double step = 0;
  auto scan = [&](const std::string& p) {
    progress.update(step++ / n_steps, "reading");
    std::string warning;
    io::RecordingSummary sum = io::scanRawlogSalvaging(p, o.salvage, &warning);
    if (!warning.empty()) std::cerr << "wheelchair diagnose: warning: " << warning << "\n";
    return sum;
  };
  for (const auto& p : o.inputs) in.fit_sums.push_back(scan(p));
  for (const auto& p : o.validate) in.val_sums.push_back(scan(p));
  if (!in.fit_sums.empty())
    in.recorded_config = io::headerConfigText(in.fit_sums.front().report.header_text);
  for (const auto& s : in.fit_sums) in.streamed |= s.count(io::StreamKind::Motors) > 0;
  if (in.streamed) return in;
  // The scan applied the salvage rule (and warned): the same rule again, without a warning.
  auto load = [&](const std::string& p) {
    progress.update(step++ / n_steps, "reading");
    return io::readRawlogSalvaging(p, o.salvage, nullptr);
  };
  for (const auto& p : o.inputs) in.fit.push_back(load(p));
  for (const auto& p : o.validate) in.val.push_back(load(p));
  return in;
}

// Recordings with motor currents (never command-driven: the wheelchair stages alone), read as
// streams into what the diagnosis reads (diagnosis/RawlogInput.h), one after the other: the
// same report as analyse() on the loaded recordings.
diagnosis::DiagnosisReport analyseStreamed(const DiagnoseOptions& o, const Inputs& in,
                                           const config::WheelchairConfig& cfg,
                                           const diagnosis::DiagnosisOptions& opt,
                                           Progress& progress) {
  const auto streams = diagnosis::sensorStreams(in.fit_sums);
  const double n_files = double(o.inputs.size() + o.validate.size());
  diagnosis::DiagnosisInput fit, val;
  for (std::size_t i = 0; i < o.inputs.size(); ++i) {
    progress.update(0.5 + 0.5 * double(i) / n_files, "reading");
    diagnosis::readForDiagnosis(o.inputs[i], in.fit_sums[i], cfg, fit);
  }
  for (std::size_t i = 0; i < o.validate.size(); ++i) {
    progress.update(0.5 + 0.5 * double(o.inputs.size() + i) / n_files, "reading");
    diagnosis::readForDiagnosis(o.validate[i], in.val_sums[i], cfg, val);
  }
  progress.tick("diagnosing");
  diagnosis::DiagnosisReport rep = diagnosis::diagnose(std::move(fit), std::move(val), cfg, opt);
  diagnosis::enforceHeldOutRule(rep);       // every analyser: held-out prediction never worse
  diagnosis::addComparisons(streams, rep);  // what could and could not be tested (issue 16)
  return rep;
}

// The wheelchair stages and, for command-driven recordings (JOYSTICK + GROUND_TRUTH, no motor
// currents: e.g. MRCLAM imports), the command-response analyser; encoders, if any, still go
// through the wheelchair stages. Without the command-response analyser the recordings are
// handed to diagnose(), which releases their bulk once it has made its streams (memory).
diagnosis::DiagnosisReport analyse(Inputs& in, const config::WheelchairConfig& cfg,
                                   const diagnosis::DiagnosisOptions& opt) {
  const auto& fit = in.fit;
  const auto& val = in.val;
  bool command_driven = !fit.empty(), any_motors = false, any_encoders = false;
  for (const auto& r : fit) {
    command_driven &= diagnosis::hasCommandResponseData(r);
    any_motors |= !r.motors.empty();
    any_encoders |= !r.encoders.empty();
  }
  for (const auto& r : val) command_driven &= diagnosis::hasCommandResponseData(r);
  command_driven &= !any_motors;
  const auto streams = diagnosis::sensorStreams(fit);  // before diagnose() releases them
  diagnosis::DiagnosisReport rep;
  if (!command_driven)
    rep = diagnosis::diagnose(std::move(in.fit), std::move(in.val), cfg, opt);
  else if (any_encoders)
    rep = diagnosis::diagnose(fit, val, cfg, opt);
  if (command_driven) {
    diagnosis::CommandResponseOptions co;
    co.alpha = opt.alpha;
    co.min_delta_bic = opt.min_bic_drop;
    std::vector<io::Recording> cf = fit, cv = val;
    std::string how = fmt::format("{} --validate recording(s)", val.size());
    if (cv.empty()) {
      std::tie(cf, cv) = diagnosis::splitRecordingsInTime(fit, opt.fit_fraction);
      how = fmt::format("held-out last {:.0f}% of each recording", 100 * (1 - opt.fit_fraction));
    }
    const auto cr = diagnosis::diagnoseCommandResponse(cf, cv, co);
    diagnosis::addCommandResponseFindings(cr, rep);
    rep.info["analyser"] = "command_response";
    rep.info["command_response_validation"] = how;
    if (!any_encoders) rep.info["validation"] = how;
  }
  diagnosis::enforceHeldOutRule(rep);       // every analyser: held-out prediction never worse
  diagnosis::addComparisons(streams, rep);  // what could and could not be tested (issue 16)
  return rep;
}

// The findings, one line each, with what was not tested and why.
std::string findingsText(const diagnosis::DiagnosisReport& rep) {
  std::string text;
  const bool insufficient = rep.info.contains("insufficient_data");
  text += fmt::format("mismatch: {}\n", rep.mismatch   ? "yes"
                                        : insufficient ? "none found (see 'insufficient data')"
                                                       : "no");
  for (const auto& f : rep.findings) {
    text +=
        fmt::format("- {}{}: {}\n", f.effect, f.is_fault ? " (sensor fault)" : "", f.description);
    if (f.command_response && f.fit_before.contains("drift_10s_m"))
      text += fmt::format(
          "    held-out drift without -> with it: 10 s {:.3f} -> {:.3f} m, heading {:.2f} -> "
          "{:.2f} deg\n",
          f.fit_before["drift_10s_m"].get<double>(), f.fit_after["drift_10s_m"].get<double>(),
          f.fit_before["heading_drift_10s_deg"].get<double>(),
          f.fit_after["heading_drift_10s_deg"].get<double>());
    else if (!f.effectText().empty() && !f.is_fault && f.effect != "wheel_geometry")
      text += fmt::format("    as effect: {}\n", f.effectText());
  }
  if (insufficient)
    for (const auto& why : rep.info["insufficient_data"])
      text += fmt::format("insufficient data: {}\n", why.get<std::string>());
  if (rep.info.contains("cannot_tell"))  // readings the data do not tell apart (issue 16)
    for (const auto& why : rep.info["cannot_tell"])
      if (why.is_string()) text += fmt::format("cannot tell: {}\n", why.get<std::string>());
  if (rep.info.contains("kinematic_calibration")) {
    const auto& k = rep.info["kinematic_calibration"];
    if (!k.value("tested", false)) {
      if (!rep.info.contains("comparisons"))
        text += "  not tested: " + k.value("not_tested", std::string()) + "\n";
    } else if (!k.value("accepted", false))
      text += "  kinematic calibration: " +
              k.value("rejected",
                      std::string("no wheel-geometry correction predicts left-out fit data 5 % "
                                  "better than the configured geometry")) +
              "\n";
  }
  // Held-out rule (issue 16): what was found in the fit data but not reported.
  for (const char* key : {"rejected_heldout", "command_response_rejected"})
    if (rep.info.contains(key))
      for (const auto& r : rep.info[key])
        text += fmt::format(
            "  not reported ({}): {}{} -- its held-out prediction is not better\n",
            r.value("rejected_by", std::string("held-out rule")), r.value("effect", std::string()),
            r.contains("channel") ? " (" + r["channel"].get<std::string>() + ")" : std::string());
  if (rep.info.contains("comparisons"))  // every comparison, tested or not and why
    text += diagnosis::comparisonsText(rep);
  else if (rep.info.contains("skipped"))
    for (auto it = rep.info["skipped"].begin(); it != rep.info["skipped"].end(); ++it)
      if (it->is_string()) text += "  not tested: " + it->get<std::string>() + "\n";
  return text;
}

// Before -> after on the validation data: open-loop drift, residual RMS per channel (in the
// units and of the model of the report figures), dead-reckoning terminal errors. (`rep` is
// read through nlohmann::json's operator[], which adds the keys it does not find.)
std::string validationText(diagnosis::DiagnosisReport& rep,
                           const diagnosis::DiagnosisOptions& opt) {
  std::string text;
  if (rep.fit_before.contains("drift_10s_m")) {
    auto d = [](const nlohmann::json& j, const char* k) {
      return j.contains(k) && j[k].is_number() ? j[k].get<double>() : std::nan("");
    };
    text += "  open-loop drift on the validation recordings (median), before -> after:\n";
    text += fmt::format(
        "    10 s: {:.3f} m -> {:.3f} m, heading {:.2f} deg -> {:.2f} deg\n"
        "    60 s: {:.3f} m -> {:.3f} m, heading {:.2f} deg -> {:.2f} deg\n",
        d(rep.fit_before, "drift_10s_m"), d(rep.fit_after, "drift_10s_m"),
        d(rep.fit_before, "heading_drift_10s_deg"), d(rep.fit_after, "heading_drift_10s_deg"),
        d(rep.fit_before, "drift_60s_m"), d(rep.fit_after, "drift_60s_m"),
        d(rep.fit_before, "heading_drift_60s_deg"), d(rep.fit_after, "heading_drift_60s_deg"));
  }
  auto rms = [&](const char* ch, const char* which) {
    const auto& c = rep.channels[ch];
    return c.contains(which) && c[which].contains("rms") ? c[which]["rms"].get<double>()
                                                         : std::nan("");
  };
  for (const char* ch : {"v", "omega"})
    if (rep.channels.contains(ch) && rep.channels[ch]["before"].contains("rms"))
      text += fmt::format("  {} window residual RMS (validation): before {:.4g}, after {:.4g} {}\n",
                          ch, rms(ch, "before"), rms(ch, "after"),
                          rep.channels[ch].value("unit", std::string("(no unit recorded)")));
  if (rep.channels.contains("gyro_vs_encoders") &&
      rep.channels["gyro_vs_encoders"]["before"].contains("rms")) {
    // The channel is in rad per window of window_s: / window_s = rad/s, as in the figure.
    const double w = rep.channels["gyro_vs_encoders"].value("window_s", opt.window_s);
    text += fmt::format(
        "  gyro minus encoder turn rate ({:.2f} s window means), validation RMS: before {:.4g} "
        "rad/s, after {:.4g} rad/s\n",
        w, rms("gyro_vs_encoders", "before") / w, rms("gyro_vs_encoders", "after") / w);
  }
  for (const char* ch : {"current_right", "current_left"})
    if (rep.channels.contains(ch) && rep.channels[ch]["before"].contains("rms"))
      text += fmt::format(
          "  {} model error, validation RMS: nominal model {:.4g} A, corrected {:.4g} A (sensor "
          "corrections alone {:.4g} A)\n",
          ch, rms(ch, "before_nominal"), rms(ch, "after"), rms(ch, "before"));
  if (rep.validation.contains("trajectory_full_recordings")) {
    auto& t = rep.validation["trajectory_full_recordings"];
    const bool gyro = rep.info.contains("streams") && rep.info["streams"].value("gyro", false);
    // The lines show what the sensor corrections of stages 1-2 change; without a gyro or motor
    // currents there are none (the kinematic calibration reports its own held-out errors).
    const bool motors = rep.info.contains("streams") && rep.info["streams"].value("motors", false);
    for (size_t k = 0; (gyro || motors) && k < t["before"].size(); ++k) {
      text += fmt::format("  recording {}: odometry terminal error {:.3f} m -> {:.3f} m", k,
                          t["before"][k]["odometry_terminal_m"].get<double>(),
                          t["after"][k]["odometry_terminal_m"].get<double>());
      if (gyro)  // without a gyro there is no encoder+gyro dead reckoning
        text += fmt::format(", encoder+gyro {:.3f} m -> {:.3f} m",
                            t["before"][k]["encoder_gyro_terminal_m"].get<double>(),
                            t["after"][k]["encoder_gyro_terminal_m"].get<double>());
      text += " (sensor corrections of the gyro stage)\n";
    }
  }
  return text;
}

int runDiagnose(const DiagnoseOptions& o) {
  util::returnLargeBlocksToSystem();  // a long drive's arrays, stage after stage (memory)
  Progress progress(!o.no_progress && isatty(STDERR_FILENO));
  Inputs in = readInputs(o, progress);
  if (!in.streamed) progress.tick("diagnosing");
  // Without --config: the configuration recorded in the first input (e.g. the geometry an
  // importer took from the dataset's metadata), else the nominal vehicle.
  const auto cfg = !o.config_path.empty() ? config::WheelchairConfig::load(o.config_path)
                   : !in.recorded_config.empty()
                       ? config::WheelchairConfig::fromText(in.recorded_config, o.inputs.front())
                       : config::WheelchairConfig();
  diagnosis::DiagnosisOptions opt;
  opt.loadFromConfig(cfg.ini());
  diagnosis::DiagnosisReport rep =
      in.streamed ? analyseStreamed(o, in, cfg, opt, progress) : analyse(in, cfg, opt);
  util::RemoveUnlessKept outputs;  // a failed later write removes the earlier outputs
  if (!o.write_config.empty()) {
    diagnosis::correctedConfig(cfg, rep).save(o.write_config);
    outputs.add(o.write_config);
    rep.config_written = o.write_config;
  }
  auto j = rep.toJson();
  j["inputs"] = o.inputs;
  j["validate"] = o.validate;
  j["config"] = !o.config_path.empty()        ? o.config_path
                : !in.recorded_config.empty() ? "recorded in " + o.inputs.front()
                                              : "<nominal>";
  util::writeFileAtomically(o.json_path, j.dump(2) + "\n");
  outputs.add(o.json_path);
  progress.stop();
  std::string text = findingsText(rep) + validationText(rep, opt);
  if (!rep.config_written.empty()) text += fmt::format("wrote {}\n", rep.config_written);
  text += fmt::format("wrote {}\n", o.json_path);
  std::cout << text;
  if (!o.report_dir.empty()) {
    // Figures, index.md, summary.txt and diagnosis.json (visualization/DiagnosisFigures.h).
    visualization::DiagnosisFigureOptions fo;
    fo.out_dir = o.report_dir;
    fo.summary_text = text;
    fo.diagnosis_options = opt;
    progress.tick("figures");
    const auto fr = visualization::writeDiagnosisFigures(
        j, cfg, diagnosis::correctedConfig(cfg, rep), o.inputs, o.validate, fo);
    progress.stop();
    for (const auto& n : fr.notes) std::cout << "report: " << n << "\n";
    std::cout << fmt::format("wrote {} ({} figures)\n", fr.index_path, fr.figures.size());
  }
  outputs.keep();
  return kExitOk;
}

const RegisterCommand reg{Command{
    "diagnose", fullOnlyDescription("diagnose"), [](CLI::App& sub) -> std::function<int()> {
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
                     "Write the corrected configuration here ([model_extensions]; "
                     "command-driven recordings: [mrclam_response])");
      sub.add_option("--report", o->report_dir,
                     "Write figures (residuals and trajectories before/after), index.md, the "
                     "summary and the full JSON into this directory");
      sub.add_flag("--salvage", o->salvage, kSalvageHelp);
      sub.add_flag("--no-progress", o->no_progress,
                   "No progress display on stderr (it is shown only when stderr is a terminal)");
      return [o] { return runDiagnose(*o); };
    }}};

}  // namespace
}  // namespace wheelchair::cli
