#pragma once
// Shared by the streaming tests: a sink that keeps every estimate (the in-memory reference a
// streamed run is compared with) and the option sets those comparisons cover.

#include "libwheelchair/estimation/Estimator.h"

#include <vector>

namespace wheelchair::estimation::test {

/// An EstimateSink that keeps every sample.
struct Collect : EstimateSink {
  std::vector<EstimateSample> v;
  void add(const EstimateSample& s) override { v.push_back(s); }
};

/// Both filters (physics, baseline), each with every estimate and with 20 Hz output, Pozyx
/// fused: the runs a streamed path must reproduce bit for bit.
inline std::vector<EkfOptions> streamingOptionSets() {
  std::vector<EkfOptions> sets;
  for (auto kind : {FilterKind::Physics, FilterKind::Baseline})
    for (double rate : {0.0, 20.0}) {
      EkfOptions opt;
      opt.filter = kind;
      opt.use_pozyx = true;
      opt.output_rate_hz = rate;
      sets.push_back(opt);
    }
  return sets;
}

}  // namespace wheelchair::estimation::test
