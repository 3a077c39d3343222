#include "libwheelchair/evaluation/Alignment.h"

#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

#include "libwheelchair/model/Kinematics.h"

namespace wheelchair::evaluation {

Eigen::Vector2d SE2::apply(const Eigen::Vector2d& p) const {
  const double c = std::cos(theta), s = std::sin(theta);
  return {c * p.x() - s * p.y() + x, s * p.x() + c * p.y() + y};
}

SE2 SE2::inverse() const {
  const double c = std::cos(theta), s = std::sin(theta);
  return {-(c * x + s * y), -(-s * x + c * y), -theta};
}

SE2 SE2::operator*(const SE2& o) const {
  const Eigen::Vector2d t = apply({o.x, o.y});
  return {t.x(), t.y(), model::wrapAngle(theta + o.theta)};
}

SE2 alignSE2(const std::vector<Eigen::Vector2d>& est, const std::vector<Eigen::Vector2d>& gt) {
  if (est.size() != gt.size() || est.empty()) {
    throw std::invalid_argument(fmt::format(
        "alignSE2: need equal, non-zero numbers of points (est {}, gt {})", est.size(), gt.size()));
  }
  const double n = static_cast<double>(est.size());
  Eigen::Vector2d mu_e = Eigen::Vector2d::Zero(), mu_g = Eigen::Vector2d::Zero();
  for (std::size_t k = 0; k < est.size(); ++k) {
    mu_e += est[k];
    mu_g += gt[k];
  }
  mu_e /= n;
  mu_g /= n;
  Eigen::Matrix2d H = Eigen::Matrix2d::Zero();
  for (std::size_t k = 0; k < est.size(); ++k) H += (est[k] - mu_e) * (gt[k] - mu_g).transpose();
  // maximise tr(R H): c (H00 + H11) + s (H01 - H10).
  const double theta = std::atan2(H(0, 1) - H(1, 0), H(0, 0) + H(1, 1));
  SE2 T{0.0, 0.0, theta};
  const Eigen::Vector2d t = mu_g - T.apply(mu_e);
  T.x = t.x();
  T.y = t.y();
  return T;
}

const char* toString(Alignment a) {
  switch (a) {
    case Alignment::None:
      return "none";
    case Alignment::Origin:
      return "origin";
    case Alignment::SE2:
      return "se2";
    case Alignment::SE2FirstSeconds:
      return "se2_first_seconds";
  }
  return "?";
}

namespace {
double rmsSpread(const std::vector<Eigen::Vector2d>& p) {
  if (p.empty()) return 0.0;
  Eigen::Vector2d mu = Eigen::Vector2d::Zero();
  for (const auto& q : p) mu += q;
  mu /= static_cast<double>(p.size());
  double s = 0.0;
  for (const auto& q : p) s += (q - mu).squaredNorm();
  return std::sqrt(s / static_cast<double>(p.size()));
}
}  // namespace

SE2 computeAlignment(const Association& a, Alignment alignment, double first_s, double* spread_m) {
  if (spread_m) *spread_m = 0.0;
  if (a.est.empty()) return {};
  switch (alignment) {
    case Alignment::None:
      return {};
    case Alignment::Origin: {
      // evo --align_origin: T = Q0 P0^-1. Without a ground-truth heading only the translation
      // is defined, so the rotation is left at zero.
      const double th =
          std::isfinite(a.gt_phi[0]) ? model::wrapAngle(a.gt_phi[0] - a.est_phi[0]) : 0.0;
      SE2 T{0.0, 0.0, th};
      const Eigen::Vector2d t = a.gt[0] - T.apply(a.est[0]);
      T.x = t.x();
      T.y = t.y();
      return T;
    }
    case Alignment::SE2: {
      if (spread_m) *spread_m = rmsSpread(a.gt);
      return alignSE2(a.est, a.gt);
    }
    case Alignment::SE2FirstSeconds: {
      std::vector<Eigen::Vector2d> e, g;
      for (std::size_t k = 0; k < a.t.size() && a.t[k] - a.t[0] <= first_s; ++k) {
        e.push_back(a.est[k]);
        g.push_back(a.gt[k]);
      }
      if (spread_m) *spread_m = rmsSpread(g);
      return alignSE2(e, g);
    }
  }
  return {};
}

Association applyAlignment(const Association& a, const SE2& T) {
  Association out = a;
  for (std::size_t k = 0; k < out.est.size(); ++k) {
    out.est[k] = T.apply(a.est[k]);
    out.est_phi[k] = model::wrapAngle(T.applyHeading(a.est_phi[k]));
  }
  return out;
}

}  // namespace wheelchair::evaluation
