#include "libwheelchair/signals/DriveSignals.h"

#include "libwheelchair/sensors/Encoders.h"
#include "libwheelchair/sensors/Filtering.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace wheelchair::signals {

DriveStreams driveStreams(const io::Recording& rec, const config::WheelchairConfig& cfg) {
  DriveStreams s;
  const double rR = cfg.vehicle.geom.odometryRadius(0), rL = cfg.vehicle.geom.odometryRadius(1);
  const double rpt = cfg.encoders.params.wheelRadPerTick();
  if (!rec.encoders.empty()) {
    auto un = sensors::unwrapTicks(rec.encoders);
    std::vector<size_t> idx(un.t_s.size());
    std::iota(idx.begin(), idx.end(), 0);
    std::stable_sort(idx.begin(), idx.end(),
                     [&](size_t a, size_t b) { return un.t_s[a] < un.t_s[b]; });
    // Sized once for every sample (a repeated stamp leaves one unused): no growth slack, which
    // on a long drive is up to as much again (memory, docs/benchmarks.md).
    for (auto* v : {&s.te, &s.s[0], &s.s[1]}) v->reserve(idx.size());
    for (size_t k : idx) {
      if (!s.te.empty() && !(un.t_s[k] > s.te.back())) continue;
      s.te.push_back(un.t_s[k]);
      s.s[0].push_back(rR * rpt * double(un.right[k]));
      s.s[1].push_back(rL * rpt * double(un.left[k]));
    }
    if (!s.s[0].empty()) {
      const double r0 = s.s[0].front(), l0 = s.s[1].front();
      for (auto& v : s.s[0]) v -= r0;
      for (auto& v : s.s[1]) v -= l0;
    }
  }
  // The samples in stable time order through an index (a long drive's motor samples are not
  // copied: memory, docs/benchmarks.md).
  std::vector<std::size_t> order(rec.motors.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return rec.motors[a].t_s < rec.motors[b].t_s;
  });
  for (auto* v : {&s.tm, &s.i[0], &s.i[1]}) v->reserve(order.size());
  double last = -INFINITY;
  for (std::size_t k : order) {
    const io::MotorSample& m = rec.motors[k];
    if (!(m.t_s > last)) continue;  // repeated stamp: the first sample is kept
    last = m.t_s;
    if (std::isfinite(m.current_right_A) && std::isfinite(m.current_left_A))
      s.tm.push_back(m.t_s), s.i[0].push_back(m.current_right_A),
          s.i[1].push_back(m.current_left_A);
  }
  return s;
}

std::vector<std::pair<double, double>> splitAtGaps(const std::vector<double>& t, double max_gap_s) {
  std::vector<std::pair<double, double>> out;
  if (t.empty()) return out;
  double a = t.front();
  for (size_t i = 1; i < t.size(); ++i)
    if (t[i] - t[i - 1] > max_gap_s) out.push_back({a, t[i - 1]}), a = t[i];
  out.push_back({a, t.back()});
  return out;
}

namespace {

/// Steps 3-6 over one segment [lo, hi]; false when too short or without currents.
bool conditionSegment(const DriveStreams& s, const DriveSignalOptions& o, double lo, double hi,
                      DriveSegment& seg) {
  const double fs = o.grid_rate_hz, fc = o.cutoff_hz;
  // grid with a margin for the filter (the margin is dropped afterwards)
  const double margin = std::min(o.edge_trim_s, 1.0);
  const double glo = lo - margin, ghi = hi + margin;
  const int n = static_cast<int>(std::floor((ghi - glo) * fs)) + 1;
  if (n < 20) return false;
  seg.lo = lo, seg.hi = hi;
  seg.t.resize(n);
  for (int i = 0; i < n; ++i) seg.t[i] = glo + i / fs;
  // currents: filtered on their own time base, then resampled
  std::vector<double> tmi;
  std::array<std::vector<double>, 2> is;
  for (size_t i = 0; i < s.tm.size(); ++i)
    if (s.tm[i] >= glo - 2 && s.tm[i] <= ghi + 2)
      tmi.push_back(s.tm[i]), is[0].push_back(s.i[0][i]), is[1].push_back(s.i[1][i]);
  if (tmi.size() < 10) return false;
  for (int side = 0; side < 2; ++side) {
    seg.p[side] = sensors::resampleLinear(s.te, s.s[side], seg.t);
    seg.u[side] = sensors::centralDerivative(seg.t, seg.p[side]);
    seg.u_f[side] = sensors::filtfiltButter2(seg.u[side], fc, fs);
    seg.a_f[side] = sensors::centralDerivative(seg.t, seg.u_f[side]);
    seg.i_f[side] =
        sensors::resampleLinear(tmi, sensors::filtfiltButter2(tmi, is[side], fc), seg.t);
  }
  seg.i0 = static_cast<int>(std::ceil(margin * fs));
  seg.i1 = n - seg.i0;
  return true;
}

}  // namespace

std::vector<DriveSegment> prepare(const DriveStreams& s, const DriveSignalOptions& o) {
  std::vector<DriveSegment> out;
  if (s.te.size() < 3 || s.tm.size() < 3) return out;
  // Continuous segments covered by both streams.
  const auto se = splitAtGaps(s.te, o.max_gap_s), sm = splitAtGaps(s.tm, o.max_gap_s);
  for (const auto& a : se)
    for (const auto& b : sm) {
      const double lo = std::max(a.first, b.first) + o.edge_trim_s;
      const double hi = std::min(a.second, b.second) - o.edge_trim_s;
      if (!(hi - lo > o.min_segment_s)) continue;
      DriveSegment seg;
      if (conditionSegment(s, o, lo, hi, seg)) out.push_back(std::move(seg));
    }
  return out;
}

}  // namespace wheelchair::signals
