// signals::prepare on a simulated drive: segments split at a stream gap, and the conditioned
// rim speeds and currents follow the simulator's truth.
#include "libwheelchair/signals/DriveSignals.h"
#include "libwheelchair/simulation/Simulator.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

namespace wheelchair::signals {
namespace {

simulation::SimulationResult excite() {
  static const config::WheelchairConfig cfg;
  return simulation::simulate(cfg, "excite", 3, 40, {}, simulation::SimulationOptions{});
}

/// Linear interpolation of a truth column at t.
double truthAt(const simulation::SimulationResult& r, double t,
               double simulation::TruthSample::*m) {
  const auto& s = r.truth.samples;
  auto it = std::lower_bound(s.begin(), s.end(), t,
                             [](const simulation::TruthSample& a, double x) { return a.t_s < x; });
  if (it == s.begin()) return (*it).*m;
  if (it == s.end()) return s.back().*m;
  const auto& b = *it;
  const auto& a = *(it - 1);
  return a.*m + (t - a.t_s) / (b.t_s - a.t_s) * (b.*m - a.*m);
}

}  // namespace

TEST(DriveSignals, FollowTheTruthOnTheGrid) {
  const config::WheelchairConfig cfg;
  const auto sim = excite();
  DriveSignalOptions o;
  o.cutoff_hz = 4;
  const auto segs = prepare(sim.recording, cfg, o);
  ASSERT_EQ(segs.size(), 1u);
  const DriveSegment& s = segs[0];
  EXPECT_NEAR(s.t[1] - s.t[0], 1.0 / o.grid_rate_hz, 1e-12);
  const double r = cfg.vehicle.geom.wheel_radius_m;
  double e_u = 0, e_i = 0, n = 0, u2 = 0, i2 = 0;
  for (int i = s.i0; i < s.i1; ++i) {
    const double u = r * truthAt(sim, s.t[i], &simulation::TruthSample::wheel_speed_right_rad_s);
    const double cur = truthAt(sim, s.t[i], &simulation::TruthSample::current_right_A);
    e_u += std::pow(s.u_f[0][i] - u, 2), u2 += u * u;
    e_i += std::pow(s.i_f[0][i] - cur, 2), i2 += cur * cur;
    ++n;
  }
  EXPECT_GT(n, 30 * o.grid_rate_hz);
  EXPECT_LT(std::sqrt(e_u / u2), 0.1);  // 4 Hz low-pass of a persistently exciting drive
  EXPECT_LT(std::sqrt(e_i / i2), 0.25);
}

TEST(DriveSignals, SplitAtAGapLongerThanMaxGap) {
  const config::WheelchairConfig cfg;
  auto rec = excite().recording;
  // 1 s without encoder samples in the middle.
  rec.encoders.erase(
      std::remove_if(rec.encoders.begin(), rec.encoders.end(),
                     [](const io::EncoderSample& e) { return e.t_s > 20.0 && e.t_s < 21.0; }),
      rec.encoders.end());
  DriveSignalOptions o;
  const auto segs = prepare(rec, cfg, o);
  ASSERT_EQ(segs.size(), 2u);
  EXPECT_LT(segs[0].hi, 20.0 - o.edge_trim_s + 1e-9);
  EXPECT_GT(segs[1].lo, 21.0 + o.edge_trim_s - 1e-9);
  o.max_gap_s = 2.0;  // the same gap is now allowed
  EXPECT_EQ(prepare(rec, cfg, o).size(), 1u);
}

}  // namespace wheelchair::signals
