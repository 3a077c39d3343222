// CVODE's nonlinear solver for the Adams method: fixed-point (functional) iteration without
// acceleration, as a SUNDIALS "user-supplied" SUNNonlinearSolver compiled with the project's
// optimisation.
//
// Each step of CVODE solves ycor = G(ycor) (G: CVODE's fixed-point system, which calls the
// right-hand side) by
//   for it = 0 .. maxiters-1:  yprev = ycor;  ycor = G(ycor);  delta = ycor - yprev;
//                              stop if CVODE's convergence test on delta says converged
//                              (or failed); else iterate
// with at most 3 iterations (CVODE's NLS_MAXCOR). This is the algorithm and the sequence of
// vector operations of SUNDIALS 6.4.1's SUNNonlinSol_FixedPoint with m = 0 (no Anderson
// acceleration), checked against the library's machine code: the same N_VScale(1, .) copies
// and N_VLinearSum(1, ycor, -1, yprev, delta), the same return codes and counters. Debian
// builds that library at -O0 (docs/benchmarks.md, "Eleventh round"); this copy runs the same
// operations through the vectors' ops tables (CdEkf's kernels), so the results are
// bit-identical (tests/estimation/test_fixed_point_solver.cpp compares it with the library's
// solver on a stiff-free ODE, step by step).
//
// Example: CdEkf::initCvode, Adams method:
//   cv.nls = newFixedPointSolver(cv.y, cv.ctx);   // instead of SUNNonlinSol_FixedPoint(y, 0, ctx)
//   CVodeSetNonlinearSolver(mem, cv.nls);          // freed with SUNNonlinSolFree
#pragma once

#include <sundials/sundials_context.h>
#include <sundials/sundials_nonlinearsolver.h>
#include <sundials/sundials_nvector.h>

namespace wheelchair::estimation {

/// A fixed-point solver whose work vectors are clones of `y` (so they inherit y's ops table);
/// nullptr if SUNDIALS cannot allocate. Free it with SUNNonlinSolFree.
SUNNonlinearSolver newFixedPointSolver(N_Vector y, SUNContext ctx);

}  // namespace wheelchair::estimation
