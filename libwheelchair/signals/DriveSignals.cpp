#include "libwheelchair/signals/DriveSignals.h"

#include "libwheelchair/sensors/Encoders.h"
#include "libwheelchair/sensors/Filtering.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace wheelchair::signals {

namespace {

/// Calls visit(k) for the samples 0..n-1 in stable time order (`time(k)`), the first sample of
/// each repeated stamp only; without an index when the stamps never decrease (memory).
template <class Time, class Visit>
void firstOfEachStampInTimeOrder(std::size_t n, const Time& time, const Visit& visit) {
  double last = -INFINITY;
  auto step = [&](std::size_t k) {
    const double t = time(k);
    if (!(t > last)) return;  // repeated stamp: the first sample is kept
    last = t;
    visit(k);
  };
  bool sorted = true;
  for (std::size_t k = 1; k < n && sorted; ++k) sorted = !(time(k) < time(k - 1));
  if (sorted) {  // a stable sort would leave them in place
    for (std::size_t k = 0; k < n; ++k) step(k);
    return;
  }
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return time(a) < time(b); });
  for (std::size_t k : order) step(k);
}

}  // namespace

void encoderDistances(const std::vector<io::EncoderSample>& enc,
                      const config::WheelchairConfig& cfg, DriveStreams& s) {
  const double rR = cfg.vehicle.geom.odometryRadius(0), rL = cfg.vehicle.geom.odometryRadius(1);
  const double rpt = cfg.encoders.params.wheelRadPerTick();
  if (enc.empty()) return;
  // Sized once for every sample (a repeated stamp leaves one unused): no growth slack, which
  // on a long drive is up to as much again (memory, docs/benchmarks.md).
  for (auto* v : {&s.te, &s.s[0], &s.s[1]}) v->reserve(enc.size());
  // Counters unwrapped in stored order, the samples then taken in stable time order, the
  // first of a repeated stamp only.
  auto take = [&](double t, int64_t right, int64_t left) {
    if (!s.te.empty() && !(t > s.te.back())) return;
    s.te.push_back(t);
    s.s[0].push_back(rR * rpt * double(right));
    s.s[1].push_back(rL * rpt * double(left));
  };
  if (std::is_sorted(
          enc.begin(), enc.end(), [](const io::EncoderSample& a, const io::EncoderSample& b) {
            return a.t_s < b.t_s;
          })) {  // no unwrapped copy nor index (memory): a stable sort would leave them in place
    sensors::TickUnwrapper ur, ul;
    for (const auto& e : enc) {
      const int64_t r = ur.unwrap(e.right_ticks), l = ul.unwrap(e.left_ticks);
      take(e.t_s, r, l);
    }
  } else {
    const auto un = sensors::unwrapTicks(enc);
    std::vector<size_t> idx(un.t_s.size());
    std::iota(idx.begin(), idx.end(), 0);
    std::stable_sort(idx.begin(), idx.end(),
                     [&](size_t a, size_t b) { return un.t_s[a] < un.t_s[b]; });
    for (size_t k : idx) take(un.t_s[k], un.right[k], un.left[k]);
  }
  if (!s.s[0].empty()) {
    const double r0 = s.s[0].front(), l0 = s.s[1].front();
    for (auto& v : s.s[0]) v -= r0;
    for (auto& v : s.s[1]) v -= l0;
  }
}

DriveStreams driveStreams(const io::Recording& rec, const config::WheelchairConfig& cfg) {
  DriveStreams s;
  encoderDistances(rec.encoders, cfg, s);
  // The samples in stable time order through an index (a long drive's motor samples are not
  // copied: memory, docs/benchmarks.md).
  for (auto* v : {&s.tm, &s.i[0], &s.i[1]}) v->reserve(rec.motors.size());
  firstOfEachStampInTimeOrder(
      rec.motors.size(), [&](std::size_t k) { return rec.motors[k].t_s; },
      [&](std::size_t k) {
        const io::MotorSample& m = rec.motors[k];
        if (std::isfinite(m.current_right_A) && std::isfinite(m.current_left_A))
          s.tm.push_back(m.t_s), s.i[0].push_back(m.current_right_A),
              s.i[1].push_back(m.current_left_A);
      });
  return s;
}

void sortUniqueFinite(std::vector<double>& t, const std::vector<std::vector<double>*>& values) {
  const std::size_t n = t.size();
  auto finite = [&](std::size_t k) {
    for (const auto* v : values)
      if (!std::isfinite((*v)[k])) return false;
    return true;
  };
  auto time = [&](std::size_t k) { return t[k]; };
  if (std::is_sorted(t.begin(), t.end())) {  // in place: sample k moves to w <= k
    std::size_t w = 0;
    firstOfEachStampInTimeOrder(n, time, [&](std::size_t k) {
      if (!finite(k)) return;
      t[w] = t[k];
      for (auto* v : values) (*v)[w] = (*v)[k];
      ++w;
    });
    t.resize(w);
    for (auto* v : values) v->resize(w);
    return;
  }
  std::vector<double> nt;
  std::vector<std::vector<double>> nv(values.size());
  nt.reserve(n);
  for (auto& v : nv) v.reserve(n);
  firstOfEachStampInTimeOrder(n, time, [&](std::size_t k) {
    if (!finite(k)) return;
    nt.push_back(t[k]);
    for (std::size_t c = 0; c < values.size(); ++c) nv[c].push_back((*values[c])[k]);
  });
  t.swap(nt);
  for (std::size_t c = 0; c < values.size(); ++c) values[c]->swap(nv[c]);
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
  // (sized exactly first: no growth slack on a long drive's copy; memory, docs/benchmarks.md)
  // (a window holding every sample, e.g. a drive without gaps, reads the streams themselves:
  // no copy)
  auto inWindow = [&](double t) { return t >= glo - 2 && t <= ghi + 2; };
  const auto m = static_cast<std::size_t>(std::count_if(s.tm.begin(), s.tm.end(), inWindow));
  if (m < 10) return false;
  const bool whole = m == s.tm.size();
  std::vector<double> tmi;
  std::array<std::vector<double>, 2> is;
  if (!whole) {
    tmi.reserve(m), is[0].reserve(m), is[1].reserve(m);
    for (size_t i = 0; i < s.tm.size(); ++i)
      if (inWindow(s.tm[i]))
        tmi.push_back(s.tm[i]), is[0].push_back(s.i[0][i]), is[1].push_back(s.i[1][i]);
  }
  const std::vector<double>& tw = whole ? s.tm : tmi;
  for (int side = 0; side < 2; ++side) {
    seg.p[side] = sensors::resampleLinear(s.te, s.s[side], seg.t);
    seg.u[side] = sensors::centralDerivative(seg.t, seg.p[side]);
    seg.u_f[side] = sensors::filtfiltButter2(seg.u[side], fc, fs);
    seg.a_f[side] = sensors::centralDerivative(seg.t, seg.u_f[side]);
    seg.i_f[side] = sensors::resampleLinear(
        tw, sensors::filtfiltButter2(tw, whole ? s.i[side] : is[side], fc), seg.t);
    std::vector<double>().swap(is[side]);
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
