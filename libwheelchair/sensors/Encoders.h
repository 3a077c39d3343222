// Wheel encoders: ticks -> wheel angle (eq. (9), Table I), unwrapping of the 32-bit hardware
// counter, and the interval-mean wheel speeds that differenced counts really measure
// (docs/sensors.md, "Encoders").
//
// Conventions (vehicle.md): index 0 / "right" is the right wheel; counts increase when their
// wheel rolls forward; rim speeds u_R = v + l_w omega / 2, u_L = v - l_w omega / 2, so
// v = (u_R + u_L) / 2 and omega = (u_R - u_L) / l_w (omega > 0 turns left: right wheel faster).
//
// A differenced count (N_k - N_{k-1}) / (t_k - t_{k-1}) is the MEAN rim speed over the interval
// [t_{k-1}, t_k], i.e. the speed at the interval's midpoint to second order, not the speed at
// t_k. Consumers (EKF, identification) should treat it as (1/dt) * integral of u over the
// interval, or at least time-stamp it at tMid().
//
// Example:
//   EncoderParams enc;                                  // Table I
//   double psi = ticksToWheelAngle(7333, enc);          // ~ 2 pi
//   TickUnwrapper uw;  int64_t n = uw.unwrap(raw);      // continuous count
//   auto iv = wheelSpeedsFromTicks(rec.encoders, enc, 0.17, 0.55);
#pragma once

#include "libwheelchair/io/Recording.h"
#include "libwheelchair/model/VehicleParams.h"

#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

namespace wheelchair::sensors {

/// Table I of the paper: encoder pulley, wheel pulley, encoder counts per shaft revolution
/// (500 ppr quadrature-decoded = 2000 counts).
struct EncoderParams {
  int encoder_pulley_teeth = 30;  ///< N_ep
  int wheel_pulley_teeth = 110;   ///< N_mp
  int counts_per_rev = 2000;      ///< N_ec, counts per encoder-shaft revolution

  /// Wheel angle per count, 2 pi N_ep / (N_ec N_mp) (rad), eq. (9).
  double wheelRadPerTick() const;
  /// Counts per wheel revolution, N_ec N_mp / N_ep (7333.33 for Table I).
  double ticksPerWheelRev() const;
};

/// Wheel angle psi (rad) of a cumulative count, eq. (9).
double ticksToWheelAngle(int64_t ticks, const EncoderParams& p);
/// Continuous inverse of eq. (9): the (fractional, not rounded) count of a wheel angle.
double wheelAngleToTicks(double psi_rad, const EncoderParams& p);

/// What a 32-bit hardware counter holding the cumulative count `ticks` reads (two's-complement
/// wrap modulo 2^32, i.e. it jumps from 2^31 - 1 to -2^31). For simulators.
int32_t toHardwareCounter(int64_t ticks);

/// Unwraps an int32 hardware counter that wraps at 2^31 into a continuous int64 count.
/// The first reading after construction / reset() is taken as-is (so the unwrapped count equals
/// the raw value until the first wrap); afterwards each reading adds the modulo-2^32 difference
/// to the previous one, interpreted as a signed step in [-2^31, 2^31). This is exact as long
/// as the wheel moves less than 2^31 counts between two readings (~ 2.9e5 wheel turns).
class TickUnwrapper {
 public:
  int64_t unwrap(int32_t raw);
  void reset();
  bool initialized() const { return initialized_; }
  /// The last unwrapped count (0 before the first reading).
  int64_t count() const { return count_; }
  /// Number of wraps seen (forward minus backward).
  int64_t wraps() const { return wraps_; }

 private:
  bool initialized_ = false;
  int32_t last_raw_ = 0;
  int64_t count_ = 0;
  int64_t wraps_ = 0;
};

/// Mean rim and body speeds over one interval between consecutive encoder samples.
struct WheelSpeedInterval {
  double t0_s = 0, t1_s = 0;               ///< interval ends
  double u_right_m_s = 0, u_left_m_s = 0;  ///< mean rim speeds over [t0, t1]
  double v_m_s = 0, omega_rad_s = 0;       ///< mean body speeds: v=(uR+uL)/2, omega=(uR-uL)/l_w
  double tMid() const { return 0.5 * (t0_s + t1_s); }
  double dt() const { return t1_s - t0_s; }
};

/// Counters of wheelSpeedsFromTicks.
struct WheelSpeedStats {
  std::size_t intervals = 0;               ///< intervals returned
  std::size_t skipped_nonpositive_dt = 0;  ///< samples not later than the last accepted one
};

/// wheelSpeedsFromTicks one sample at a time (streaming use; the vector functions below are
/// this loop): add() returns the interval a sample closes, if any. Example:
///   WheelSpeedConverter c(enc, 0.17, 0.55);
///   for (const auto& s : samples) if (auto iv = c.add(s)) use(*iv);
class WheelSpeedConverter {
 public:
  WheelSpeedConverter(const EncoderParams& p, double wheel_radius_m, double track_width_m);
  /// Samples must come sorted by time; the first one only sets the reference.
  std::optional<WheelSpeedInterval> add(const io::EncoderSample& s);
  /// Whether the first sample (the start of the first interval) has been seen.
  bool started() const { return have_ref_; }
  /// Time of the last accepted sample (start of the next interval).
  double referenceTime() const { return t_ref_; }
  const WheelSpeedStats& stats() const { return st_; }

 private:
  double m_per_tick_, track_width_m_;
  TickUnwrapper ur_, ul_;
  bool have_ref_ = false;
  double t_ref_ = 0;
  int64_t nr_ref_ = 0, nl_ref_ = 0;
  WheelSpeedStats st_;
};

/// Mean rim speeds over each interval between consecutive encoder samples (see the header
/// comment): u = r (psi(t1) - psi(t0)) / (t1 - t0). Copes with uneven sampling. A sample whose
/// time is not later than the previous accepted sample (zero or negative dt) is skipped and
/// counted; its counts still feed the unwrapper, and the next interval starts at the last
/// accepted sample. Fewer than two samples give an empty result.
std::vector<WheelSpeedInterval> wheelSpeedsFromTicks(const std::vector<io::EncoderSample>& enc,
                                                     const EncoderParams& p, double wheel_radius_m,
                                                     double track_width_m);
/// Same, reporting the counters in `stats` (may be null).
std::vector<WheelSpeedInterval> wheelSpeedsFromTicks(const std::vector<io::EncoderSample>& enc,
                                                     const EncoderParams& p, double wheel_radius_m,
                                                     double track_width_m, WheelSpeedStats* stats);
/// Same, with r and l_w from the vehicle geometry.
std::vector<WheelSpeedInterval> wheelSpeedsFromTicks(const std::vector<io::EncoderSample>& enc,
                                                     const EncoderParams& p,
                                                     const model::Geometry& g,
                                                     WheelSpeedStats* stats = nullptr);

/// Unwrapped cumulative counts of both wheels, one entry per input sample (right, left).
struct UnwrappedTicks {
  std::vector<double> t_s;
  std::vector<int64_t> right, left;
};
UnwrappedTicks unwrapTicks(const std::vector<io::EncoderSample>& enc);

}  // namespace wheelchair::sensors
