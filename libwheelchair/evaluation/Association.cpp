#include "libwheelchair/evaluation/Association.h"

#include <cmath>

namespace wheelchair::evaluation {

Association associate(const Trajectory& est, const std::vector<Position2DStamped>& gt,
                      double max_gap_s, const Eigen::Vector2d& lever_arm_m) {
  checkTimeOrdered(est, "associate: estimate");
  checkTimeOrdered(gt, "associate: ground truth");
  Association a;
  a.n_gt_total = gt.size();
  for (std::size_t k = 0; k < gt.size(); ++k) {
    const auto& g = gt[k];
    if (!std::isfinite(g.x_m) || !std::isfinite(g.y_m)) continue;
    const auto p = interpolatePose(est, g.t_s, max_gap_s);
    if (!p) continue;
    a.est.push_back(bodyPointPosition(*p, lever_arm_m));
    a.gt.emplace_back(g.x_m, g.y_m);
    a.t.push_back(g.t_s);
    a.est_phi.push_back(p->phi_rad);
    a.gt_phi.push_back(g.phi_rad);
    a.gt_index.push_back(k);
  }
  a.n_matched = a.t.size();
  return a;
}

}  // namespace wheelchair::evaluation
