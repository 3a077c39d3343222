// The held-out rule every analyser's findings obey (issue 16): a finding is reported only if
// it predicts data it was not fitted on better -- in the quantity it concerns (the window
// residual of its channel: rad, A, m/s, rad/s) AND in the trajectory (dead-reckoned or
// open-loop drift, m / deg) -- and never if any of those held-out predictions gets worse.
//
// Two pieces:
//  - blockBootstrapProbNotPositive: moving-block bootstrap of the MEAN of paired held-out
//    gains d_i = loss_without_i - loss_with_i (autocorrelated, misspecified residuals: no
//    asymptotic n_eff test). Returns the fraction of resamples whose mean is <= 0 (a one-sided
//    p-value of "the term helps"). Blocks of `block` consecutive values (>= 1), wrapped within
//    the series; `resamples` draws with a fixed seed (deterministic).
//  - enforceHeldOutRule(rep): the safety net over a finished report. Every finding whose
//    fit_after is WORSE than its fit_before in any held-out key (validation_rms_*, drift_10s_m,
//    drift_60s_m, heading_drift_10s_deg, heading_drift_60s_deg,
//    odometry_{mean,end}_position_error_m, odometry_end_heading_error_deg; keys present in
//    both, larger is worse) is removed from `findings` and
//    listed in rep.info["rejected_heldout"] with the numbers ({effect, analyser, reason,
//    fit_before, fit_after, worse: [key...]}). `mismatch` is recomputed from what remains
//    only when no finding remains and nothing else set it (info "insufficient_data" keeps it).
//    Exception: a finding whose stage says the held-out data cannot test it (evidence
//    "validation_tested": false -- predicted held-out LR gain below threshold) has a held-out
//    residual change that is noise; its validation_rms_* keys are not judged and evidence
//    "heldout" says "not testable" (trajectory keys still are).
//
//  - blockedCvTerm(A, y, j, ...): blocked cross-validation of regressor j of the linear fit
//    y ~ A b (rows in time order). The rows are cut into `blocks` contiguous time blocks; each
//    block is predicted from a fit on the others, with and without column j, and the paired
//    per-row gains d_i = e_without_i^2 - e_with_i^2 (unit of y squared) go to the moving-block
//    bootstrap above (p_not_positive). The delete-one-block jackknife of b_j,
//    se = sqrt((K-1)/K sum_k (b_j(-k) - mean)^2), is its uncertainty including what the
//    model's misspecification does to it from one stretch of the drive to the next (a physical
//    constant is the same in every block; a regressor borrowing unexplained structure is not).
//    kept(alpha): the term predicts the blocks it was not fitted on better (p_not_positive <
//    alpha) AND its coefficient is larger than that block-to-block uncertainty
//    (|b_j| >= z_{1-alpha/2} se). Too few rows (< 20 per block and column): not testable,
//    not kept. Normal equations per block (k x k), so memory is A's only.
//
// Example:
//   double p = blockBootstrapProbNotPositive({0.1, -0.02, 0.05, ...}, 20);   // p < 0.05: helps
//   BlockedCvTerm c = blockedCvTerm(A, y, 2, 10, 50);  // column 2, 10 blocks, 1-s resampling
//   if (!c.kept(0.01)) /* not a finding */;
//   enforceHeldOutRule(rep);   // after every analyser has added its findings
#pragma once

#include "libwheelchair/diagnosis/Finding.h"

#include <Eigen/Core>

#include <functional>
#include <string>
#include <vector>

namespace wheelchair::diagnosis {

double blockBootstrapProbNotPositive(const std::vector<double>& d, int block, int resamples = 2000,
                                     unsigned seed = 16);

/// Blocked cross-validation of one regressor (see header).
struct BlockedCvTerm {
  bool testable = false;
  double mean_gain = 0;       ///< mean held-out squared-error gain per row (unit of y squared)
  double p_not_positive = 1;  ///< moving-block bootstrap of mean_gain <= 0
  double coef = 0;            ///< b_j fitted on all rows
  double coef_se = 0;         ///< delete-one-block jackknife standard error of b_j
  bool kept(double alpha) const;
  nlohmann::json toJson() const;
};

BlockedCvTerm blockedCvTerm(const Eigen::MatrixXd& A, const Eigen::VectorXd& y, int j,
                            int blocks = 10, int boot_block = 1);
/// Rows [r0, r1) of the design (r1 - r0 rows), made on demand.
using CvRows = std::function<Eigen::MatrixXd(Eigen::Index r0, Eigen::Index r1)>;
/// The same on an n x k design that is never stored whole: `rows` gives one time block of it at
/// a time (twice per block; memory: one block's rows, n / blocks x k). Same numbers as on A.
BlockedCvTerm blockedCvTerm(const CvRows& rows, Eigen::Index n, Eigen::Index k,
                            const Eigen::VectorXd& y, int j, int blocks = 10, int boot_block = 1);

/// Keys of fit_before / fit_after that are held-out predictions (larger = worse).
const std::vector<std::string>& heldOutKeys();

/// Removes findings whose own held-out prediction gets worse (see header); returns how many.
int enforceHeldOutRule(DiagnosisReport& rep);

}  // namespace wheelchair::diagnosis
