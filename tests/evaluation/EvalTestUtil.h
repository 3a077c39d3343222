// Shared trajectory generators for the evaluation tests.
#pragma once

#include <cmath>
#include <functional>
#include <string>

#include <gtest/gtest.h>
#include <Eigen/Core>

#include "libwheelchair/evaluation/Alignment.h"
#include "libwheelchair/evaluation/Trajectory.h"

namespace wheelchair::evaluation::testutil {

/// Samples f(t) -> (x, y, phi) at t = t0 + k dt, k = 0..n-1.
inline Trajectory sample(const std::function<Eigen::Vector3d(double)>& f, double t0, double dt,
                         int n) {
  Trajectory out;
  for (int k = 0; k < n; ++k) {
    const double t = t0 + k * dt;
    const Eigen::Vector3d p = f(t);
    out.push_back({t, p.x(), p.y(), p.z()});
  }
  return out;
}

/// A smooth wandering drive (not degenerate for alignment), heading = direction of travel.
inline Eigen::Vector3d wander(double t) {
  const double x = 0.5 * t + 2.0 * std::sin(0.15 * t);
  const double y = 3.0 * std::sin(0.1 * t) + 0.5 * std::cos(0.23 * t);
  const double dx = 0.5 + 0.3 * std::cos(0.15 * t);
  const double dy = 0.3 * std::cos(0.1 * t) - 0.115 * std::sin(0.23 * t);
  return {x, y, std::atan2(dy, dx)};
}

/// Applies T to every pose (position and heading).
inline Trajectory transformed(const Trajectory& traj, const SE2& T) {
  Trajectory out = traj;
  for (auto& p : out) {
    const Eigen::Vector2d q = T.apply({p.x_m, p.y_m});
    p.x_m = q.x();
    p.y_m = q.y();
    p.phi_rad = p.phi_rad + T.theta;
  }
  return out;
}

inline double angleDiff(double a, double b) {
  return std::remainder(a - b, 2.0 * M_PI);
}

inline std::string tempPath(const std::string& name) {
  return std::string(::testing::TempDir()) + "wc_eval_" + name;
}

}  // namespace wheelchair::evaluation::testutil
