// The one clock of a capture session: the host's wall clock, read through the monotonic
// clock so that an NTP step or a manual clock change during a drive cannot make timestamps
// jump. The wall-clock origin is taken once, when the clock is first used (docs/capture.md,
// "Which clock").
#pragma once

#include <mrpt/core/Clock.h>

#include <chrono>

namespace wheelchair::capture {

class HostClock {
 public:
  /// Seconds since the UNIX epoch: wall time at the origin + monotonic time elapsed since.
  static double now();
  /// The same instant as an MRPT timestamp.
  static mrpt::Clock::time_point nowStamp() { return mrpt::Clock::fromDouble(now()); }
  /// Monotonic seconds (arbitrary origin), for timeouts and rates.
  static double monotonic();
};

}  // namespace wheelchair::capture
