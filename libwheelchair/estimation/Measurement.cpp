#include "libwheelchair/estimation/Measurement.h"

#include "libwheelchair/model/Kinematics.h"
#include "libwheelchair/stats/Distributions.h"

#include <array>

namespace wheelchair::estimation {

Measurement::Measurement(Sensor s, int dim, int n)
    : sensor(s),
      z(Eigen::VectorXd::Zero(dim)),
      h(Eigen::VectorXd::Zero(dim)),
      H(Eigen::MatrixXd::Zero(dim, n)),
      R(Eigen::MatrixXd::Zero(dim, dim)),
      y_(Eigen::VectorXd::Zero(dim)) {}

const Eigen::VectorXd& Measurement::innovation() {
  y_ = z - h;
  for (int i = 0; i < dim(); ++i)
    if (angular_rows & (1u << i)) y_(i) = model::wrapAngle(y_(i));
  return y_;
}

UpdateResult correct(Eigen::VectorXd& x, Eigen::MatrixXd& P, Measurement& m, double gate) {
  return josephUpdate(x, P, m.innovation(), m.H, m.R, gate);
}

std::pair<double, double> chi2Band95(int dof) {
  constexpr int kCached = 4;
  static const auto kBands = [] {
    std::array<std::pair<double, double>, kCached + 1> b{};
    for (int k = 1; k <= kCached; ++k)
      b[k] = {stats::chi2Quantile(0.025, k), stats::chi2Quantile(0.975, k)};
    return b;
  }();
  if (dof >= 1 && dof <= kCached) return kBands[dof];
  return {stats::chi2Quantile(0.025, dof), stats::chi2Quantile(0.975, dof)};
}

void bookUpdate(EstimationResult& res, Sensor s, double t, const UpdateResult& r, double g,
                bool keep_record) {
  SensorStats& st = res.sensors[static_cast<int>(s)];
  st.dof = r.dof;
  if (keep_record) res.nis.push_back({t, s, r.nis, r.dof, r.accepted});
  if (r.accepted) {
    ++st.used;
    ++st.nis_count;
    st.nis_sum += r.nis;
    const auto [lo, hi] = chi2Band95(r.dof);
    if (r.nis >= lo && r.nis <= hi) ++st.nis_inside95;
  } else {
    ++st.rejected;
    res.rejected.push_back({t, s, r.nis, r.dof, g, r.innovation});
  }
}

}  // namespace wheelchair::estimation
