// Robust flagging of ground-truth outliers (UWB multipath jumps) from the ground-truth track's
// own motion, independent of the estimate (docs/evaluation.md, "Ground-truth outliers").
//
// For each sample i the position is predicted from its neighbours (up to half_window samples on
// each side within window_s, already flagged samples excluded) by a constant-velocity model:
// every pair (a, b) with a before and b after i gives the linear interpolation at t_i (if one
// side has no neighbours, pairs on the other side extrapolate); the prediction is the
// component-wise median of these. The residual r_i = q_i - prediction. The scale is
// sigma = 1.4826 * MAD of all residual components (x and y pooled, flagged samples excluded), and
// i is an outlier when |r_i| > max(k_mad * sigma, floor_m). Repeated (up to max_iterations, until
// the flags stop changing) with the previous pass's outliers excluded from the neighbours and the
// scale, so that a burst of outliers no longer contaminates its neighbours' predictions.
// Example:
//   OutlierReport r = detectGtOutliers(gt, OutlierOptions{});
#pragma once

#include <cstddef>
#include <vector>

#include "libwheelchair/evaluation/Trajectory.h"

namespace wheelchair::evaluation {

struct OutlierOptions {
  bool enabled = true;
  int half_window = 3;    ///< neighbours used on each side
  double window_s = 1.0;  ///< neighbours farther away in time are ignored
  double k_mad = 5.0;     ///< threshold in robust standard deviations
  double floor_m = 0.10;  ///< never flag residuals below this (noise-free tracks: MAD = 0)
  int max_iterations = 5;
};

struct OutlierReport {
  std::vector<bool> is_outlier;      ///< per ground-truth sample
  std::vector<double> residual_m;    ///< |r_i| at the last iteration, NaN if not predictable
  std::vector<std::size_t> indices;  ///< flagged sample indices, increasing
  double sigma_m = 0.0;              ///< robust residual scale (per axis)
  double threshold_m = 0.0;          ///< max(k_mad * sigma, floor)
};

/// Ground truth must be time-ordered (throws std::invalid_argument otherwise). Samples with a
/// non-finite position are flagged. With options.enabled == false nothing else is flagged.
OutlierReport detectGtOutliers(const std::vector<Position2DStamped>& gt,
                               const OutlierOptions& options);

}  // namespace wheelchair::evaluation
