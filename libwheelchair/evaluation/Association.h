// Time association of an estimate with ground truth by linear interpolation of the estimate at
// each ground-truth time (docs/evaluation.md, "Association").
//
// For every ground-truth sample g (time t, finite position) the estimate pose is interpolated at
// t (x, y linearly, phi along the shorter arc); the sample is matched only when t lies inside
// the estimate's time span and the two bracketing estimate samples are at most max_gap_s apart
// (an estimate sample exactly at t always matches). The estimate position reported is that of
// the body point `lever_arm_m` (the ground-truth tag): x + R(phi) l, applied after interpolating
// the body pose. Differs from evo, which pairs nearest timestamps within --t_max_diff; see
// writeEvoFiles() to hand evo already-associated files.
// Example:
//   Association a = associate(est, gt, 0.5, Eigen::Vector2d(0.2, 0.0));
//   double e0 = (a.est[0] - a.gt[0]).norm();
#pragma once

#include <cstddef>
#include <vector>

#include <Eigen/Core>

#include "libwheelchair/evaluation/Trajectory.h"

namespace wheelchair::evaluation {

struct Association {
  std::vector<Eigen::Vector2d> est, gt;  ///< matched positions (estimate at the tag point), m
  std::vector<double> t;                 ///< ground-truth times of the matches, s
  std::vector<double> est_phi;           ///< interpolated estimate heading, (-pi, pi]
  std::vector<double> gt_phi;            ///< ground-truth heading, NaN when not measured
  std::vector<std::size_t> gt_index;     ///< index of each match in the ground-truth input
  std::size_t n_gt_total = 0;            ///< ground-truth samples given
  std::size_t n_matched = 0;             ///< == t.size()
};

/// Throws std::invalid_argument unless both inputs are strictly time-ordered.
/// Ground-truth samples with a non-finite position are skipped (not matched).
Association associate(const Trajectory& est, const std::vector<Position2DStamped>& gt,
                      double max_gap_s = 0.5,
                      const Eigen::Vector2d& lever_arm_m = Eigen::Vector2d::Zero());

}  // namespace wheelchair::evaluation
