// wheelchair report FILE.rawlog -o DIR [--config F] [--at SECONDS] [--alignment A]
//                   [--truth T.json] [--no-3d]
// Headless PNG figures like the paper's Fig. 5-8 plus index.md with the metrics table and the
// configuration used (libwheelchair/visualization/Report.h, docs/visualization.md).
#include "AlignmentOption.h"
#include "Command.h"
#include "FullProgram.h"

#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/RawlogStream.h"

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/evaluation/Batch.h"
#include "libwheelchair/visualization/Report.h"

#include <fmt/core.h>

#include <iostream>
#include <memory>

namespace wheelchair::cli {
namespace {

struct ReportCliOptions {
  std::string file, out_dir, config_path, alignment = "se2", truth;
  double at_s = NAN;
  bool no_3d = false;
  bool salvage = false;
};

int runReport(const ReportCliOptions& o) {
  visualization::ReportOptions ro;
  if (!parseAlignmentFor("report", o.alignment, ro.metrics)) return kExitUsage;
  const auto cfg = o.config_path.empty() ? config::WheelchairConfig()
                                         : config::WheelchairConfig::load(o.config_path);
  ro.out_dir = o.out_dir;
  ro.scene3d = !o.no_3d;
  ro.truth_path = o.truth;
  // The rawlog read as a stream: the figures' series, not the recording nor every estimate.
  const io::RecordingSummary sum = scanRawlogFor("report", o.file, o.salvage);
  const auto d = visualization::loadDriveStreamed(o.file, sum, cfg, ro.metrics, o.truth, o.at_s);
  if (std::isfinite(o.at_s)) ro.at_s = d.t0_s + o.at_s;
  const auto r = visualization::writeReport(d, ro);
  for (const auto& f : r.figures) fmt::print("wrote {}\n", f);
  fmt::print("wrote {}\n", r.index_path);
  for (const auto& n : r.notes) fmt::print(stderr, "wheelchair report: {}\n", n);
  return kExitOk;
}

const RegisterCommand reg{Command{
    "report", fullOnlyDescription("report"), [](CLI::App& sub) -> std::function<int()> {
      auto o = std::make_shared<ReportCliOptions>();
      sub.add_option("file", o->file, "Rawlog recording")->required();
      sub.add_option("-o,--output", o->out_dir, "Output directory")->required();
      sub.add_option("--config", o->config_path, "Configuration INI (default: nominal vehicle)");
      sub.add_option("--at", o->at_s,
                     "Time of Fig. 7 and the 3-D snapshot, s since the start of the drive "
                     "(default: inside the obstacle-estimate span)");
      sub.add_option("--alignment", o->alignment,
                     "Metrics table: none | origin | se2 | se2-first:S")
          ->default_val("se2");
      sub.add_option("--truth", o->truth,
                     "Simulator truth JSON (default FILE.truth.json if present)");
      sub.add_flag("--no-3d", o->no_3d, "Skip the offscreen 3-D snapshot");
      sub.add_flag("--salvage", o->salvage, kSalvageHelp);
      return [o] { return runReport(*o); };
    }}};

}  // namespace
}  // namespace wheelchair::cli
