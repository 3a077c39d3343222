// The replay source (`wheelchair replay-serial`): plays a recording into pseudo-terminals,
// one per capture source, in exactly the line formats that the capture configuration
// expects, at real speed or faster, so that the whole capture path runs without hardware
// (docs/capture.md, "Replay").
//
// Each source of the capture INI gets a pty (posix_openpt, grantpt, unlockpt, ptsname) and
// a stable symlink LINK_DIR/<section> to it, like udev's /dev/serial/by-id links; a derived
// capture INI (serial_port = the link, time_source = device, encoders on the serial
// fallback) is written for `wheelchair capture`. Every line carries the recording's own
// timestamp in its {t} field, so a capture with time_source = device reproduces the
// recording's timestamps exactly.
//
// Faults, for tests and demonstrations:
//  - an outage (unplug) of a source from recording second S for D seconds: the device stops
//    sending, its pty is closed (the capture side sees a hang-up, the link disappears) and
//    the lines of that interval are lost; at S+D a new pty appears behind the same link.
//    An outage starting at 0 is a device absent at start.
//  - garbage: after every N lines of each source, one malformed line (binary noise, a line
//    cut short, a non-numeric field, an overlong line without end, in turn).
#pragma once

#include "libwheelchair/capture/LineFormat.h"
#include "libwheelchair/io/Samples.h"

#include <atomic>
#include <memory>
#include <string>
#include <vector>

namespace wheelchair::capture {

struct Outage {
  std::string source;  ///< section name or sensorLabel (case-insensitive)
  double start_s = 0;  ///< from the recording's first sample
  double duration_s = 0;
};

/// Parses "SOURCE@START+DURATION" (seconds), e.g. "imu@1.5+0.5". Throws std::invalid_argument.
Outage parseOutage(const std::string& spec);

struct ReplayOptions {
  std::string recording;       ///< plain-text recording directory, or a .rawlog file
  std::string capture_config;  ///< the capture INI whose line formats to produce
  std::string link_dir;        ///< where the pty links go (created if missing)
  std::string derived_config;  ///< write the capture INI for these ptys here ("" = don't)
  double speed = 1.0;          ///< 1 = real time, 10 = ten times faster, 0 = no pacing
  double start_delay_s = 0;    ///< pause between setup() and the first line
  std::vector<Outage> outages;
  std::size_t garbage_every = 0;
};

struct ReplaySourceReport {
  std::string section, label, link;
  std::size_t lines = 0;              ///< records written
  std::size_t dropped_unplugged = 0;  ///< records of an outage interval (lost, as on a real unplug)
  std::size_t dropped_overflow = 0;   ///< records the pty could not take (nobody reading)
  std::size_t garbage = 0;            ///< malformed lines injected
  std::size_t inexact = 0;            ///< values that no raw value reproduces exactly
  std::size_t ptys = 0;               ///< ptys opened (1 + replugs)
  std::vector<double> dropped_times;  ///< timestamps of the records lost in outages
};

struct ReplayReport {
  std::vector<ReplaySourceReport> sources;
  std::size_t no_source = 0;  ///< samples of streams without a source in the capture INI
  double wall_s = 0;
};

class SerialReplayer {
 public:
  explicit SerialReplayer(ReplayOptions opt);
  ~SerialReplayer();  ///< closes the ptys and removes the links

  /// Opens the ptys of the sources present at the start, makes the links, writes the derived
  /// configuration. Throws std::runtime_error / std::invalid_argument.
  void setup();
  /// Plays the recording (blocking) until its end or *stop; ptys stay open until destruction
  /// or close(). setup() must have been called.
  ReplayReport run(const std::atomic<bool>* stop = nullptr);
  /// Closes every pty (the capture side sees hang-ups) and removes the links.
  void close();

  std::string linkPath(const std::string& section) const;

 private:
  struct Source;
  void openPty(Source& s);
  void closePty(Source& s, bool settle);
  bool writeLine(Source& s, const std::string& line);
  ReplayOptions opt_;
  std::vector<std::unique_ptr<Source>> sources_;
  std::string derived_text_;
};

}  // namespace wheelchair::capture
