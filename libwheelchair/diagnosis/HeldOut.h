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
// Example:
//   double p = blockBootstrapProbNotPositive({0.1, -0.02, 0.05, ...}, 20);   // p < 0.05: helps
//   enforceHeldOutRule(rep);   // after every analyser has added its findings
#pragma once

#include "libwheelchair/diagnosis/Finding.h"

#include <string>
#include <vector>

namespace wheelchair::diagnosis {

double blockBootstrapProbNotPositive(const std::vector<double>& d, int block, int resamples = 2000,
                                     unsigned seed = 16);

/// Keys of fit_before / fit_after that are held-out predictions (larger = worse).
const std::vector<std::string>& heldOutKeys();

/// Removes findings whose own held-out prediction gets worse (see header); returns how many.
int enforceHeldOutRule(DiagnosisReport& rep);

}  // namespace wheelchair::diagnosis
