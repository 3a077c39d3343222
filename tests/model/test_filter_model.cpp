// The EKF's continuous-time model: analytic Jacobians of f, h_sonar, h_pozyx against central
// differences in both obstacle forms (e), and the two forms (7)/(8) agreeing along a simulated
// drive with the closed-form position of the static obstacle (f).
#include "libwheelchair/model/FilterModel.h"
#include "libwheelchair/model/Kinematics.h"
#include "libwheelchair/model/VehicleParams.h"

#include "NumDiff.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace wheelchair::model {
namespace {

using testing::numericJacobian;
using testing::relativeError;

FilterModelParams nominalParams(ObstacleForm form) {
  const VehicleParams p;
  FilterModelParams fp;
  fp.ode = odeCoefficients(p.geom, lumpedTheta(p));
  fp.form = form;
  return fp;
}

FilterState randomState(std::mt19937& rng, ObstacleForm form) {
  std::uniform_real_distribution<double> u(-1, 1);
  FilterState x;
  x << 1.5 * u(rng), 1.5 * u(rng), 10 * u(rng), 10 * u(rng), 4 * u(rng), 0, 0;
  if (form == ObstacleForm::Cartesian) {
    x(kIdxO1) = 4 * u(rng);
    x(kIdxO2) = 4 * u(rng);
  } else {
    x(kIdxO1) = 0.3 + 4 * std::abs(u(rng));
    x(kIdxO2) = 3.1 * u(rng);
  }
  return x;
}

class FilterModelForms : public ::testing::TestWithParam<ObstacleForm> {};

TEST_P(FilterModelForms, ProcessJacobiansMatchNumerical) {
  const ObstacleForm form = GetParam();
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> u(-1, 1);
  FilterModelParams fp = nominalParams(form);
  fp.sonar_offset_m = {0.45, 0.0};
  const FilterModel m(fp);
  for (int k = 0; k < 300; ++k) {
    const FilterState x = randomState(rng, form);
    const FilterInput in(20 * u(rng), 20 * u(rng));
    auto fx = [&](const FilterState& y) { return m.f(y, in); };
    auto fu = [&](const FilterInput& w) { return m.f(x, w); };
    const FilterStateJacobian Fn = numericJacobian<7, 7>(fx, x);
    EXPECT_LT(relativeError(m.F(x, in), Fn), 1e-6) << "analytic\n"
                                                   << m.F(x, in) << "\nnumeric\n"
                                                   << Fn;
    EXPECT_LT(relativeError(m.G(x), numericJacobian<7, 2>(fu, in)), 1e-6);
  }
}

// The fused right-hand side the CD-EKF evaluates (fAndF): its Jacobian against central
// differences of f, its rate against the kinematics (1)/(7)/(8) evaluated from phi directly
// and against f.
TEST_P(FilterModelForms, FusedRhsMatchesNumericalJacobianAndKinematics) {
  const ObstacleForm form = GetParam();
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  const FilterModel m(nominalParams(form));
  for (int k = 0; k < 200; ++k) {
    const FilterState x = randomState(rng, form);
    const FilterInput in(20 * u(rng), 20 * u(rng));
    FilterState xd;
    FilterStateJacobian J;
    m.fAndF(x, in, xd, J);
    auto fx = [&](const FilterState& y) { return m.f(y, in); };
    EXPECT_LT(relativeError(J, numericJacobian<7, 7>(fx, x)), 1e-6);
    const double v = x(kIdxV), om = x(kIdxOmega);
    EXPECT_LT((xd.segment<3>(kIdxX) - poseRate(x(kIdxPhi), v, om)).norm(), 1e-12);
    const Eigen::Vector2d o = x.segment<2>(kIdxO1);
    const Eigen::Vector2d orate = form == ObstacleForm::Cartesian ? obstacleCartesianRate(o, v, om)
                                                                  : obstaclePolarRate(o, v, om);
    EXPECT_LT((xd.segment<2>(kIdxO1) - orate).norm(), 1e-12);
    EXPECT_EQ(xd, m.f(x, in));
  }
}

TEST_P(FilterModelForms, MeasurementJacobiansMatchNumerical) {
  const ObstacleForm form = GetParam();
  std::mt19937 rng(22);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int k = 0; k < 300; ++k) {
    FilterModelParams fp = nominalParams(form);
    fp.sonar_offset_m = {0.45 + 0.2 * u(rng), 0.2 * u(rng)};
    fp.pozyx_lever_arm_m = {0.5 * u(rng), 0.5 * u(rng)};
    const FilterModel m(fp);
    const FilterState x = randomState(rng, form);
    if (m.hSonar(x) < 0.05) continue;  // the range's gradient is singular at 0
    auto hs = [&](const FilterState& y) { return Eigen::Matrix<double, 1, 1>(m.hSonar(y)); };
    auto hp = [&](const FilterState& y) { return m.hPozyx(y); };
    auto hv = [&](const FilterState& y) { return Eigen::Matrix<double, 1, 1>(m.hV(y)); };
    auto hw = [&](const FilterState& y) { return Eigen::Matrix<double, 1, 1>(m.hOmega(y)); };
    EXPECT_LT(relativeError(m.HSonar(x), numericJacobian<1, 7>(hs, x)), 1e-6);
    EXPECT_LT(relativeError(m.HPozyx(x), numericJacobian<2, 7>(hp, x)), 1e-6);
    EXPECT_LT(relativeError(FilterModel::HV(), numericJacobian<1, 7>(hv, x)), 1e-6);
    EXPECT_LT(relativeError(FilterModel::HOmega(), numericJacobian<1, 7>(hw, x)), 1e-6);
  }
}

TEST_P(FilterModelForms, SonarRangeIsFromTheSonar) {
  const ObstacleForm form = GetParam();
  const FilterModel m(nominalParams(form));
  FilterState x = FilterState::Zero();
  x.segment<2>(kIdxO1) = FilterModel::obstacleFromWorld({0, 0, 0}, {2.45, 0.0}, form);
  EXPECT_NEAR(m.hSonar(x), 2.0, 1e-12);  // 2.45 m ahead of the axle, 2 m from the sonar
  x.segment<2>(kIdxO1) = FilterModel::obstacleFromWorld({0, 0, 0}, {0.45, 1.5}, form);
  EXPECT_NEAR(m.hSonar(x), 1.5, 1e-12);
  // Obstacle at the sonar: range 0, zero gradient rather than NaN.
  if (form == ObstacleForm::Cartesian) {
    x.segment<2>(kIdxO1) = Eigen::Vector2d(0.45, 0.0);
    EXPECT_EQ(m.hSonar(x), 0.0);
    EXPECT_TRUE(m.HSonar(x).allFinite());
  }
}

INSTANTIATE_TEST_SUITE_P(Both, FilterModelForms,
                         ::testing::Values(ObstacleForm::Cartesian, ObstacleForm::Polar),
                         [](const auto& info) {
                           return info.param == ObstacleForm::Cartesian ? "Cartesian" : "Polar";
                         });

TEST(FilterModel, PozyxLeverArm) {
  FilterModelParams fp = nominalParams(ObstacleForm::Cartesian);
  fp.pozyx_lever_arm_m = {-0.20, -0.10};
  const FilterModel m(fp);
  FilterState x = FilterState::Zero();
  x(kIdxX) = 1.0;
  x(kIdxY) = 2.0;
  x(kIdxPhi) = M_PI / 2;  // facing +y: body -x is world -y, body -y is world +x
  const Eigen::Vector2d tag = m.hPozyx(x);
  EXPECT_NEAR(tag(0), 1.0 + 0.10, 1e-12);
  EXPECT_NEAR(tag(1), 2.0 - 0.20, 1e-12);
}

TEST(FilterModel, StructureOfF) {
  const FilterModel m(nominalParams(ObstacleForm::Cartesian));
  FilterState x;
  x << 0.7, 0.2, 1, 2, 0.3, 2.0, 0.5;
  const FilterStateJacobian F = m.F(x);
  EXPECT_EQ(F(kIdxV, kIdxV), m.params().ode.a3);
  EXPECT_EQ(F(kIdxOmega, kIdxOmega), m.params().ode.a4);
  // Nothing depends on the position (x, y); the obstacle does not depend on the pose at all.
  EXPECT_TRUE(F.col(kIdxX).isZero());
  EXPECT_TRUE(F.col(kIdxY).isZero());
  EXPECT_TRUE((F.block<2, 3>(kIdxO1, kIdxX).isZero()));
  const FilterInputJacobian G = m.G();
  EXPECT_TRUE(G.bottomRows<5>().isZero());
  EXPECT_EQ(G(kIdxV, 0), G(kIdxV, 1));
  EXPECT_EQ(G(kIdxOmega, 0), -G(kIdxOmega, 1));
}

TEST(FilterModel, ConvertObstacleRoundTrip) {
  FilterState x;
  x << 0.7, 0.2, 1, 2, 0.3, -1.5, 0.5;
  const FilterState q =
      FilterModel::convertObstacle(x, ObstacleForm::Cartesian, ObstacleForm::Polar);
  EXPECT_NEAR(q(kIdxO1), std::hypot(1.5, 0.5), 1e-12);
  EXPECT_NEAR(q(kIdxO2), std::atan2(0.5, -1.5), 1e-12);
  const FilterState back =
      FilterModel::convertObstacle(q, ObstacleForm::Polar, ObstacleForm::Cartesian);
  EXPECT_LT((back - x).norm(), 1e-12);
  const FilterModel mp(nominalParams(ObstacleForm::Polar));
  FilterState w = q;
  w(kIdxO2) += 4 * M_PI;
  w(kIdxPhi) = -7.0;
  const FilterState wrapped = mp.wrapAngles(w);
  EXPECT_NEAR(wrapped(kIdxO2), q(kIdxO2), 1e-12);
  EXPECT_NEAR(wrapped(kIdxPhi), -7.0 + 2 * M_PI, 1e-12);
}

struct DriveStats {
  double max_err_forms = 0;  ///< |p_cartesian - polarToCartesian(q_polar)|
  double max_err_world = 0;  ///< |p_form - R(phi)'(p0 - o)| for both forms
  double min_d = 1e9, max_abs_v = 0, max_abs_omega = 0, min_omega = 0, max_omega = 0;
};

// (f) Integrates the filter model in both forms from rest along the same drive (currents as a
// function of time) and compares them through the change of variables and against the
// obstacle's closed-form position R(phi)'(p0 - o) from the integrated pose (the obstacle is
// static in the inertial frame).
template <typename Currents>
DriveStats runDrive(Currents currents, double T, const Eigen::Vector3d& pose0,
                    const Eigen::Vector2d& p0_world) {
  const FilterModel mc(nominalParams(ObstacleForm::Cartesian));
  const FilterModel mp(nominalParams(ObstacleForm::Polar));
  const double dt = 2e-3;
  FilterState xc = FilterState::Zero();
  xc.segment<3>(kIdxX) = pose0;
  xc.segment<2>(kIdxO1) = FilterModel::obstacleFromWorld(pose0, p0_world, ObstacleForm::Cartesian);
  FilterState xp = FilterModel::convertObstacle(xc, ObstacleForm::Cartesian, ObstacleForm::Polar);
  EXPECT_LT(
      (FilterModel::obstacleFromWorld(pose0, p0_world, ObstacleForm::Polar) - xp.segment<2>(kIdxO1))
          .norm(),
      1e-14);

  DriveStats st;
  const int n = static_cast<int>(std::lround(T / dt));
  for (int k = 0; k < n; ++k) {
    const FilterInput in = currents((k + 0.5) * dt);
    xc = mc.rk4Step(xc, in, dt);
    xp = mp.rk4Step(xp, in, dt);
    // Pose and velocities do not depend on the obstacle: identical in both.
    EXPECT_LT((xc.head<5>() - xp.head<5>()).norm(), 1e-12);
    const Eigen::Vector2d pc = xc.segment<2>(kIdxO1);
    const Eigen::Vector2d pp = polarToCartesian(xp.segment<2>(kIdxO1));
    st.max_err_forms = std::max(st.max_err_forms, (pc - pp).norm());
    EXPECT_NEAR(xp(kIdxO1), pc.norm(), 1e-8);
    EXPECT_NEAR(wrapAngle(xp(kIdxO2) - std::atan2(pc.y(), pc.x())), 0.0, 1e-8);
    EXPECT_NEAR(mc.hSonar(xc), mp.hSonar(xp), 1e-8);
    const Eigen::Vector2d pw =
        FilterModel::obstacleFromWorld(xc.segment<3>(kIdxX), p0_world, ObstacleForm::Cartesian);
    st.max_err_world = std::max({st.max_err_world, (pc - pw).norm(), (pp - pw).norm()});
    st.min_d = std::min(st.min_d, pc.norm());
    st.max_abs_v = std::max(st.max_abs_v, std::abs(xc(kIdxV)));
    st.max_abs_omega = std::max(st.max_abs_omega, std::abs(xc(kIdxOmega)));
    st.min_omega = std::min(st.min_omega, xc(kIdxOmega));
    st.max_omega = std::max(st.max_omega, xc(kIdxOmega));
    if (!xc.allFinite() || !xp.allFinite()) break;
  }
  return st;
}

TEST(FilterModel, FormsAgreeOnAStraightDrive) {
  // Equal currents from rest: omega stays exactly 0. Obstacle ahead-left, passed closely.
  const DriveStats st =
      runDrive([](double t) { return FilterInput(t < 4 ? 6.0 : 0.0, t < 4 ? 6.0 : 0.0); }, 10.0,
               {1.0, -2.0, 0.4}, {4.0, 0.5});
  EXPECT_EQ(st.max_abs_omega, 0.0);
  EXPECT_GT(st.max_abs_v, 0.5);
  EXPECT_GT(st.min_d, 0.3);
  EXPECT_LT(st.max_err_forms, 1e-8);
  EXPECT_LT(st.max_err_world, 1e-8);
}

TEST(FilterModel, FormsAgreeOnAPureRotation) {
  // Opposite currents from rest: v stays exactly 0, the obstacle circles the chair; beta
  // winds through +-pi several times (the polar state is not wrapped, the comparison is).
  const DriveStats st =
      runDrive([](double t) { return FilterInput(2.0, -2.0); }, 15.0, {0, 0, 0}, {-1.0, 2.0});
  EXPECT_EQ(st.max_abs_v, 0.0);
  EXPECT_GT(st.max_abs_omega, 1.0);
  EXPECT_LT(st.max_err_forms, 1e-8);
  EXPECT_LT(st.max_err_world, 1e-8);
}

TEST(FilterModel, FormsAgreeAlongAVaryingDrive) {
  // Straight start, then currents that make v and omega vary and omega change sign, with a
  // reversing phase.
  auto currents = [](double t) {
    if (t < 2) return FilterInput(5.0, 5.0);
    if (t < 12) return FilterInput(4.0 + 5.0 * std::sin(0.9 * t), 4.0 + 5.0 * std::cos(1.3 * t));
    return FilterInput(-6.0 + 2.0 * std::sin(2.0 * t), -5.0);
  };
  const DriveStats st = runDrive(currents, 20.0, {0.5, 0.2, -0.3}, {3.0, 4.0});
  EXPECT_GT(st.max_abs_v, 0.5);
  EXPECT_GT(st.max_omega, 0.1);
  EXPECT_LT(st.min_omega, -0.1);
  EXPECT_GT(st.min_d, 0.3);  // clear of the polar singularity at d = 0
  EXPECT_LT(st.max_err_forms, 1e-8);
  EXPECT_LT(st.max_err_world, 1e-8);
}

}  // namespace
}  // namespace wheelchair::model
