// CVODE integration of the state and Riccati ODEs against closed forms (matrix exponentials).
#include "libwheelchair/estimation/CdEkf.h"
#include "libwheelchair/stats/Distributions.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <unsupported/Eigen/MatrixFunctions>

#include <cmath>
#include <cstdlib>

using namespace wheelchair::estimation;

namespace {

// xdot = A x + B u, constant Q.
struct LinearModel : CdModel {
  Eigen::MatrixXd A, B, Qc;
  int stateDim() const override { return static_cast<int>(A.rows()); }
  void f(const Eigen::VectorXd& x, const Eigen::VectorXd& u, Eigen::VectorXd& xd) const override {
    xd = A * x + B * u;
  }
  void F(const Eigen::VectorXd&, const Eigen::VectorXd&, Eigen::MatrixXd& F) const override {
    F = A;
  }
  void Q(const Eigen::VectorXd&, const Eigen::VectorXd&, Eigen::MatrixXd& Q) const override {
    Q = Qc;
  }
};

LinearModel makeModel() {
  LinearModel m;
  m.A.resize(4, 4);
  // Lightly damped oscillator + a first-order lag + an integrator (like v, omega, pose).
  m.A << -0.3, 1.2, 0.0, 0.0,  //
      -1.2, -0.3, 0.0, 0.0,    //
      0.0, 0.5, -0.27, 0.0,    //
      0.0, 0.0, 1.0, 0.0;
  m.B.resize(4, 2);
  m.B << 0.0, 0.0,  //
      1.0, 0.0,     //
      0.05, 0.05,   //
      0.0, 0.0;
  m.Qc = Eigen::MatrixXd::Zero(4, 4);
  m.Qc.diagonal() << 0.01, 0.02, 0.003, 1e-4;
  m.Qc(0, 1) = m.Qc(1, 0) = 0.005;
  return m;
}

// Exact solution over dt with u linear from u0 to u1: augmented state [x; u; udot].
Eigen::VectorXd exactState(const LinearModel& m, const Eigen::VectorXd& x0,
                           const Eigen::VectorXd& u0, const Eigen::VectorXd& u1, double dt) {
  const int n = m.stateDim(), p = static_cast<int>(m.B.cols());
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n + 2 * p, n + 2 * p);
  M.topLeftCorner(n, n) = m.A;
  M.block(0, n, n, p) = m.B;
  M.block(n, n + p, p, p) = Eigen::MatrixXd::Identity(p, p);
  Eigen::VectorXd z(n + 2 * p);
  z << x0, u0, (u1 - u0) / dt;
  const Eigen::MatrixXd E = (M * dt).exp();
  return (E * z).head(n);
}

// Exact covariance over dt (Van Loan): Phi P0 Phi' + int_0^dt e^{As} Q e^{A's} ds.
Eigen::MatrixXd exactCov(const LinearModel& m, const Eigen::MatrixXd& P0, double dt) {
  const int n = m.stateDim();
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(2 * n, 2 * n);
  M.topLeftCorner(n, n) = -m.A;
  M.topRightCorner(n, n) = m.Qc;
  M.bottomRightCorner(n, n) = m.A.transpose();
  const Eigen::MatrixXd E = (M * dt).exp();
  const Eigen::MatrixXd Phi = E.bottomRightCorner(n, n).transpose();
  const Eigen::MatrixXd Qd = Phi * E.topRightCorner(n, n);
  return Phi * P0 * Phi.transpose() + Qd;
}

void runAgainstClosedForm(CvodeOptions::Method method) {
  const LinearModel m = makeModel();
  CvodeOptions o;
  o.method = method;
  o.rel_tol = 1e-10;
  o.abs_tol_state = 1e-12;
  o.abs_tol_cov = 1e-12;
  CdEkf ekf(m, o);
  Eigen::VectorXd x(4);
  x << 1.0, -0.5, 0.2, 0.0;
  Eigen::MatrixXd P = Eigen::MatrixXd::Identity(4, 4) * 0.1;
  P(0, 2) = P(2, 0) = 0.02;
  double t = 3.0;
  ekf.reset(t, x, P);
  // Uneven intervals, inputs linear within each and discontinuous between them (ReInit path).
  const double dts[] = {0.01, 0.5, 0.003, 1.7, 0.02, 0.25, 2.0, 1e-4, 0.7, 0.05};
  for (int k = 0; k < 10; ++k) {
    const double dt = dts[k];
    Eigen::VectorXd u0(2), u1(2);
    u0 << std::sin(k), 0.5 * k;
    u1 << std::cos(3 * k), -0.2 * k;
    const double ta = t;
    ekf.propagate(t + dt,
                  [&](double tt) -> Eigen::VectorXd { return u0 + (tt - ta) / dt * (u1 - u0); });
    x = exactState(m, x, u0, u1, dt);
    P = exactCov(m, P, dt);
    t += dt;
    EXPECT_NEAR((ekf.x() - x).cwiseAbs().maxCoeff(), 0.0, 1e-6) << "interval " << k;
    EXPECT_NEAR((ekf.P() - P).cwiseAbs().maxCoeff(), 0.0, 1e-6) << "interval " << k;
    EXPECT_EQ((ekf.P() - ekf.P().transpose()).cwiseAbs().maxCoeff(), 0.0);
  }
  EXPECT_DOUBLE_EQ(ekf.time(), t);
  EXPECT_GE(ekf.stats().intervals, 9);
}

}  // namespace

TEST(CdEkfLinear, AdamsMatchesMatrixExponential) {
  runAgainstClosedForm(CvodeOptions::Method::Adams);
}

TEST(CdEkfLinear, BdfMatchesMatrixExponential) {
  runAgainstClosedForm(CvodeOptions::Method::Bdf);
}

TEST(CdEkfLinear, JosephUpdateMatchesTextbookAndGates) {
  const LinearModel m = makeModel();
  CdEkf ekf(m, CvodeOptions{});
  Eigen::VectorXd x = Eigen::VectorXd::Zero(4);
  Eigen::MatrixXd P = Eigen::MatrixXd::Identity(4, 4);
  P(0, 1) = P(1, 0) = 0.3;
  ekf.reset(0, x, P);
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(1, 4);
  H(0, 0) = 1;
  H(0, 3) = 0.5;
  Eigen::MatrixXd R = Eigen::MatrixXd::Constant(1, 1, 0.04);
  Eigen::VectorXd y(1);
  y << 0.3;
  const UpdateResult r = ekf.update(y, H, R, wheelchair::stats::chi2Quantile(0.999, 1));
  ASSERT_TRUE(r.accepted);
  const Eigen::MatrixXd S = H * P * H.transpose() + R;
  const Eigen::MatrixXd K = P * H.transpose() * S.inverse();
  EXPECT_NEAR(r.nis, 0.09 / S(0, 0), 1e-12);
  EXPECT_LT((ekf.x() - K * y).norm(), 1e-12);
  EXPECT_LT((ekf.P() - (P - K * H * P)).norm(), 1e-12);  // optimal gain: Joseph = short form
  // A gross innovation is gated and leaves the filter untouched.
  const Eigen::VectorXd x1 = ekf.x();
  y << 50.0;
  const UpdateResult g = ekf.update(y, H, R, wheelchair::stats::chi2Quantile(0.999, 1));
  EXPECT_FALSE(g.accepted);
  EXPECT_GT(g.nis, 1000);
  EXPECT_EQ(ekf.x(), x1);
}

// The closed-form path (m <= 2) against the LDLT path and the textbook form, on random SPD
// problems of every state size the filters use, with suboptimal (non-symmetric-looking) H.
TEST(CdEkfLinear, ClosedFormJosephMatchesLdltPath) {
  std::srand(4711);
  for (int trial = 0; trial < 200; ++trial) {
    const int n = 2 + trial % 14;
    const int m = 1 + trial % 2;
    const Eigen::MatrixXd L = Eigen::MatrixXd::Random(n, n);
    const Eigen::MatrixXd P = L * L.transpose() + 0.1 * Eigen::MatrixXd::Identity(n, n);
    const Eigen::MatrixXd H = Eigen::MatrixXd::Random(m, n);
    const Eigen::MatrixXd LR = Eigen::MatrixXd::Random(m, m);
    const Eigen::MatrixXd R = LR * LR.transpose() + 0.01 * Eigen::MatrixXd::Identity(m, m);
    const Eigen::VectorXd y = Eigen::VectorXd::Random(m);
    const Eigen::VectorXd x0 = Eigen::VectorXd::Random(n);
    Eigen::VectorXd xa = x0, xb = x0;
    Eigen::MatrixXd Pa = P, Pb = P;
    const UpdateResult a = josephUpdate(xa, Pa, y, H, R, 0);
    const UpdateResult b = josephUpdateLdlt(xb, Pb, y, H, R, 0);
    ASSERT_TRUE(a.accepted && b.accepted);
    EXPECT_NEAR(a.nis, b.nis, 1e-9 * (1 + b.nis));
    EXPECT_LT((a.S - b.S).norm(), 1e-12 * (1 + b.S.norm()));
    EXPECT_LT((xa - xb).norm(), 1e-9 * (1 + xb.norm()));
    EXPECT_LT((Pa - Pb).norm(), 1e-9 * (1 + Pb.norm()));
    // Textbook short form for the optimal gain.
    const Eigen::MatrixXd S = H * P * H.transpose() + R;
    const Eigen::MatrixXd K = P * H.transpose() * S.inverse();
    EXPECT_LT((Pa - (P - K * H * P)).norm(), 1e-8 * (1 + P.norm()));
    EXPECT_LT((xa - (x0 + K * y)).norm(), 1e-9 * (1 + xa.norm()));
  }
  // Degenerate S (zero prior variance seen, zero noise) is rejected, state untouched, by both.
  Eigen::VectorXd x = Eigen::VectorXd::Ones(3);
  Eigen::MatrixXd P = Eigen::MatrixXd::Identity(3, 3);
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(2, 3);
  H(0, 0) = 1;
  H(1, 0) = 1;  // two rows measuring the same state, no noise: S singular
  const Eigen::MatrixXd R = Eigen::MatrixXd::Zero(2, 2);
  const Eigen::VectorXd y = Eigen::Vector2d(0.1, 0.1);
  const UpdateResult r = josephUpdate(x, P, y, H, R, 0);
  EXPECT_FALSE(r.accepted);
  EXPECT_TRUE(std::isinf(r.nis));
  EXPECT_EQ(x, Eigen::VectorXd::Ones(3));
  EXPECT_EQ(P, Eigen::MatrixXd::Identity(3, 3));
  const UpdateResult rl = josephUpdateLdlt(x, P, y, H, R, 0);
  EXPECT_FALSE(rl.accepted);
}

// The integration runs in time relative to reset(): the same intervals at t0 = 0 and at a
// UNIX-like t0 = 2^30 s (~1.07e9; stamps k * 2^-10 s, exactly representable at both offsets)
// give the same state and covariance to the bit, and the closed form to CVODE's tolerance.
// Before, a tolerance relative to |t| turned every interval into one Euler step there.
TEST(CdEkfLinear, ResultIsIndependentOfTheClockOffset) {
  const LinearModel m = makeModel();
  Eigen::VectorXd x0(4);
  x0 << 0.3, -0.1, 0.2, 0.0;
  const Eigen::MatrixXd P0 = 0.01 * Eigen::MatrixXd::Identity(4, 4);
  Eigen::VectorXd u(2);
  u << 0.4, -0.2;
  const auto run = [&](double t0, Eigen::MatrixXd* P) {
    CvodeOptions o;  // tight, so that the closed-form comparison below is sharp
    o.rel_tol = 1e-10;
    o.abs_tol_state = 1e-12;
    o.abs_tol_cov = 1e-12;
    CdEkf ekf(m, o);
    ekf.reset(t0, x0, P0);
    for (int k = 1; k <= 2048; ++k) {  // 2 s in ~1 ms intervals, some of them 1/8 of that
      const double t1 = t0 + std::ldexp(k, -10) + (k % 7 == 0 ? std::ldexp(1, -13) : 0.0);
      ekf.propagate(t1, [&](double) { return u; });
    }
    EXPECT_EQ(ekf.stats().short_intervals, 0);
    *P = ekf.P();
    return Eigen::VectorXd(ekf.x());
  };
  Eigen::MatrixXd Pa, Pb;
  const Eigen::VectorXd xa = run(0.0, &Pa);
  const Eigen::VectorXd xb = run(std::ldexp(1.0, 30), &Pb);
  EXPECT_EQ(xa, xb);
  EXPECT_EQ(Pa, Pb);
  const double T = 2.0;  // the last stamp, k = 2048
  const Eigen::VectorXd exact = exactState(m, x0, u, u, T);
  EXPECT_LT((xb - exact).cwiseAbs().maxCoeff(), 1e-6) << xb.transpose() << "\n"
                                                      << exact.transpose();
  EXPECT_LT((Pb - exactCov(m, P0, T)).cwiseAbs().maxCoeff(), 1e-6);
}

// setHeldTail: two random-walk states (zero rows of A and Q) that feed the others (a bias on
// x0, a scale-like term on x2). While their rows of P are zero the filter integrates only the
// leading 4 states: their means stay exactly constant, their rows of P exactly zero, and the
// rest matches the full 6-state integration and the closed form. Once their variance is
// non-zero (a group opened) the full system runs and the coupling shows in P.
TEST(CdEkfLinear, HeldTailIntegratesTheLeadingStatesOnlyWhileItsCovarianceIsZero) {
  const LinearModel core = makeModel();
  LinearModel m;
  m.A = Eigen::MatrixXd::Zero(6, 6);
  m.A.topLeftCorner(4, 4) = core.A;
  m.A(0, 4) = 1.0;   // x0dot += b
  m.A(2, 5) = -0.4;  // x2dot -= 0.4 k
  m.B = Eigen::MatrixXd::Zero(6, 2);
  m.B.topRows(4) = core.B;
  m.Qc = Eigen::MatrixXd::Zero(6, 6);
  m.Qc.topLeftCorner(4, 4) = core.Qc;
  CvodeOptions o;
  o.rel_tol = 1e-10;
  o.abs_tol_state = 1e-12;
  o.abs_tol_cov = 1e-12;
  Eigen::VectorXd x0(6);
  x0 << 1.0, -0.5, 0.2, 0.0, 0.03, 1.05;
  Eigen::MatrixXd P0 = Eigen::MatrixXd::Zero(6, 6);
  P0.topLeftCorner(4, 4) = 0.1 * Eigen::MatrixXd::Identity(4, 4);
  P0(0, 2) = P0(2, 0) = 0.02;
  Eigen::VectorXd u(2);
  u << 0.4, -0.2;
  const auto input = [&](double) { return u; };
  CdEkf held(m, o), full(m, o);
  held.setHeldTail(2);
  held.reset(0.0, x0, P0);
  full.reset(0.0, x0, P0);
  double t = 0;
  for (int k = 1; k <= 50; ++k) {
    t = 0.02 * k;
    held.propagate(t, input);
    full.propagate(t, input);
  }
  EXPECT_EQ(held.x().tail(2), x0.tail(2));
  EXPECT_EQ(held.P().bottomRows(2).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(held.P().rightCols(2).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_LT((held.x() - full.x()).cwiseAbs().maxCoeff(), 1e-8);
  EXPECT_LT((held.P() - full.P()).cwiseAbs().maxCoeff(), 1e-8);
  EXPECT_LT((held.x() - exactState(m, x0, u, u, t)).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_LT((held.P() - exactCov(m, P0, t)).cwiseAbs().maxCoeff(), 1e-6);
  // The tail opens: the full system (the bias variance flows into x0's covariance).
  Eigen::MatrixXd P1 = held.P();
  P1(4, 4) = 1e-4;
  P1(5, 5) = 4e-4;
  const Eigen::VectorXd x1 = held.x();
  held.setCovariance(P1);
  held.propagate(t + 1.0, input);
  EXPECT_GT(std::fabs(held.P()(0, 4)), 1e-6);
  EXPECT_GT(std::fabs(held.P()(2, 5)), 1e-6);
  EXPECT_LT((held.x() - exactState(m, x1, u, u, 1.0)).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_LT((held.P() - exactCov(m, P1, 1.0)).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_THROW(held.setHeldTail(6), std::invalid_argument);
}

namespace {
// A unicycle [v, phi, x, y] (vdot = -0.3 v + u0, phidot = u1, xdot = v cos phi, ydot = v sin
// phi: F depends on the state) with two states that do not enter f (a scale and a bias seen
// only by measurements): the consider tail of setHeldTail(2, true).
struct UnicycleWithConsiderTail : CdModel {
  int stateDim() const override { return 6; }
  void f(const Eigen::VectorXd& x, const Eigen::VectorXd& u, Eigen::VectorXd& xd) const override {
    xd = Eigen::VectorXd::Zero(6);
    xd << -0.3 * x(0) + u(0), u(1), x(0) * std::cos(x(1)), x(0) * std::sin(x(1)), 0.0, 0.0;
  }
  void F(const Eigen::VectorXd& x, const Eigen::VectorXd&, Eigen::MatrixXd& F) const override {
    F = Eigen::MatrixXd::Zero(6, 6);
    F(0, 0) = -0.3;
    F(2, 0) = std::cos(x(1));
    F(2, 1) = -x(0) * std::sin(x(1));
    F(3, 0) = std::sin(x(1));
    F(3, 1) = x(0) * std::cos(x(1));
  }
  void Q(const Eigen::VectorXd&, const Eigen::VectorXd&, Eigen::MatrixXd& Q) const override {
    Q = Eigen::MatrixXd::Zero(6, 6);
    Q(0, 0) = 0.01;
    Q(1, 1) = 0.02;
  }
};

// The consider tests' start: moving and turning, P0 with the correlations a consider update
// leaves (v with the scale, phi with the bias); a turning, accelerating input.
struct ConsiderStart {
  Eigen::VectorXd x0 = (Eigen::VectorXd(6) << 0.6, 0.3, 0.0, 0.0, 1.0, 0.0).finished();
  Eigen::MatrixXd P0 = [] {
    Eigen::MatrixXd P = Eigen::MatrixXd::Zero(6, 6);
    P.diagonal() << 1e-3, 1e-4, 1e-6, 1e-6, 2.5e-5, 1e-4;
    P(0, 4) = P(4, 0) = 3e-6;
    P(1, 5) = P(5, 1) = -5e-5;
    return P;
  }();
  static Eigen::VectorXd input(double t) {
    Eigen::VectorXd u(2);
    u << 0.3 + 0.2 * std::sin(2.0 * t), 0.5 * std::cos(1.3 * t);
    return u;
  }
};
}  // namespace

// setHeldTail(count, consider = true): the held states carry a non-zero covariance (Schmidt
// consider states). CVODE integrates only the leading states; P_xc is carried by the
// second-order Magnus transition matrix. Against the full 6-state integration over 2 s of
// 10 ms intervals on a turning, accelerating unicycle: P_xc within 1e-5 of its size (the
// Magnus step's O(dt^3) local error; CVODE's tolerance is 1e-10 here), P_xx and x as the full
// integration to its tolerance, P_cc and the tail's means unchanged. On a linear model (constant
// F) the step is the exact matrix exponential: P against the closed form.
TEST(CdEkfLinear, ConsiderTailCarriesItsCrossCovarianceWithTheTransitionMatrix) {
  const UnicycleWithConsiderTail m;
  CvodeOptions o;
  o.rel_tol = 1e-10;
  o.abs_tol_state = 1e-12;
  o.abs_tol_cov = 1e-14;
  const ConsiderStart start;
  const Eigen::VectorXd& x0 = start.x0;
  const Eigen::MatrixXd& P0 = start.P0;
  const auto& input = ConsiderStart::input;
  CdEkf held(m, o), full(m, o);
  held.setHeldTail(2, true);
  held.reset(0.0, x0, P0);
  full.reset(0.0, x0, P0);
  for (int k = 1; k <= 200; ++k) {
    held.propagate(0.01 * k, input);
    full.propagate(0.01 * k, input);
  }
  const Eigen::MatrixXd Pxc_full = full.P().topRightCorner(4, 2);
  const Eigen::MatrixXd Pxc_held = held.P().topRightCorner(4, 2);
  ASSERT_GT(Pxc_full.cwiseAbs().maxCoeff(), 1e-5);  // the pose picked up the correlations
  EXPECT_LT((Pxc_held - Pxc_full).cwiseAbs().maxCoeff(), 1e-5 * Pxc_full.cwiseAbs().maxCoeff());
  EXPECT_EQ(held.P().bottomRightCorner(2, 2), P0.bottomRightCorner(2, 2));
  EXPECT_EQ(held.x().tail(2), x0.tail(2));
  EXPECT_LT((held.x() - full.x()).cwiseAbs().maxCoeff(), 1e-8);
  EXPECT_LT((held.P().topLeftCorner(4, 4) - full.P().topLeftCorner(4, 4)).cwiseAbs().maxCoeff(),
            1e-10);
  EXPECT_EQ(held.P(), held.P().transpose());
  // A constant (linear) model gives the exact exponential: the Magnus step is exact there.
  LinearModel lin = makeModel();
  LinearModel aug;
  aug.A = Eigen::MatrixXd::Zero(5, 5);
  aug.A.topLeftCorner(4, 4) = lin.A;
  aug.B = Eigen::MatrixXd::Zero(5, 2);
  aug.B.topRows(4) = lin.B;
  aug.Qc = Eigen::MatrixXd::Zero(5, 5);
  aug.Qc.topLeftCorner(4, 4) = lin.Qc;
  Eigen::VectorXd y0 = Eigen::VectorXd::Zero(5);
  Eigen::MatrixXd Q0 = 0.1 * Eigen::MatrixXd::Identity(5, 5);
  Q0(0, 4) = Q0(4, 0) = 0.03;
  Q0(3, 4) = Q0(4, 3) = -0.02;
  CdEkf lh(aug, o);
  lh.setHeldTail(1, true);
  lh.reset(0.0, y0, Q0);
  for (int k = 1; k <= 50; ++k) lh.propagate(0.02 * k, input);
  EXPECT_LT((lh.P() - exactCov(aug, Q0, 1.0)).cwiseAbs().maxCoeff(), 1e-9);
}

// The consider step of each interval uses F at both of its ends: F(t0) at the state the
// interval starts from (after a restart taken from CVODE's first right-hand side, evaluated
// there exactly) and F(t1) at the integrated end state. Against the Magnus step computed here
// from the model's own F at (x(t0), u(t0)) and (x(t1), u(t1)), interval by interval (every
// propagate with a function input restarts CVODE): equal to rounding (measured: identical).
// Taking CVODE's second evaluation instead (t0 + its first step) is off by ~5e-12 of P_xc.
TEST(CdEkfLinear, ConsiderStepUsesTheJacobiansAtBothEndsOfEachInterval) {
  const UnicycleWithConsiderTail m;
  const ConsiderStart start;
  const Eigen::VectorXd& x0 = start.x0;
  const Eigen::MatrixXd& P0 = start.P0;
  const auto& input = ConsiderStart::input;
  CdEkf held(m, CvodeOptions{});
  held.setHeldTail(2, true);
  held.reset(0.0, x0, P0);
  for (int k = 1; k <= 30; ++k) {
    const double t0 = 0.01 * (k - 1), t1 = 0.01 * k;
    Eigen::MatrixXd F0, F1;
    m.F(held.x(), input(t0), F0);
    Eigen::MatrixXd Y = held.P().topRightCorner(4, 2);
    held.propagate(t1, input);
    m.F(held.x(), input(t1), F1);
    const Eigen::MatrixXd M = (0.5 * (t1 - t0)) * (F0 + F1).topLeftCorner(4, 4);
    Eigen::MatrixXd T = Y;
    for (int j = 1; j <= 4; ++j) {
      T = (M * T / static_cast<double>(j)).eval();
      Y += T;
    }
    const Eigen::MatrixXd Pxc = held.P().topRightCorner(4, 2);
    ASSERT_LE((Pxc - Y).cwiseAbs().maxCoeff(), 1e-14 * Y.cwiseAbs().maxCoeff()) << "interval " << k;
  }
}
