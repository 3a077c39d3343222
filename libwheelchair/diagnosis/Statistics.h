// Statistics shared by the diagnosis stages (docs/diagnosis-design.md, docs/discovery.md):
// least squares with a heteroscedasticity- and autocorrelation-consistent (Newey-West)
// covariance, the effective sample size of autocorrelated residuals, Ljung-Box whiteness,
// and the evidence comparison of two nested linear models (likelihood ratio on the effective
// sample size, BIC difference).
//
// Residual series are organised in GROUPS (e.g. the right-motor and the left-motor equation
// errors, or one recording each): lags never cross a group boundary.
//
// Example:
//   LinearFit f = fitLinear(X, y, groups, 10);      // beta, HAC covariance, RSS
//   double ne = effectiveSampleSize(f.residual, groups, 10);
//   Evidence e = compareNested(rss0, rss1, k_added, ne);
#pragma once

#include <Eigen/Core>

#include <string>
#include <utility>
#include <vector>

namespace wheelchair::diagnosis {

/// Half-open index ranges [begin, end) of contiguous series in a stacked vector.
using Groups = std::vector<std::pair<int, int>>;

/// One group covering all n samples.
Groups singleGroup(int n);

struct LinearFit {
  Eigen::VectorXd beta;
  Eigen::MatrixXd cov;  ///< Newey-West (Bartlett) sandwich covariance of beta
  Eigen::VectorXd residual;
  double rss = 0;
  int rank = 0;
  bool ok = false;  ///< false when the design is rank deficient
};

/// Ordinary least squares y ~ X beta (column-pivoted QR; rank tolerance relative 1e-10 on
/// equilibrated columns) with the HAC covariance over `lags` (Bartlett weights) within groups.
LinearFit fitLinear(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, const Groups& groups,
                    int lags);

/// Effective number of independent samples of a residual series: n * gamma0 / LRV, with the
/// long-run variance LRV = gamma0 + 2 sum_{k<=lags} (1 - k/(lags+1)) gamma_k (Bartlett), summed
/// over groups; clamped to [1, n].
double effectiveSampleSize(const Eigen::VectorXd& r, const Groups& groups, int lags);

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

/// Upper tail of chi2(k).
double chi2Sf(double x, double k);
/// Standard normal two-sided p-value of |z|.
double normalTwoSidedP(double z);

/// Mean and the t statistic of the mean using the effective sample size.
struct BiasTest {
  double mean = 0, rms = 0, t = 0, p_value = 1, n_eff = 0;
  int n = 0;
};
BiasTest biasTest(const Eigen::VectorXd& r, const Groups& groups, int lags);

}  // namespace wheelchair::diagnosis
