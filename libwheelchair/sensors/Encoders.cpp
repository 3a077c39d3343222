#include "libwheelchair/sensors/Encoders.h"

#include <cmath>
#include <stdexcept>

namespace wheelchair::sensors {

namespace {
constexpr double kTwoPi = 6.283185307179586476925286766559;
constexpr int64_t kTwoPow32 = int64_t(1) << 32;
}  // namespace

double EncoderParams::wheelRadPerTick() const {
  return kTwoPi * double(encoder_pulley_teeth) /
         (double(counts_per_rev) * double(wheel_pulley_teeth));
}

double EncoderParams::ticksPerWheelRev() const {
  return double(counts_per_rev) * double(wheel_pulley_teeth) / double(encoder_pulley_teeth);
}

double ticksToWheelAngle(int64_t ticks, const EncoderParams& p) {
  return double(ticks) * p.wheelRadPerTick();
}

double wheelAngleToTicks(double psi_rad, const EncoderParams& p) {
  return psi_rad / p.wheelRadPerTick();
}

int32_t toHardwareCounter(int64_t ticks) {
  // Two's complement modulo 2^32, well defined through uint32_t.
  return static_cast<int32_t>(static_cast<uint32_t>(static_cast<uint64_t>(ticks)));
}

int64_t TickUnwrapper::unwrap(int32_t raw) {
  if (!initialized_) {
    initialized_ = true;
    last_raw_ = raw;
    count_ = raw;
    wraps_ = 0;
    return count_;
  }
  // Signed modulo-2^32 step in [-2^31, 2^31).
  const uint32_t diff = static_cast<uint32_t>(raw) - static_cast<uint32_t>(last_raw_);
  const int64_t step = static_cast<int64_t>(static_cast<int32_t>(diff));
  const int64_t plain = int64_t(raw) - int64_t(last_raw_);
  if (step != plain) wraps_ += (step > 0) ? 1 : -1;  // the counter crossed 2^31 -> -2^31
  count_ += step;
  last_raw_ = raw;
  return count_;
}

void TickUnwrapper::reset() {
  *this = TickUnwrapper{};
}

UnwrappedTicks unwrapTicks(const std::vector<io::EncoderSample>& enc) {
  UnwrappedTicks out;
  out.t_s.reserve(enc.size());
  out.right.reserve(enc.size());
  out.left.reserve(enc.size());
  TickUnwrapper ur, ul;
  for (const auto& s : enc) {
    out.t_s.push_back(s.t_s);
    out.right.push_back(ur.unwrap(s.right_ticks));
    out.left.push_back(ul.unwrap(s.left_ticks));
  }
  return out;
}

WheelSpeedConverter::WheelSpeedConverter(const EncoderParams& p, double wheel_radius_m,
                                         double track_width_m)
    : m_per_tick_(wheel_radius_m * p.wheelRadPerTick()), track_width_m_(track_width_m) {
  if (!(track_width_m > 0)) throw std::invalid_argument("wheelSpeedsFromTicks: track width <= 0");
}

std::optional<WheelSpeedInterval> WheelSpeedConverter::add(const io::EncoderSample& s) {
  const int64_t nr = ur_.unwrap(s.right_ticks);
  const int64_t nl = ul_.unwrap(s.left_ticks);
  if (!have_ref_) {
    have_ref_ = true;
    t_ref_ = s.t_s;
    nr_ref_ = nr;
    nl_ref_ = nl;
    return std::nullopt;
  }
  const double dt = s.t_s - t_ref_;
  if (!(dt > 0)) {  // also catches NaN
    ++st_.skipped_nonpositive_dt;
    return std::nullopt;
  }
  WheelSpeedInterval iv;
  iv.t0_s = t_ref_;
  iv.t1_s = s.t_s;
  iv.u_right_m_s = m_per_tick_ * double(nr - nr_ref_) / dt;
  iv.u_left_m_s = m_per_tick_ * double(nl - nl_ref_) / dt;
  iv.v_m_s = 0.5 * (iv.u_right_m_s + iv.u_left_m_s);
  iv.omega_rad_s = (iv.u_right_m_s - iv.u_left_m_s) / track_width_m_;
  ++st_.intervals;
  t_ref_ = s.t_s;
  nr_ref_ = nr;
  nl_ref_ = nl;
  return iv;
}

std::vector<WheelSpeedInterval> wheelSpeedsFromTicks(const std::vector<io::EncoderSample>& enc,
                                                     const EncoderParams& p, double wheel_radius_m,
                                                     double track_width_m, WheelSpeedStats* stats) {
  WheelSpeedConverter conv(p, wheel_radius_m, track_width_m);
  std::vector<WheelSpeedInterval> out;
  if (enc.size() >= 2) out.reserve(enc.size() - 1);
  for (const auto& s : enc)
    if (auto iv = conv.add(s)) out.push_back(*iv);
  if (stats) *stats = conv.stats();
  return out;
}

std::vector<WheelSpeedInterval> wheelSpeedsFromTicks(const std::vector<io::EncoderSample>& enc,
                                                     const EncoderParams& p, double wheel_radius_m,
                                                     double track_width_m) {
  return wheelSpeedsFromTicks(enc, p, wheel_radius_m, track_width_m, nullptr);
}

std::vector<WheelSpeedInterval> wheelSpeedsFromTicks(const std::vector<io::EncoderSample>& enc,
                                                     const EncoderParams& p,
                                                     const model::Geometry& g,
                                                     WheelSpeedStats* stats) {
  return wheelSpeedsFromTicks(enc, p, g.wheel_radius_m, g.track_width_m, stats);
}

}  // namespace wheelchair::sensors
