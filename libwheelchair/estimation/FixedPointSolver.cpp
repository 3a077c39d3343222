#include "libwheelchair/estimation/FixedPointSolver.h"

#include <initializer_list>
#include <new>

namespace wheelchair::estimation {

namespace {

struct FixedPoint {
  SUNNonlinSolSysFn sys = nullptr;
  SUNNonlinSolConvTestFn ctest = nullptr;
  void* ctest_data = nullptr;
  N_Vector yprev = nullptr, gy = nullptr, delta = nullptr;
  int curiter = 0;
  int maxiters = 3;  // SUNDIALS' default; CVODE sets NLS_MAXCOR = 3 too
  long niters = 0, nconvfails = 0;
};

FixedPoint* content(SUNNonlinearSolver nls) {
  return static_cast<FixedPoint*>(nls->content);
}

SUNNonlinearSolver_Type getType(SUNNonlinearSolver) {
  return SUNNONLINEARSOLVER_FIXEDPOINT;
}

int initialize(SUNNonlinearSolver nls) {
  if (nls == nullptr) return SUN_NLS_MEM_NULL;
  FixedPoint* c = content(nls);
  if (c->sys == nullptr || c->ctest == nullptr) return SUN_NLS_MEM_NULL;
  c->niters = 0;
  c->nconvfails = 0;
  return SUN_NLS_SUCCESS;
}

// SUNNonlinSolSolve_FixedPoint with m = 0 (see the header): a system-function failure and
// running out of iterations both count a convergence failure and return SUN_NLS_CONV_RECVR,
// a convergence-test failure its own code.
int solve(SUNNonlinearSolver nls, N_Vector y0, N_Vector ycor, N_Vector w, sunrealtype tol,
          sunbooleantype /*callSetup*/, void* mem) {
  if (nls == nullptr || y0 == nullptr || ycor == nullptr || w == nullptr || mem == nullptr)
    return SUN_NLS_MEM_NULL;
  FixedPoint* c = content(nls);
  if (c->sys == nullptr || c->ctest == nullptr) return SUN_NLS_MEM_NULL;
  c->niters = 0;
  c->nconvfails = 0;
  for (c->curiter = 0; c->curiter < c->maxiters; ++c->curiter) {
    N_VScale(1.0, ycor, c->yprev);
    if (c->sys(ycor, c->gy, mem) != SUN_NLS_SUCCESS) break;
    N_VScale(1.0, c->gy, ycor);
    ++c->niters;
    N_VLinearSum(1.0, ycor, -1.0, c->yprev, c->delta);
    const int r = c->ctest(nls, ycor, c->delta, tol, w, c->ctest_data);
    if (r == SUN_NLS_SUCCESS) return SUN_NLS_SUCCESS;
    if (r != SUN_NLS_CONTINUE) {
      ++c->nconvfails;
      return r;
    }
  }
  ++c->nconvfails;
  return SUN_NLS_CONV_RECVR;
}

int freeSolver(SUNNonlinearSolver nls) {
  if (nls == nullptr) return SUN_NLS_SUCCESS;
  if (FixedPoint* c = content(nls)) {
    for (N_Vector v : {c->yprev, c->gy, c->delta})
      if (v != nullptr) N_VDestroy(v);
    delete c;
    nls->content = nullptr;
  }
  SUNNonlinSolFreeEmpty(nls);
  return SUN_NLS_SUCCESS;
}

int setSysFn(SUNNonlinearSolver nls, SUNNonlinSolSysFn f) {
  if (nls == nullptr) return SUN_NLS_MEM_NULL;
  if (f == nullptr) return SUN_NLS_ILL_INPUT;
  content(nls)->sys = f;
  return SUN_NLS_SUCCESS;
}

int setConvTestFn(SUNNonlinearSolver nls, SUNNonlinSolConvTestFn f, void* data) {
  if (nls == nullptr) return SUN_NLS_MEM_NULL;
  if (f == nullptr) return SUN_NLS_ILL_INPUT;
  content(nls)->ctest = f;
  content(nls)->ctest_data = data;
  return SUN_NLS_SUCCESS;
}

int setMaxIters(SUNNonlinearSolver nls, int maxiters) {
  if (nls == nullptr) return SUN_NLS_MEM_NULL;
  if (maxiters < 1) return SUN_NLS_ILL_INPUT;
  content(nls)->maxiters = maxiters;
  return SUN_NLS_SUCCESS;
}

int getNumIters(SUNNonlinearSolver nls, long* n) {
  if (nls == nullptr) return SUN_NLS_MEM_NULL;
  *n = content(nls)->niters;
  return SUN_NLS_SUCCESS;
}

int getCurIter(SUNNonlinearSolver nls, int* iter) {
  if (nls == nullptr) return SUN_NLS_MEM_NULL;
  *iter = content(nls)->curiter;
  return SUN_NLS_SUCCESS;
}

int getNumConvFails(SUNNonlinearSolver nls, long* n) {
  if (nls == nullptr) return SUN_NLS_MEM_NULL;
  *n = content(nls)->nconvfails;
  return SUN_NLS_SUCCESS;
}

}  // namespace

SUNNonlinearSolver newFixedPointSolver(N_Vector y, SUNContext ctx) {
  if (y == nullptr || ctx == nullptr) return nullptr;
  SUNNonlinearSolver nls = SUNNonlinSolNewEmpty(ctx);
  if (nls == nullptr) return nullptr;
  nls->ops->gettype = getType;
  nls->ops->initialize = initialize;
  nls->ops->solve = solve;
  nls->ops->free = freeSolver;
  nls->ops->setsysfn = setSysFn;
  nls->ops->setctestfn = setConvTestFn;
  nls->ops->setmaxiters = setMaxIters;
  nls->ops->getnumiters = getNumIters;
  nls->ops->getcuriter = getCurIter;
  nls->ops->getnumconvfails = getNumConvFails;
  auto* c = new (std::nothrow) FixedPoint;
  nls->content = c;
  if (c != nullptr) {
    c->yprev = N_VClone(y);
    c->gy = N_VClone(y);
    c->delta = N_VClone(y);
  }
  if (c == nullptr || c->yprev == nullptr || c->gy == nullptr || c->delta == nullptr) {
    freeSolver(nls);
    return nullptr;
  }
  return nls;
}

}  // namespace wheelchair::estimation
