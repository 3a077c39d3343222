// SIGINT / SIGTERM as a stop request for the commands that run until stopped (capture,
// replay-serial): the handler only sets a lock-free atomic flag (async-signal-safe), which the
// command's loop polls.
//
// Example:
//   std::atomic<bool>& stop = stopOnSigintSigterm();
//   while (!stop) step();
#pragma once

#include <atomic>

namespace wheelchair::cli {

/// Installs the handlers (again, if called twice) and returns the flag they set.
std::atomic<bool>& stopOnSigintSigterm();

}  // namespace wheelchair::cli
