// Evidence statistics of autocorrelated residual series (docs/diagnosis-design.md,
// docs/discovery.md): the effective sample size, Ljung-Box whiteness, the bias t-test and the
// evidence comparison of two nested models (likelihood ratio on the effective sample size,
// BIC difference). The HAC least squares they go with is in LeastSquares.h, the distribution
// functions in Distributions.h, the selection rule and engine in Selection.h.
//
// Residual series are organised in GROUPS (e.g. the right-motor and the left-motor equation
// errors, or one recording each): lags never cross a group boundary.
//
// Example:
//   LinearFit f = fitLinear(X, y, groups, 10);      // beta, HAC covariance, RSS
//   double ne = effectiveSampleSize(f.residual, groups, 10);
//   Evidence e = compareNested(rss0, rss1, k_added, ne);
#pragma once

#include "libwheelchair/stats/Distributions.h"
#include "libwheelchair/stats/LeastSquares.h"

#include <Eigen/Core>

namespace wheelchair::stats {

/// Effective number of independent samples of a residual series: n * gamma0 / LRV, with the
/// long-run variance LRV = gamma0 + 2 sum_{k<=lags} (1 - k/(lags+1)) gamma_k (Bartlett), summed
/// over groups; clamped to [1, n].
double effectiveSampleSize(const Eigen::VectorXd& r, const Groups& groups, int lags);

/// What a prediction p1 gains over p0 on held-out rows y (rows in `groups`, HAC `lags`): the
/// residual sums of squares rss0 = |y - p0|^2 (given) and rss1 = |y - p1|^2, n_eff of y - p1,
/// the realised likelihood-ratio gain lr = n_eff log(rss0 / rss1) and the gain predicted if p1
/// were right, lr_expected = n_eff log(1 + |p1 - p0|^2 / rss1) (diagnose's held-out checks: a
/// forward-selection step, Stages.cpp; each component of an unmodeled finding,
/// UnmodeledPhysics.cpp).
struct HeldOutGain {
  double rss1 = 0, n_eff = 0, lr = 0, lr_expected = 0;
};
HeldOutGain heldOutGain(const Eigen::VectorXd& y, const Eigen::VectorXd& p0, double rss0,
                        const Eigen::VectorXd& p1, const Groups& groups, int lags);

/// Ljung-Box Q over lags 1..m (within groups, pooled autocorrelation) and its p-value
/// against chi2(m).
struct Whiteness {
  double q = 0;
  int lags = 0;
  double p_value = 1;
  double rho1 = 0;  ///< lag-1 autocorrelation
};
Whiteness ljungBox(const Eigen::VectorXd& r, const Groups& groups, int m);

/// Evidence for a nested model with k more parameters, from the residual sums of squares of
/// the smaller (rss0) and larger (rss1) model and the effective sample size (Gaussian
/// likelihood with the variance profiled out): LR = n_eff log(rss0 / rss1), p = chi2_k sf,
/// dBIC = -LR + k log(n_eff) (negative favours the larger model).
struct Evidence {
  double lr = 0;
  double p_value = 1;
  double delta_bic = 0;
  double n_eff = 0;
  int k = 0;
};
Evidence compareNested(double rss0, double rss1, int k, double n_eff);

/// Same with a known measurement-noise floor: the residual of n rows is model misfit plus
/// measurement error of at least `floor_var` per row (e.g. the noise of differenced
/// motion-capture poses and the time resolution of the model's window means), so the
/// profiled variance is rss / n + floor_var: LR = n_eff log((rss0/n + floor) / (rss1/n +
/// floor)). Improvements far below the measurement noise carry no evidence (with floor_var = 0
/// this is compareNested).
Evidence compareNestedWithFloor(double rss0, double rss1, double n, int k, double n_eff,
                                double floor_var);

/// Mean and the t statistic of the mean using the effective sample size.
struct BiasTest {
  double mean = 0, rms = 0, t = 0, p_value = 1, n_eff = 0;
  int n = 0;
};
BiasTest biasTest(const Eigen::VectorXd& r, const Groups& groups, int lags);

}  // namespace wheelchair::stats
