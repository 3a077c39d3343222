// wheelchair capture --config CAPTURE.ini -o FILE.rawlog [--duration S] [--health OUT.jsonl] :
// records every source of a capture configuration into a rawlog, continuously
// (docs/capture.md). With --health the physics filter runs live on the samples as they are
// written (estimation::LiveEstimator, the vehicle configuration of the capture) and every
// new model-health event is printed as it is found; OUT.jsonl is written atomically at the end.
#include "Command.h"
#include "FullProgram.h"
#include "HealthJson.h"
#include "StopSignal.h"

#include "libwheelchair/capture/CaptureSession.h"
#include "libwheelchair/estimation/Estimator.h"
#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/util/AtomicFile.h"

#include <fmt/core.h>

#include <atomic>
#include <csignal>
#include <iostream>
#include <optional>

namespace wheelchair::cli {
namespace {

struct CaptureCliOptions {
  capture::CaptureOptions o;
  std::string health;  ///< model-health events (JSON lines), "" = no live monitor
};

// The live model-health monitor of --health: the capture's samples through the filter as
// they are written, new events printed at once ("health: t = 15.3 s: left encoder reads
// 5.0 % short (+-0.5 %) since t = 8.0 s", t from the recording's first sample). A failure
// of the filter stops the monitor only (said once, with the reason); the recording goes on.
// The events file is committed complete at the end (util::AtomicFile), also after a stop,
// with the events found until then.
class LiveHealth {
 public:
  explicit LiveHealth(const std::string& path) : path_(path), file_(path) {}

  void start(const capture::CaptureSession& s) {
    auto cfg = s.vehicleConfig();
    estimation::EkfOptions opt;
    opt.loadFromConfig(cfg.ini());
    if (!opt.estimate_encoder_scales) {  // as filter --health: faults are estimated
      cfg.set("estimator", "estimate_encoder_scales", "1");
      opt.estimate_encoder_scales = true;
      note_ = "note: --health switches estimate_encoder_scales on";
    }
    live_.emplace(cfg, opt, s.captures(io::StreamKind::Motors));
  }

  void add(const mrpt::obs::CObservation& obs, const capture::CaptureOptions::Say& say) {
    if (!note_.empty()) say(std::exchange(note_, ""));
    if (!stopped_.empty() || !live_) return;
    const auto sample = io::fromObservation(obs);
    if (!sample) return;
    try {
      live_->push(*sample);
    } catch (const std::exception& e) {
      stop(e.what(), say);
      return;
    }
    report(say);
  }

  /// Processes the rest and writes the events file; false (said) when it cannot be written.
  bool finish(const capture::CaptureOptions::Say& say) {
    if (stopped_.empty() && live_) {
      try {
        live_->finish();
      } catch (const std::exception& e) {
        stop(e.what(), say);
      }
      report(say);
    }
    if (live_ && live_->late() > 0)
      say(fmt::format(
          "health monitor: {} samples arrived after a later one had been filtered: not used "
          "live (`wheelchair filter` on the recording uses them)",
          live_->late()));
    try {
      for (const auto& e : events_) file_.stream() << healthJsonLine(e) << "\n";
      file_.commit();
    } catch (const std::exception& e) {
      say(fmt::format("error: health events not written: {}", e.what()));
      return false;
    }
    say(fmt::format("health events (JSON lines): {} ({} events{})", path_, events_.size(),
                    stopped_.empty() ? "" : ", until the monitor stopped"));
    return true;
  }

 private:
  void report(const capture::CaptureOptions::Say& say) {
    const auto& h = live_->health();
    for (; events_.size() < h.size();) {
      events_.push_back(h[events_.size()]);
      say(fmt::format("health: t = {:.1f} s: {}", events_.back().t_s - live_->startTime(),
                      events_.back().text));
    }
  }
  void stop(const std::string& why, const capture::CaptureOptions::Say& say) {
    stopped_ = why;
    say("health monitor stopped (the recording goes on): filter failed at " + why);
  }

  std::string path_;
  util::AtomicFile file_;
  std::optional<estimation::LiveEstimator> live_;
  std::vector<estimation::HealthEvent> events_;  // reported so far
  std::string note_, stopped_;
};

int runCapture(CaptureCliOptions& c) {
  std::atomic<bool>& stop = stopOnSigintSigterm();
  std::signal(SIGPIPE, SIG_IGN);
  // A file-size limit (ulimit -f) must be a write error (EFBIG), not a crash.
  std::signal(SIGXFSZ, SIG_IGN);

  std::unique_ptr<capture::CaptureSession> s;
  std::shared_ptr<LiveHealth> health;
  bool health_ok = true;
  try {
    if (!c.health.empty()) {  // a bad path fails before anything is captured
      health = std::make_shared<LiveHealth>(c.health);
      c.o.on_record = [health](const mrpt::obs::CObservation& obs,
                               const capture::CaptureOptions::Say& say) { health->add(obs, say); };
      c.o.on_finish = [health, &health_ok](const capture::CaptureOptions::Say& say) {
        health_ok = health->finish(say);
      };
    }
    s = std::make_unique<capture::CaptureSession>(c.o);
    if (health) health->start(*s);
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
  return health_ok ? kExitOk : kExitBadInput;
}

const RegisterCommand reg{Command{
    "capture", fullOnlyDescription("capture"), [](CLI::App& sub) -> std::function<int()> {
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
      sub.add_option("--health", c->health,
                     "Run the physics filter live and print model-health events as found; "
                     "write them as JSON lines {t_s, sensor, kind, effect, side, parameter, "
                     "value, sd, since_s, text} at the end (switches estimate_encoder_scales on)");
      return [c] { return runCapture(*c); };
    }}};

}  // namespace
}  // namespace wheelchair::cli
