#include "libwheelchair/stats/Descriptive.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace wheelchair::stats {

namespace {

void dropNonFinite(std::vector<double>& v) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
}

}  // namespace

double median(std::vector<double> v) {
  dropNonFinite(v);
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const std::size_t m = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + m, v.end());
  const double hi = v[m];
  if (v.size() % 2 == 1) return hi;
  const double lo = *std::max_element(v.begin(), v.begin() + m);
  return 0.5 * (lo + hi);
}

double quantile(std::vector<double> v, double q) {
  dropNonFinite(v);
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const double qc = std::clamp(q, 0.0, 1.0);
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(qc * v.size()));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

}  // namespace wheelchair::stats
