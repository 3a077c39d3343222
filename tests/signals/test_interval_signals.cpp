// signals::prepareIntervalMeans (the identification's conditioning) on a simulated drive:
// v, omega and the currents follow the simulator's truth, omega may come from the gyro,
// rows near the segment ends are not interior, and a stream gap splits the drive.
#include "libwheelchair/signals/IntervalSignals.h"
#include "libwheelchair/simulation/Simulator.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

namespace wheelchair::signals {
namespace {

const simulation::SimulationResult& excite() {
  static const simulation::SimulationResult r = simulation::simulate(
      config::WheelchairConfig{}, "excite", 3, 40, {}, simulation::SimulationOptions{});
  return r;
}

double truthAt(double t, double simulation::TruthSample::*m) {
  const auto& s = excite().truth.samples;
  auto it = std::lower_bound(s.begin(), s.end(), t,
                             [](const simulation::TruthSample& a, double x) { return a.t_s < x; });
  if (it == s.begin()) return (*it).*m;
  if (it == s.end()) return s.back().*m;
  const auto &b = *it, &a = *(it - 1);
  return a.*m + (t - a.t_s) / (b.t_s - a.t_s) * (b.*m - a.*m);
}

/// Relative rms error of a conditioned signal against a truth column over the interior rows.
double relError(const IntervalSegment& s, const std::vector<double>& x,
                double simulation::TruthSample::*m) {
  double e = 0, x2 = 0;
  for (std::size_t k = 0; k < s.t.size(); ++k)
    if (s.interior[k]) {
      const double ref = truthAt(s.t[k], m);
      e += std::pow(x[k] - ref, 2), x2 += ref * ref;
    }
  return std::sqrt(e / x2);
}

}  // namespace

TEST(IntervalSignals, FollowTheTruthAndTrimTheEdges) {
  IntervalSignalOptions o;
  o.cutoff_hz = 4;
  const IntervalSignals d = prepareIntervalMeans({excite().recording}, {}, o);
  ASSERT_EQ(d.segments.size(), 1u);
  const IntervalSegment& s = d.segments[0];
  EXPECT_NEAR(s.t[1] - s.t[0], 1.0 / o.rate_hz, 1e-12);
  EXPECT_GT(s.t.size(), 35 * o.rate_hz);
  EXPECT_LT(relError(s, s.v, &simulation::TruthSample::v_m_s), 0.1);
  EXPECT_LT(relError(s, s.omega, &simulation::TruthSample::omega_rad_s), 0.1);
  EXPECT_LT(relError(s, s.i_r, &simulation::TruthSample::current_right_A), 0.25);
  EXPECT_LT(relError(s, s.U_r, &simulation::TruthSample::voltage_right_V), 0.25);
  EXPECT_TRUE(d.has_voltage);
  // edge_trim_s at both ends is not interior, the rest is
  const long trim = std::lround(o.edge_trim_s * o.rate_hz);
  EXPECT_FALSE(s.interior[trim - 1]);
  EXPECT_TRUE(s.interior[trim]);
  EXPECT_FALSE(s.interior[s.t.size() - trim]);
  EXPECT_TRUE(s.interior[s.t.size() - trim - 1]);
  // the noise floors of a filtered signal: positive, far below the signal
  EXPECT_GT(d.noise_v, 0);
  EXPECT_LT(d.noise_v, 0.01);
  // omega from the gyro follows the same truth
  o.gyro_omega = true;
  const IntervalSignals g = prepareIntervalMeans({excite().recording}, {}, o);
  ASSERT_EQ(g.segments.size(), 1u);
  EXPECT_LT(relError(g.segments[0], g.segments[0].omega, &simulation::TruthSample::omega_rad_s),
            0.1);
}

TEST(IntervalSignals, SplitAtAGapLongerThanMaxGap) {
  io::Recording rec = excite().recording;
  rec.motors.erase(
      std::remove_if(rec.motors.begin(), rec.motors.end(),
                     [](const io::MotorSample& m) { return m.t_s > 20.0 && m.t_s < 21.0; }),
      rec.motors.end());
  IntervalSignalOptions o;
  const IntervalSignals d = prepareIntervalMeans({rec, excite().recording}, {}, o);
  ASSERT_EQ(d.segments.size(), 3u);
  EXPECT_EQ(d.segments[0].recording, 0);
  EXPECT_LT(d.segments[0].t.back(), 20.0);
  EXPECT_GT(d.segments[1].t.front(), 21.0 - o.max_gap_s);
  EXPECT_EQ(d.segments[2].recording, 1);
  o.max_gap_s = 2.0;  // the same gap is now allowed
  EXPECT_EQ(prepareIntervalMeans({rec}, {}, o).segments.size(), 1u);
}

}  // namespace wheelchair::signals
