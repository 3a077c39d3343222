// wheelchair evaluate FILES... [--config F] [-j N] [--csv OUT.csv] [--json OUT.json]
//                     [--markdown OUT.md] [--alignment none|origin|se2|se2-first:SECONDS]
//                     [--no-baseline] [--truth T.json...]
// Trajectory metrics of every recording and variant (ekf, encoders, encoders_gyro, baseline)
// against the recording's ground truth (libwheelchair/evaluation/Batch.h). Recordings with
// landmark sightings / a landmark map (MRCLAM imports) get the variants ekf (command-driven
// EKF) and commands (open-loop dead reckoning of the commands) instead, against the Vicon
// GROUND_TRUTH stream; their options come from the configuration's [mrclam_filter] /
// [mrclam_response] sections (`--config config/mrclam.ini`). The metrics table goes to stdout
// (`--csv -`: the CSV instead); a variant needing a sensor the recording lacks is listed as
// n/a (not a failure). Exit 1 when any recording (or variant) failed.
#include "AlignmentOption.h"
#include "Command.h"

#include "libwheelchair/util/OutputDir.h"

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/evaluation/Batch.h"

#include <fmt/core.h>

#include <iostream>
#include <memory>

#include <unistd.h>

namespace wheelchair::cli {
namespace {

struct EvaluateOptions {
  std::vector<std::string> files, truth;
  std::string config_path, csv, json, markdown, alignment = "se2";
  unsigned jobs = 0;
  bool no_baseline = false, quiet = false, salvage = false;
};

int runEvaluate(const EvaluateOptions& o) {
  evaluation::BatchOptions bo;
  if (!parseAlignmentFor("evaluate", o.alignment, bo.metrics)) return kExitUsage;
  const auto cfg = o.config_path.empty() ? config::WheelchairConfig()
                                         : config::WheelchairConfig::load(o.config_path);
  if (!o.truth.empty() && o.truth.size() != o.files.size()) {
    fmt::print(stderr,
               "wheelchair evaluate: --truth needs one truth file per recording ({} given "
               "for {} recordings)\n",
               o.truth.size(), o.files.size());
    return kExitUsage;
  }
  for (std::size_t i = 0; i < o.truth.size(); ++i) bo.truth[o.files[i]] = o.truth[i];
  bo.jobs = o.jobs;
  bo.baseline = !o.no_baseline;
  bo.salvage = o.salvage;
  bo.warning = [](const std::string& w) {
    fmt::print(stderr, "wheelchair evaluate: warning: {}\n", w);
  };
  if (!o.quiet && isatty(STDERR_FILENO)) {
    bo.progress = [](std::size_t done, std::size_t total, const std::string& file) {
      const int width = 30;
      const int filled = static_cast<int>(width * done / (total ? total : 1));
      fmt::print(stderr, "\r[{}{}] {}/{} {:<40.40}", std::string(filled, '#'),
                 std::string(width - filled, '.'), done, total, file);
      if (done == total) fmt::print(stderr, "\n");
      std::fflush(stderr);
    };
  }
  const auto res = evaluation::runBatch(o.files, cfg, bo);
  // The metrics table on stdout; `--csv -` puts the CSV there instead.
  if (o.csv == "-")
    std::cout << evaluation::batchCsv(res);
  else
    std::cout << evaluation::batchTable(res);
  util::RemoveUnlessKept outputs;  // a failed later write removes the earlier outputs
  if (!o.csv.empty() && o.csv != "-") {
    evaluation::writeBatchCsv(o.csv, res, cfg);
    outputs.add(o.csv);
    outputs.add(o.csv + ".config.ini");
  }
  if (!o.json.empty()) {
    evaluation::writeBatchJson(o.json, res, cfg);
    outputs.add(o.json);
  }
  if (!o.markdown.empty()) evaluation::writeBatchMarkdown(o.markdown, res, cfg);
  outputs.keep();
  for (const auto& r : res.rows)
    if (!r.error.empty())
      std::cerr << "wheelchair evaluate: " << r.recording
                << (r.variant.empty() ? "" : " [" + r.variant + "]") << ": " << r.error << "\n";
  std::size_t not_applicable = 0;
  for (const auto& r : res.rows) not_applicable += r.not_applicable.empty() ? 0 : 1;
  if (!o.quiet)
    fmt::print(stderr, "evaluated {} recording(s), {} failed, {} variant(s) not applicable\n",
               res.recordings, res.failed_recordings, not_applicable);
  return res.anyFailed() ? kExitBadInput : kExitOk;
}

const RegisterCommand reg{Command{
    "evaluate",
    "Trajectory metrics (ATE, RPE, drift) of recordings' estimates against ground truth",
    [](CLI::App& sub) -> std::function<int()> {
      auto o = std::make_shared<EvaluateOptions>();
      sub.add_option("files", o->files, "Rawlog recordings")->required();
      sub.add_option("--config", o->config_path,
                     "Configuration INI (default: nominal vehicle; MRCLAM: config/mrclam.ini)");
      sub.add_option("-j,--jobs", o->jobs, "Parallel jobs (default: all cores)")
          ->check(CLI::NonNegativeNumber);
      sub.add_option("--csv", o->csv,
                     "CSV output (+ OUT.csv.config.ini with the configuration); - : the CSV on "
                     "stdout instead of the table");
      sub.add_option("--json", o->json, "JSON output (includes the full configuration)");
      sub.add_option("--markdown", o->markdown, "Markdown table (includes the configuration)");
      sub.add_option("--alignment", o->alignment, "none | origin | se2 | se2-first:SECONDS")
          ->default_val("se2");
      sub.add_flag("--no-baseline", o->no_baseline, "Skip the baseline filter");
      sub.add_option("--truth", o->truth,
                     "Simulator truth (NAME.truth.json of `wheelchair simulate`), one per "
                     "recording in order: the ground truth instead of the recording's streams "
                     "(needed when the filters fuse the Pozyx, use_pozyx = 1)")
          ->take_all();
      sub.add_flag("-q,--quiet", o->quiet, "No progress bar or summary on stderr");
      sub.add_flag("--salvage", o->salvage, kSalvageHelp);
      return [o] { return runEvaluate(*o); };
    }}};

}  // namespace
}  // namespace wheelchair::cli
