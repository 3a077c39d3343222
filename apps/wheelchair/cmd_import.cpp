// wheelchair import DIR -o FILE.rawlog : plain-text recording -> observations-only rawlog.
#include "Command.h"

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/io/MrclamImport.h"
#include "libwheelchair/io/OptiodomImport.h"
#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/TextFormat.h"

#include <fmt/core.h>

#include <iostream>

namespace wheelchair::cli {
namespace {

struct ImportOptions {
  std::string input, output, config_path, format = "text";
  int robot = 1;
  int run = 1;
  bool strict = false;
  double max_gap_s = -1;  ///< < 0: [import] max_gap_s of the configuration
};

int runImport(const ImportOptions& o) {
  auto cfg = o.config_path.empty() ? config::WheelchairConfig()
                                         : config::WheelchairConfig::load(o.config_path);
  if (o.format == "mrclam") {
    io::MrclamImportReport rep;
    const io::Recording rec = io::importMrclam(o.input, o.robot, &rep);
    io::writeRawlog(rec, o.output, cfg);
    fmt::print("imported {} robot {}: {}\ninto {}\n", o.input, o.robot, rep.summary(), o.output);
    return kExitOk;
  }
  if (o.format == "optiodom") {
    io::OptiodomImportReport rep;
    const io::Recording rec = io::importOptiodom(o.input, o.run, &rep);
    io::applyOptiodomGeometry(rep.geometry, cfg);  // the recording's configuration
    io::writeRawlog(rec, o.output, cfg);
    fmt::print("imported {} run {}: {}\ninto {}\n", o.input, o.run, rep.summary(), o.output);
    return kExitOk;
  }
  if (o.format != "text") {
    std::cerr << "wheelchair import: unknown --format '" << o.format
              << "' (text, mrclam, optiodom)\n";
    return kExitUsage;
  }
  io::TextRecordingReader in(o.input);
  // A forward jump of the timeline above max_gap_s (a clock step, a stalled logger) is refused
  // with file, line and size: filtering across it would silently coast for the whole jump.
  io::ImportOptions imp;
  imp.options().load(cfg.ini());
  const double max_gap_s = o.max_gap_s >= 0 ? o.max_gap_s : imp.max_gap_s;
  in.setMaxGap(max_gap_s);
  io::RawlogWriter out(o.output);
  io::AnySample s;
  bool header_written = false;
  std::size_t n = 0;
  while (in.next(s)) {
    if (!header_written) {
      out.writeHeader(in.meta(), cfg, io::timeOf(s));
      header_written = true;
    }
    out.write(s, cfg);
    ++n;
  }
  const auto warnings = in.warnings();
  if (o.strict) {
    for (const auto& w : warnings)
      if (w.find("timestamps") != std::string::npos) throw std::runtime_error(w + " (--strict)");
  }
  if (!header_written) out.writeHeader(in.meta(), cfg, 0.0);
  out.commit();
  for (const auto& w : warnings) std::cerr << "warning: " << w << "\n";
  fmt::print("imported {} observations from {} into {}\n", n, o.input, o.output);
  return kExitOk;
}

const RegisterCommand reg{Command{
    "import", "Read a plain-text recording directory and write an MRPT rawlog",
    [](CLI::App& sub) -> std::function<int()> {
      auto o = std::make_shared<ImportOptions>();
      sub.add_option("input", o->input, "Recording directory (encoders.csv, imu.csv, ...)")
          ->required();
      sub.add_option("-o,--output", o->output, "Output rawlog file")->required();
      sub.add_option("--config", o->config_path,
                     "Configuration INI (sensor geometry recorded in the rawlog)");
      sub.add_option("--format", o->format,
                     "Input format: text (default; docs/recording-format.md) or mrclam (UTIAS "
                     "MRCLAM dataset directory) or optiodom (OptiOdom experiment directory "
                     "<ID>/ with <ID>_metadata.csv, <ID>.csv, <ID>_run-NN.csv)")
          ->check(CLI::IsMember({"text", "mrclam", "optiodom"}));
      sub.add_option("--robot", o->robot, "MRCLAM robot number (1-5)")->check(CLI::Range(1, 5));
      sub.add_option("--max-gap", o->max_gap_s,
                     "Largest forward jump of the timestamps accepted, s (default: [import] "
                     "max_gap_s of --config, else 5; 0: no limit)")
          ->check(CLI::NonNegativeNumber);
      sub.add_option("--run", o->run, "OptiOdom run number (1..N of the metadata)")
          ->check(CLI::PositiveNumber);
      sub.add_flag("--strict", o->strict,
                   "Fail on out-of-order or duplicated timestamps instead of warning");
      return [o] { return runImport(*o); };
    }}};

}  // namespace
}  // namespace wheelchair::cli
