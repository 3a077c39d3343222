#include "StopSignal.h"

#include <csignal>

namespace wheelchair::cli {
namespace {

std::atomic<bool> g_stop{false};

extern "C" void onStopSignal(int) {
  g_stop = true;
}

}  // namespace

std::atomic<bool>& stopOnSigintSigterm() {
  struct sigaction sa {};
  sa.sa_handler = onStopSignal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  return g_stop;
}

}  // namespace wheelchair::cli
