// Command-driven model (libwheelchair/model/CommandDriven.h): nominal form = unicycle driven by
// its commands; analytic F and G against central differences (lag on/off per channel); exact
// lag step; kinds and gains; deadband; the command signal's quirk handling.
#include "libwheelchair/model/CommandDriven.h"

#include "NumDiff.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace wheelchair::model {
namespace {

using testing::numericJacobian;
using testing::relativeError;

CommandResponseParams extended(bool lag_v, bool lag_w) {
  CommandResponseParams p;
  p.v.delay_s = 0.1;
  p.omega.delay_s = 0.15;
  if (lag_v) p.v.time_constant_s = 0.3;
  if (lag_w) p.omega.time_constant_s = 0.2;
  p.omega_gain[static_cast<int>(CommandKind::TurnInPlace)] = 0.7;
  p.v_gain[static_cast<int>(CommandKind::Arc)] = 0.9;
  return p;
}

TEST(CommandDriven, AnalyticJacobiansMatchCentralDifferences) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-1, 1);
  for (int lv = 0; lv < 2; ++lv)
    for (int lw = 0; lw < 2; ++lw) {
      const CommandDrivenModel m(extended(lv, lw));
      for (int trial = 0; trial < 20; ++trial) {
        CommandState x;
        x << 5 * U(rng), 5 * U(rng), 3.1 * U(rng), 0.3 * U(rng), U(rng);
        const Eigen::Vector2d u(0.3 * U(rng), U(rng));
        const auto fx = [&](const CommandState& xx) { return m.f(xx, u); };
        const auto fu = [&](const Eigen::Vector2d& uu) { return m.f(x, uu); };
        EXPECT_LT(relativeError(m.F(x, u), numericJacobian<5, 5>(fx, x)), 1e-8);
        EXPECT_LT(relativeError(m.G(x, u), numericJacobian<5, 2>(fu, u)), 1e-8);
      }
    }
}

TEST(CommandDriven, NominalIsTheUnicycleDrivenByItsCommands) {
  const CommandDrivenModel m;
  EXPECT_TRUE(m.params().isNominal());
  CommandState x = CommandState::Zero();
  const Eigen::Vector2d u(0.2, 0.5);
  for (int k = 0; k < 1000; ++k) x = m.step(x, m.target(u), 0.01);  // 10 s of an arc
  // Exact circle: radius v/omega = 0.4 m, turned 5 rad.
  EXPECT_NEAR(x(kCmdX), 0.4 * std::sin(5.0), 1e-9);
  EXPECT_NEAR(x(kCmdY), 0.4 * (1 - std::cos(5.0)), 1e-9);
  EXPECT_NEAR(x(kCmdPhi), 5.0, 1e-12);
  EXPECT_DOUBLE_EQ(x(kCmdV), 0.2);
  EXPECT_DOUBLE_EQ(x(kCmdOmega), 0.5);
}

TEST(CommandDriven, LagStepIsExact) {
  const double tau = 0.3, c = 0.2;
  double y = 0, integral = 0;
  for (int k = 0; k < 100; ++k) {
    const auto s = lagStep(y, c, 0.01, tau);
    integral += s.integral;
    y = s.y_next;
  }
  EXPECT_NEAR(y, c * (1 - std::exp(-1.0 / tau)), 1e-14);
  EXPECT_NEAR(integral, c * (1.0 - tau * (1 - std::exp(-1.0 / tau))), 1e-14);
  // step() (exact velocities, Simpson on the pose) agrees with tiny Euler steps of f.
  const CommandDrivenModel m(extended(true, true));
  CommandState x0;
  x0 << 1, 2, 0.3, 0.05, -0.2;
  const Eigen::Vector2d u(0.15, 0.6);
  CommandState xe = x0;
  for (int k = 0; k < 200000; ++k) xe += 1e-5 * m.f(xe, u);
  CommandState xs = x0;
  for (int k = 0; k < 40; ++k) xs = m.step(xs, u, 0.05);
  EXPECT_LT((xs - xe).norm(), 1e-5);
}

TEST(CommandDriven, KindsGainsAndDeadband) {
  CommandResponseParams p = extended(false, false);
  p.v.deadband = 0.02;
  p.omega.deadband = 0.05;
  EXPECT_EQ(classifyCommand(0, 0, p), CommandKind::Stop);
  EXPECT_EQ(classifyCommand(0.1, 0, p), CommandKind::Straight);
  EXPECT_EQ(classifyCommand(0, 0.4, p), CommandKind::TurnInPlace);
  EXPECT_EQ(classifyCommand(0.1, 0.4, p), CommandKind::Arc);
  const CommandDrivenModel m(p);
  EXPECT_NEAR(m.target(Eigen::Vector2d(0, 0.4))(1), 0.28, 1e-12);    // in place x0.7
  EXPECT_NEAR(m.target(Eigen::Vector2d(0.1, 0.4))(1), 0.4, 1e-12);   // arc x1
  EXPECT_NEAR(m.target(Eigen::Vector2d(0.1, 0.4))(0), 0.09, 1e-12);  // arc v x0.9
  EXPECT_NEAR(m.target(Eigen::Vector2d(0.1, 0))(0), 0.1, 1e-12);
  EXPECT_EQ(m.target(Eigen::Vector2d(0.015, 0.03)).norm(), 0.0);  // both in the deadband
  p.v_gain_backward = 0.5;
  EXPECT_NEAR(CommandDrivenModel(p).target(Eigen::Vector2d(-0.1, 0))(0), -0.05, 1e-12);
}

TEST(CommandDriven, SignalResolvesDuplicatesAndShortZeroRuns) {
  // t: 0 moving, 0.01 duplicated (conflicting; last wins), 1.00/1.01 a two-line (0,0) blip,
  // 2.0 .. 2.5 a real stop.
  const std::vector<CommandSample> rows = {{0.00, 0.1, 0.0}, {0.01, 0.1, 0.2}, {0.01, 0.1, 0.3},
                                           {1.00, 0.0, 0.0}, {1.01, 0.0, 0.0}, {1.02, 0.1, 0.3},
                                           {2.00, 0.0, 0.0}, {2.50, 0.1, 0.3}};
  const CommandSignal raw(rows, {});
  EXPECT_EQ(raw.droppedDuplicates(), 1u);
  EXPECT_DOUBLE_EQ(raw.at(0.5)(1), 0.3);
  EXPECT_DOUBLE_EQ(raw.at(1.005)(0), 0.0);
  EXPECT_DOUBLE_EQ(raw.at(-1)(0), 0.0);
  CommandSignalOptions o;
  o.drop_short_zero_runs = true;
  const CommandSignal clean(rows, o);
  EXPECT_EQ(clean.droppedZeroRuns(), 1u);
  EXPECT_DOUBLE_EQ(clean.at(1.005)(0), 0.1);  // blip ignored
  EXPECT_DOUBLE_EQ(clean.at(2.2)(0), 0.0);    // the real stop kept
  const CommandDrivenModel m(extended(true, true));
  // target() reads each channel at t - its delay.
  EXPECT_NEAR(m.target(clean, 2.05)(0), 0.09, 1e-12);  // v at 1.95: arc, gain 0.9
  EXPECT_NEAR(m.target(clean, 2.12)(0), 0.0, 1e-12);   // v at 2.02: stopped
}

}  // namespace
}  // namespace wheelchair::model
