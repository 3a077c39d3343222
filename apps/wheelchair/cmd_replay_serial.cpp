// wheelchair replay-serial RECORDING --config CAPTURE.ini --link-dir DIR : plays a recording
// into pseudo-terminals, one per capture source, in the line formats the capture expects, so
// that `wheelchair capture` runs without hardware (docs/capture.md, "Replay").
#include "Command.h"
#include "FullProgram.h"
#include "StopSignal.h"

#include "libwheelchair/capture/SerialReplayer.h"

#include <fmt/core.h>

#include <atomic>
#include <iostream>
#include <thread>

namespace wheelchair::cli {
namespace {

struct ReplayCliOptions {
  capture::ReplayOptions o;
  std::vector<std::string> unplug;
  double hold_s = 1.0;
};

int runReplay(ReplayCliOptions& c) {
  std::atomic<bool>& stop = stopOnSigintSigterm();
  try {
    for (const auto& u : c.unplug) c.o.outages.push_back(capture::parseOutage(u));
  } catch (const std::exception& e) {
    std::cerr << "wheelchair replay-serial: error: " << e.what() << "\n";
    return kExitUsage;
  }
  capture::SerialReplayer r(c.o);
  r.setup();
  std::cerr << "wheelchair replay-serial: ptys ready";
  if (!c.o.derived_config.empty()) std::cerr << "; capture configuration " << c.o.derived_config;
  std::cerr << "\n";
  const auto rep = r.run(&stop);
  // Keep the devices "plugged in" a moment so the capture reads the last lines.
  for (double t = 0; t < c.hold_s && !stop; t += 0.05)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  r.close();
  fmt::print("replayed {:.2f} s (speed {})\n", rep.wall_s, c.o.speed);
  for (const auto& s : rep.sources)
    fmt::print(
        "  {:<9} {:<28} lines {:<7} garbage {:<5} lost-unplugged {:<5} lost-overflow {:<4} "
        "inexact {:<4} ptys {}\n",
        s.label, s.link, s.lines, s.garbage, s.dropped_unplugged, s.dropped_overflow, s.inexact,
        s.ptys);
  if (rep.no_source)
    fmt::print("  {} samples of streams without a source were skipped\n", rep.no_source);
  return kExitOk;
}

const RegisterCommand reg{Command{
    "replay-serial", fullOnlyDescription("replay-serial"),
    [](CLI::App& sub) -> std::function<int()> {
      auto c = std::make_shared<ReplayCliOptions>();
      sub.add_option("recording", c->o.recording, "Plain-text recording directory (or a .rawlog)")
          ->required();
      sub.add_option("--config,-c", c->o.capture_config,
                     "Capture configuration whose sources and line formats to play")
          ->required();
      sub.add_option("--link-dir", c->o.link_dir, "Directory for the pty links (<dir>/<section>)")
          ->required();
      sub.add_option("--write-config", c->o.derived_config,
                     "Write the capture configuration that reads these ptys here");
      sub.add_option("--speed", c->o.speed, "Playback speed factor (1 = real time, 0 = no pacing)")
          ->check(CLI::NonNegativeNumber);
      sub.add_option("--start-delay", c->o.start_delay_s, "Seconds between pty setup and playback")
          ->check(CLI::NonNegativeNumber);
      sub.add_option("--unplug", c->unplug,
                     "Outage SOURCE@START+DURATION in recording seconds (START 0 = absent at "
                     "start); repeatable");
      sub.add_option("--garbage-every", c->o.garbage_every,
                     "Inject a malformed line after every N lines of each source");
      sub.add_option("--hold", c->hold_s, "Seconds the ptys stay open after the last line")
          ->check(CLI::NonNegativeNumber);
      return [c] { return runReplay(*c); };
    }}};

}  // namespace
}  // namespace wheelchair::cli
