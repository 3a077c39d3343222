// SUNDIALS' generic dispatch functions, compiled with the project's optimisation.
//
// Debian's libsundials_cvode 6.4.1 is built without optimisation (-O0: every argument goes
// through the stack). Inside CVODE every vector operation is a call to a generic wrapper such
// as N_VLinearSum(a, x, b, y, z), which only calls z->ops->nvlinearsum(a, x, b, y, z); those
// wrappers (and SUNRpowerR/I, the nonlinear-solver wrappers) took ~5 % of a one-hour
// `wheelchair filter` (docs/benchmarks.md, "Seventh round"). CVODE calls them through its PLT,
// so the definitions below, linked into the program, replace the library's for every caller in
// the process (ELF symbol interposition; the linker exports a program's definition of a symbol
// a shared library uses).
//
// Each function does exactly what SUNDIALS 6.4's sundials_nvector.c, sundials_math.c and
// sundials_nonlinearsolver.c do (checked against the library's machine code, built without
// profiling or logging: SUNDIALS_BUILD_WITH_PROFILING undefined, SUNDIALS_LOGGING_LEVEL 0):
// the same operation from the same ops table, the same fallbacks when an optional operation
// is missing, the same floating-point operations in SUNRpowerI/R but for SUNRpowerR's square
// and fourth roots (sqrt: within one ulp of pow). The results are therefore bit-identical but
// for those roots (tests/estimation/test_sundials_dispatch.cpp compares each with the
// library's own, found with dlsym(RTLD_NEXT, ...)).
//
// Example: CVODE's predictor calls N_VLinearSum(1, zn[j-1], 1, zn[j], zn[j-1]); that is now
// one indirect jump to the serial kernel installed in CdEkf.cpp instead of an -O0 frame.
#include <nvector/nvector_serial.h>
#include <sundials/sundials_math.h>
#include <sundials/sundials_nonlinearsolver.h>
#include <sundials/sundials_nvector.h>

#include <cmath>

#if !defined(SUNDIALS_VERSION_MAJOR) || SUNDIALS_VERSION_MAJOR != 6 || \
    defined(SUNDIALS_BUILD_WITH_PROFILING)
#error "SundialsDispatch.cpp mirrors SUNDIALS 6 without profiling: check it against the new version"
#endif

extern "C" {

// --- vector operations without fallback: one call through the ops table ----------------------
void N_VLinearSum(realtype a, N_Vector x, realtype b, N_Vector y, N_Vector z) {
  z->ops->nvlinearsum(a, x, b, y, z);
}
void N_VConst(realtype c, N_Vector z) {
  z->ops->nvconst(c, z);
}
void N_VProd(N_Vector x, N_Vector y, N_Vector z) {
  z->ops->nvprod(x, y, z);
}
void N_VScale(realtype c, N_Vector x, N_Vector z) {
  z->ops->nvscale(c, x, z);
}
realtype N_VDotProd(N_Vector x, N_Vector y) {
  return y->ops->nvdotprod(x, y);
}
realtype N_VWrmsNorm(N_Vector x, N_Vector w) {
  return x->ops->nvwrmsnorm(x, w);
}
realtype* N_VGetArrayPointer(N_Vector v) {
  return v->ops->nvgetarraypointer(v);
}

// The serial vector's array accessor, which CVODE's N_VGetArrayPointer reaches through the ops
// table (CdEkf's kernels replace the arithmetic operations, not this one).
realtype* N_VGetArrayPointer_Serial(N_Vector v) {
  return NV_DATA_S(v);
}

// --- fused operations: the vector's own, else SUNDIALS' loop of single operations -----------
int N_VLinearCombination(int nvec, realtype* c, N_Vector* X, N_Vector z) {
  if (z->ops->nvlinearcombination != nullptr) return z->ops->nvlinearcombination(nvec, c, X, z);
  z->ops->nvscale(c[0], X[0], z);
  for (int i = 1; i < nvec; ++i) z->ops->nvlinearsum(c[i], X[i], RCONST(1.0), z, z);
  return 0;
}
int N_VScaleAddMulti(int nvec, realtype* a, N_Vector x, N_Vector* Y, N_Vector* Z) {
  if (x->ops->nvscaleaddmulti != nullptr) return x->ops->nvscaleaddmulti(nvec, a, x, Y, Z);
  for (int i = 0; i < nvec; ++i) x->ops->nvlinearsum(a[i], x, RCONST(1.0), Y[i], Z[i]);
  return 0;
}
int N_VScaleVectorArray(int nvec, realtype* c, N_Vector* X, N_Vector* Z) {
  if (Z[0]->ops->nvscalevectorarray != nullptr) return Z[0]->ops->nvscalevectorarray(nvec, c, X, Z);
  for (int i = 0; i < nvec; ++i) Z[0]->ops->nvscale(c[i], X[i], Z[i]);
  return 0;
}

// --- sundials_math.c ----------------------------------------------------------------------------
realtype SUNRpowerI(realtype base, int exponent) {
  realtype prod = RCONST(1.0);
  const int expt = std::abs(exponent);
  for (int i = 1; i <= expt; ++i) prod *= base;
  if (exponent < 0) prod = RCONST(1.0) / prod;
  return prod;
}
realtype SUNRpowerR(realtype base, realtype exponent) {
  if (base <= RCONST(0.0)) return RCONST(0.0);
  // CVODE's step-size rule takes the 1/(q+1)-th, 1/q-th and 1/(q+2)-th roots of error ratios;
  // after every restart (one per measurement) it runs at orders 1-3, so square and fourth
  // roots are about half of the calls. sqrt is the correctly rounded square root, which
  // glibc's pow approximates (<= 0.52 ulp: they differ for ~0.1 % of arguments);
  // sqrt(sqrt(x)) is within ~1 ulp of pow(x, 0.25). Only step sizes change, by an ulp, and
  // with them the estimates at the rounding level (docs/benchmarks.md, "Tenth round", second
  // part): not bit-identical to the library.
  if (exponent == RCONST(0.5)) return std::sqrt(base);
  if (exponent == RCONST(0.25)) return std::sqrt(std::sqrt(base));
  return std::pow(base, exponent);
}

// --- sundials_nonlinearsolver.c (the calls CVODE makes at every step) ---------------------------
int SUNNonlinSolSolve(SUNNonlinearSolver NLS, N_Vector y0, N_Vector y, N_Vector w, realtype tol,
                      booleantype callLSetup, void* mem) {
  return NLS->ops->solve(NLS, y0, y, w, tol, callLSetup, mem);
}
int SUNNonlinSolGetNumIters(SUNNonlinearSolver NLS, long int* niters) {
  if (NLS->ops->getnumiters) return NLS->ops->getnumiters(NLS, niters);
  *niters = 0;
  return SUN_NLS_SUCCESS;
}
int SUNNonlinSolGetCurIter(SUNNonlinearSolver NLS, int* iter) {
  if (NLS->ops->getcuriter) return NLS->ops->getcuriter(NLS, iter);
  *iter = -1;
  return SUN_NLS_SUCCESS;
}
int SUNNonlinSolGetNumConvFails(SUNNonlinearSolver NLS, long int* nconvfails) {
  if (NLS->ops->getnumconvfails) return NLS->ops->getnumconvfails(NLS, nconvfails);
  *nconvfails = 0;
  return SUN_NLS_SUCCESS;
}

}  // extern "C"
