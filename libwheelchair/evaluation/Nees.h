// Normalised estimation error squared of position estimates against ground truth
// (docs/evaluation.md, "NEES").
//
// At every ground-truth time the estimate position p and its 2x2 covariance P are linearly
// interpolated (same rule and max_gap_s as associate()); with e = p - q,
//   NEES_k = e^T (P + R_gt)^-1 e,
// where R_gt is the ground-truth noise covariance (Pozyx ~ (0.1 m)^2 I; 0 for Vicon). A
// consistent filter has mean NEES = 2 (two degrees of freedom). The 95 % interval for the mean of
// N independent chi2(2) values is [chi2inv(0.025, 2N), chi2inv(0.975, 2N)] / N (Wilson-Hilferty
// approximation); successive samples of a filter are correlated, so the interval is optimistic.
// Positions must be those of the ground-truth point (apply the lever arm first; the heading's
// contribution to the tag-position covariance is not modelled here).
// Example:
//   NeesResult r = averageNees(est, gt, NeesOptions{});   // r.mean_nees ~ 2 if consistent
#pragma once

#include <cstddef>
#include <vector>

#include <Eigen/Core>

#include "libwheelchair/evaluation/Outliers.h"
#include "libwheelchair/evaluation/Trajectory.h"

namespace wheelchair::evaluation {

struct PositionEstimateStamped {
  double t_s;
  Eigen::Vector2d p_m;
  Eigen::Matrix2d cov_m2;  ///< symmetric positive definite
};

struct NeesOptions {
  double max_gap_s = 0.5;
  Eigen::Matrix2d gt_cov_m2 = Eigen::Matrix2d::Zero();
  OutlierOptions outliers;  ///< ground-truth outliers are excluded as in computeMetrics
};

struct NeesResult {
  double mean_nees;          ///< NaN when nothing matched
  std::size_t n;             ///< samples used
  double lower95, upper95;   ///< 95 % interval of the mean for a consistent estimator
  double fraction_inside95;  ///< share of samples with NEES_k <= chi2inv(0.95, 2) = 5.991
  std::vector<double> nees;  ///< per matched sample
};

/// Throws std::invalid_argument on unordered input.
NeesResult averageNees(const std::vector<PositionEstimateStamped>& est,
                       const std::vector<Position2DStamped>& gt, const NeesOptions& options);

}  // namespace wheelchair::evaluation
