// wheelchair capture --config CAPTURE.ini -o FILE.rawlog [--duration S] : records every
// source of a capture configuration into a rawlog, continuously (docs/capture.md).
#include "Command.h"
#include "StopSignal.h"

#include "libwheelchair/capture/CaptureSession.h"

#include <fmt/core.h>

#include <atomic>
#include <csignal>
#include <iostream>

namespace wheelchair::cli {
namespace {

struct CaptureCliOptions {
  capture::CaptureOptions o;
};

int runCapture(CaptureCliOptions& c) {
  std::atomic<bool>& stop = stopOnSigintSigterm();
  std::signal(SIGPIPE, SIG_IGN);
  // A file-size limit (ulimit -f) must be a write error (EFBIG), not a crash.
  std::signal(SIGXFSZ, SIG_IGN);

  std::unique_ptr<capture::CaptureSession> s;
  try {
    s = std::make_unique<capture::CaptureSession>(c.o);
  } catch (const std::exception& e) {
    std::cerr << "wheelchair capture: error: " << e.what() << "\n";
    return kExitBadInput;
  }
  const int rc = s->run(&stop);
  if (rc != 0) {
    std::cerr << "wheelchair capture: error: " << s->error() << "\n";
    return kExitBadInput;
  }
  const std::size_t late = s->lateRecords();
  std::cerr << fmt::format("wheelchair capture: {} records written to {}{}\n", s->recordsWritten(),
                           c.o.output,
                           late ? fmt::format(" ({} arrived after the reorder window: written "
                                              "out of timestamp order)",
                                              late)
                                : "");
  return kExitOk;
}

const RegisterCommand reg{Command{
    "capture", "Record the wheelchair's sensors (serial devices, SPI counters) into a rawlog, live",
    [](CLI::App& sub) -> std::function<int()> {
      auto c = std::make_shared<CaptureCliOptions>();
      sub.add_option("--config,-c", c->o.config_path, "Capture configuration (config/capture.ini)")
          ->required();
      sub.add_option("-o,--output", c->o.output, "Rawlog to write (gzip, flushed every second)")
          ->required();
      sub.add_option("--duration", c->o.duration_s,
                     "Stop after this many seconds (default: run "
                     "until SIGINT/SIGTERM)")
          ->check(CLI::NonNegativeNumber);
      sub.add_flag("--force", c->o.overwrite, "Overwrite an existing output file");
      sub.add_flag("--verbose,-v", c->o.verbose,
                   "Live status every second even when stderr is not a terminal");
      sub.add_option("--vehicle-config", c->o.vehicle_config,
                     "Vehicle configuration (overrides [capture] vehicle_config)");
      return [c] { return runCapture(*c); };
    }}};

}  // namespace
}  // namespace wheelchair::cli
