// estimation/FixedPointSolver: the project's fixed-point nonlinear solver gives CVODE exactly
// what SUNDIALS' SUNNonlinSol_FixedPoint (m = 0) gives it: the same solution bits, steps,
// iterations and convergence failures, across restarts, stop times and forced failures.
#include "libwheelchair/estimation/FixedPointSolver.h"

#include <cvode/cvode.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunnonlinsol/sunnonlinsol_fixedpoint.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <vector>

namespace {

using wheelchair::estimation::newFixedPointSolver;

// A damped, driven oscillator chain with a nonlinear coupling (6 states): smooth, non-stiff,
// so Adams with fixed-point iteration is the right method, as for the filter's Riccati ODE.
int rhs(sunrealtype t, N_Vector y, N_Vector ydot, void*) {
  const double* a = N_VGetArrayPointer(y);
  double* d = N_VGetArrayPointer(ydot);
  for (int i = 0; i < 3; ++i) {
    const double x = a[2 * i], v = a[2 * i + 1];
    const double next = a[(2 * i + 2) % 6];
    d[2 * i] = v;
    d[2 * i + 1] = -(1.0 + i) * x - 0.3 * v + 0.5 * std::sin(next) + std::cos(2.0 * t + i);
  }
  return 0;
}

struct SolverRun {
  std::vector<double> y;  // the solution at every output time, all states
  long steps = 0, iters = 0, conv_fails = 0, rhs_evals = 0;
};

// Integrates over 40 output intervals of 0.05 s, restarting (CVodeReInit, with a jump in the
// state as a measurement update would make) every 4th, with the stop time at each output.
SolverRun integrate(bool ours, double nonlin_conv_coef) {
  SUNContext ctx = nullptr;
  EXPECT_EQ(SUNContext_Create(nullptr, &ctx), 0);
  N_Vector y = N_VNew_Serial(6, ctx);
  double* a = N_VGetArrayPointer(y);
  for (int i = 0; i < 6; ++i) a[i] = 0.1 * (i + 1);
  void* mem = CVodeCreate(CV_ADAMS, ctx);
  EXPECT_EQ(CVodeInit(mem, rhs, 0.0, y), CV_SUCCESS);
  EXPECT_EQ(CVodeSStolerances(mem, 1e-6, 1e-9), CV_SUCCESS);
  SUNNonlinearSolver nls = ours ? newFixedPointSolver(y, ctx) : SUNNonlinSol_FixedPoint(y, 0, ctx);
  EXPECT_NE(nls, nullptr);
  EXPECT_EQ(CVodeSetNonlinearSolver(mem, nls), CV_SUCCESS);
  EXPECT_EQ(CVodeSetNonlinConvCoef(mem, nonlin_conv_coef), CV_SUCCESS);
  EXPECT_EQ(CVodeSetMaxNumSteps(mem, 100000), CV_SUCCESS);
  SolverRun r;
  double t = 0.0;
  for (int k = 1; k <= 40; ++k) {
    if (k % 4 == 0) {
      a[1] += 0.05;  // a jump: restart
      EXPECT_EQ(CVodeReInit(mem, t, y), CV_SUCCESS);
    }
    const double t1 = 0.05 * k;
    EXPECT_EQ(CVodeSetStopTime(mem, t1), CV_SUCCESS);
    EXPECT_GE(CVode(mem, t1, y, &t, CV_NORMAL), 0);
    r.y.insert(r.y.end(), a, a + 6);
    long n = 0;
    CVodeGetNumSteps(mem, &n);
    r.steps += n;
    CVodeGetNumNonlinSolvIters(mem, &n);
    r.iters += n;
    CVodeGetNumNonlinSolvConvFails(mem, &n);
    r.conv_fails += n;
    CVodeGetNumRhsEvals(mem, &n);
    r.rhs_evals += n;
  }
  CVodeFree(&mem);
  SUNNonlinSolFree(nls);
  N_VDestroy(y);
  SUNContext_Free(&ctx);
  return r;
}

void expectSame(const SolverRun& lib, const SolverRun& ours) {
  ASSERT_EQ(lib.y.size(), ours.y.size());
  EXPECT_EQ(std::memcmp(lib.y.data(), ours.y.data(), lib.y.size() * sizeof(double)), 0);
  EXPECT_EQ(lib.steps, ours.steps);
  EXPECT_EQ(lib.iters, ours.iters);
  EXPECT_EQ(lib.conv_fails, ours.conv_fails);
  EXPECT_EQ(lib.rhs_evals, ours.rhs_evals);
}

TEST(FixedPointSolver, CvodeGetsTheLibrarySolversBitsAndCounts) {
  const SolverRun lib = integrate(false, 0.1), ours = integrate(true, 0.1);
  EXPECT_GT(lib.steps, 100);
  EXPECT_GT(lib.iters, lib.steps - 1);
  expectSame(lib, ours);
}

TEST(FixedPointSolver, ConvergenceFailuresAreCountedAndRecoveredAsByTheLibrary) {
  // A very strict convergence coefficient makes CVODE's test fail within 3 iterations: the
  // solver must report SUN_NLS_CONV_RECVR so that CVODE shrinks the step and retries.
  const SolverRun lib = integrate(false, 1e-7), ours = integrate(true, 1e-7);
  EXPECT_GT(lib.conv_fails, 0);
  expectSame(lib, ours);
}

TEST(FixedPointSolver, RejectsMissingInputsAsTheLibrary) {
  SUNContext ctx = nullptr;
  ASSERT_EQ(SUNContext_Create(nullptr, &ctx), 0);
  N_Vector y = N_VNew_Serial(3, ctx);
  EXPECT_EQ(newFixedPointSolver(nullptr, ctx), nullptr);
  SUNNonlinearSolver nls = newFixedPointSolver(y, ctx);
  ASSERT_NE(nls, nullptr);
  EXPECT_EQ(SUNNonlinSolGetType(nls), SUNNONLINEARSOLVER_FIXEDPOINT);
  EXPECT_EQ(SUNNonlinSolInitialize(nls), SUN_NLS_MEM_NULL);  // no system function yet
  EXPECT_EQ(SUNNonlinSolSetMaxIters(nls, 0), SUN_NLS_ILL_INPUT);
  EXPECT_EQ(SUNNonlinSolSetSysFn(nls, nullptr), SUN_NLS_ILL_INPUT);
  EXPECT_EQ(SUNNonlinSolSolve(nls, y, y, nullptr, 1.0, SUNFALSE, nullptr), SUN_NLS_MEM_NULL);
  EXPECT_EQ(SUNNonlinSolFree(nls), SUN_NLS_SUCCESS);
  N_VDestroy(y);
  SUNContext_Free(&ctx);
}

}  // namespace
