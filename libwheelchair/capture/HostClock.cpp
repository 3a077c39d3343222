#include "libwheelchair/capture/HostClock.h"

namespace wheelchair::capture {

namespace {
struct Origin {
  std::chrono::steady_clock::time_point mono = std::chrono::steady_clock::now();
  double wall =
      std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
};
const Origin& origin() {
  static const Origin o;
  return o;
}
}  // namespace

double HostClock::monotonic() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

double HostClock::now() {
  const Origin& o = origin();
  return o.wall + std::chrono::duration<double>(std::chrono::steady_clock::now() - o.mono).count();
}

}  // namespace wheelchair::capture
