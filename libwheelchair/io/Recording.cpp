#include "libwheelchair/io/Recording.h"

#include <algorithm>
#include <limits>

namespace wheelchair::io {

namespace {
template <class F>
void forEachTime(const Recording& r, F&& f) {
  for (const auto& s : r.encoders) f(s.t_s);
  for (const auto& s : r.imu) f(s.t_s);
  for (const auto& s : r.motors) f(s.t_s);
  for (const auto& s : r.sonar) f(s.t_s);
  for (const auto& s : r.pozyx) f(s.t_s);
  for (const auto& s : r.joystick) f(s.t_s);
  for (const auto& s : r.ground_truth) f(s.t_s);
  for (const auto& s : r.landmarks) f(s.t_s);
}
}  // namespace

double Recording::startTime() const {
  double t0 = std::numeric_limits<double>::infinity();
  forEachTime(*this, [&](double t) { t0 = std::min(t0, t); });
  return size() ? t0 : 0.0;
}

double Recording::endTime() const {
  double t1 = -std::numeric_limits<double>::infinity();
  forEachTime(*this, [&](double t) { t1 = std::max(t1, t); });
  return size() ? t1 : 0.0;
}

std::size_t Recording::size() const {
  return encoders.size() + imu.size() + motors.size() + sonar.size() + pozyx.size() +
         joystick.size() + ground_truth.size() + landmarks.size();
}

}  // namespace wheelchair::io
