// Trajectory metrics compatible with evo (docs/evaluation.md has the formulas).
//
// Pipeline of computeMetrics(est, gt, options):
//   1. flag ground-truth outliers (detectGtOutliers) and drop them;
//   2. associate by interpolating the estimate at the remaining ground-truth times, moving the
//      estimate to the tag point x + R(phi) l (options.lever_arm_m);
//   3. align (None / Origin / SE2 / SE2FirstSeconds) -> T; est <- T(est), est_phi <- est_phi+theta;
//   4. ATE  = evo_ape translation part: e_k = |p_k - q_k|, rmse / mean / median / max / std;
//      RPE  = evo_rpe -r trans_part -d D -u m (consecutive pairs, evo's filter_pairs_by_path)
//             |dP - R(phi_e,i - phi_g,i) dQ|, RMSE over pairs; without a ground-truth heading
//             phi_g,i := phi_e,i (aligned), i.e. |dP - dQ| in the aligned world frame;
//      heading drift, terminal error (ATE at the last match), loop error, path length.
// Example:
//   MetricOptions opt;  opt.lever_arm_m = {0.2, 0.0};  opt.alignment = Alignment::Origin;
//   Metrics m = computeMetrics(est, gt, opt);
//   writeMetricsCsv("metrics.csv", {{"ekf", m}}, opt.alignment);
#pragma once

#include <cstddef>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "libwheelchair/evaluation/Alignment.h"
#include "libwheelchair/evaluation/Association.h"
#include "libwheelchair/evaluation/Outliers.h"
#include "libwheelchair/evaluation/Trajectory.h"

namespace wheelchair::evaluation {

/// Which trajectory's travelled distance selects the RPE pairs. evo_rpe uses the estimate by
/// default and the reference with --pairs_from_reference.
enum class RpePairsFrom { Reference, Estimate };

/// How heading_drift_deg was obtained.
enum class HeadingDriftMethod { Unavailable, GroundTruthHeading, DirectionOfTravel };
const char* toString(HeadingDriftMethod m);

struct MetricOptions {
  Alignment alignment = Alignment::SE2;                   ///< evo -a
  double align_first_s = 10.0;                            ///< window of Alignment::SE2FirstSeconds
  double max_gap_s = 0.5;                                 ///< see associate()
  Eigen::Vector2d lever_arm_m = Eigen::Vector2d::Zero();  ///< tag position in the body frame
  OutlierOptions outliers;
  RpePairsFrom rpe_pairs_from = RpePairsFrom::Reference;  ///< evo --pairs_from_reference
  /// Direction-of-travel heading drift: length of the initial / final segments (measured along
  /// the matched estimate positions) and the minimum RMS spread of their ground truth.
  double heading_segment_m = 2.0;
  double heading_min_spread_m = 0.2;
};

struct Metrics {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  double d_path_m = kNaN;          ///< pathLength(est) (body positions, whole estimate)
  double d_path_gt_m = kNaN;       ///< path length of the matched, outlier-free ground truth
  double terminal_error_m = kNaN;  ///< ATE at the last matched sample (after alignment)
  double loop_error_m = kNaN;      ///< |last - first| body position of the estimate
  double ate_rmse_m = kNaN, ate_mean_m = kNaN, ate_median_m = kNaN, ate_max_m = kNaN,
         ate_std_m = kNaN;
  double rpe_1m_m = kNaN, rpe_5m_m = kNaN;  ///< RPE translation RMSE, delta 1 m / 5 m
  std::size_t n_rpe_1m = 0, n_rpe_5m = 0;   ///< pairs used
  double heading_drift_deg = kNaN;
  HeadingDriftMethod heading_drift_method = HeadingDriftMethod::Unavailable;
  std::size_t n_matched = 0;                 ///< matched, outlier-free ground-truth samples
  std::size_t n_gt = 0;                      ///< ground-truth samples given
  std::size_t n_outliers = 0;                ///< flagged and excluded
  std::vector<std::size_t> outlier_indices;  ///< indices into the ground-truth input
  SE2 alignment;                             ///< T applied to the estimate
  double alignment_spread_m = 0.0;           ///< see computeAlignment()
};

/// evo-style statistics of an error vector (population std as numpy). NaN when empty.
struct ErrorStats {
  double rmse, mean, median, max, min, std;
  std::size_t n;
};
ErrorStats errorStats(const std::vector<double>& e);

/// evo filter_pairs_by_path (consecutive pairs): walk the positions accumulating the distance
/// between successive samples; each time it reaches delta_m record the index and restart the
/// accumulation at 0; pairs are successive recorded indices.
std::vector<std::pair<std::size_t, std::size_t>> pairsByPath(
    const std::vector<Eigen::Vector2d>& positions, double delta_m);

/// RPE translation errors of an (aligned) association, one per pair (see the header comment).
std::vector<double> rpeTranslationErrors(const Association& aligned, double delta_m,
                                         RpePairsFrom from);

/// Heading drift (deg, wrapped to (-180, 180]) of an aligned association; see docs.
double headingDriftDeg(const Association& aligned, const MetricOptions& options,
                       HeadingDriftMethod* method = nullptr);

/// Full pipeline. Throws std::invalid_argument on unordered input; with no match the error
/// metrics are NaN (n_matched = 0).
Metrics computeMetrics(const Trajectory& est, const std::vector<Position2DStamped>& gt,
                       const MetricOptions& options);

/// Steps 1-3 of computeMetrics: returns the aligned association (and the outlier report, the
/// unaligned association and the transform if asked).
Association alignedAssociation(const Trajectory& est, const std::vector<Position2DStamped>& gt,
                               const MetricOptions& options, OutlierReport* outliers = nullptr,
                               Association* unaligned = nullptr, SE2* T = nullptr,
                               double* spread_m = nullptr);

/// CSV with a header line; columns (units in the names):
/// name,d_path_m,d_path_gt_m,terminal_error_m,loop_error_m,ate_rmse_m,ate_mean_m,ate_median_m,
/// ate_max_m,rpe_1m_m,rpe_5m_m,heading_drift_deg,n_matched,n_gt,n_outliers,alignment
std::string metricsCsvHeader();
std::string metricsCsvRow(const std::string& name, const Metrics& m, Alignment alignment);
void writeMetricsCsv(const std::string& path,
                     const std::vector<std::pair<std::string, Metrics>>& rows, Alignment alignment);

/// Files for checking the numbers with evo (scripts/evo_check.sh): at the matched, outlier-free
/// ground-truth times writes
///   <prefix>gt.tum          ground truth; heading = ground-truth heading, or, when it has none,
///                           the aligned estimate's heading (so evo's RPE equals ours),
///   <prefix>est.tum         estimate at the tag point, interpolated, NOT aligned,
///   <prefix>est_aligned.tum the same after options.alignment.
/// Identical timestamps make evo's nearest-time association exact.
void writeEvoFiles(const std::string& prefix, const Trajectory& est,
                   const std::vector<Position2DStamped>& gt, const MetricOptions& options);

}  // namespace wheelchair::evaluation
