// Rigid planar alignment of an estimate to ground truth (docs/evaluation.md, "Alignment").
//
// alignSE2 is the Umeyama (1991) / Horn closed form without scale, restricted to the plane:
//   mu_e, mu_g centroids, H = sum (e_k - mu_e)(g_k - mu_g)^T,
//   theta = atan2(H01 - H10, H00 + H11),  t = mu_g - R(theta) mu_e,
// minimising sum |g_k - (R e_k + t)|^2. It equals evo's `-a` (SE(3) Umeyama on positions) for
// planar data unless a mirror image fits better (evo could then return a 180 deg roll).
// Example:
//   SE2 T = alignSE2(est_xy, gt_xy);   // gt ~ T.apply(est)
#pragma once

#include <cstddef>
#include <vector>

#include <Eigen/Core>

#include "libwheelchair/evaluation/Association.h"

namespace wheelchair::evaluation {

/// Planar rigid transform p -> R(theta) p + (x, y).
struct SE2 {
  double x = 0.0, y = 0.0, theta = 0.0;
  Eigen::Vector2d apply(const Eigen::Vector2d& p) const;
  /// Heading of a pose after the transform: phi + theta (not wrapped).
  double applyHeading(double phi_rad) const { return phi_rad + theta; }
  SE2 inverse() const;
  /// (this * other).apply(p) == this->apply(other.apply(p)).
  SE2 operator*(const SE2& other) const;
};

/// Least-squares SE(2) mapping est onto gt (equal sizes; throws std::invalid_argument otherwise
/// or when empty). With fewer than two distinct points the rotation is undetermined and 0.
SE2 alignSE2(const std::vector<Eigen::Vector2d>& est, const std::vector<Eigen::Vector2d>& gt);

enum class Alignment {
  None,            ///< compare in the estimate's own frame
  Origin,          ///< first matched poses coincide (translation; + rotation when GT has heading)
  SE2,             ///< alignSE2 over all matched pairs (evo -a)
  SE2FirstSeconds  ///< alignSE2 over the pairs within the first N seconds (evo -a --n_to_align)
};

const char* toString(Alignment a);

/// The transform of the chosen alignment for an association (not modified). `first_s` is the
/// window of SE2FirstSeconds measured from the first matched time. Identity when empty.
/// `spread_m` (optional) receives the RMS distance of the ground-truth points used from their
/// centroid: a rotation fitted to points with a spread near the ground-truth noise is
/// meaningless (e.g. a standstill at the start with SE2FirstSeconds).
SE2 computeAlignment(const Association& a, Alignment alignment, double first_s = 0.0,
                     double* spread_m = nullptr);

/// Applies T to est, est_phi of an association (ground truth unchanged).
Association applyAlignment(const Association& a, const SE2& T);

}  // namespace wheelchair::evaluation
