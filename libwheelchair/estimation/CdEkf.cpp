#include "libwheelchair/estimation/CdEkf.h"

#include "libwheelchair/estimation/Measurement.h"

#include <limits>

#include <cvode/cvode.h>
#include <nvector/nvector_serial.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>
#include <sunnonlinsol/sunnonlinsol_fixedpoint.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <vector>

namespace wheelchair::estimation {

struct CdEkf::Cvode {
  SUNContext ctx = nullptr;
  void* mem = nullptr;
  N_Vector y = nullptr;
  N_Vector abstol = nullptr;
  SUNNonlinearSolver nls = nullptr;
  SUNMatrix A = nullptr;
  SUNLinearSolver ls = nullptr;
  bool initialised = false;
  /// CVODE holds a valid integration that ended at `t_live` with y (continuation possible).
  bool live = false;
  double t_live = 0;
  long nst = 0, nfe = 0, netf = 0, nni = 0;  // CVODE counters at the end of the last call
  int m = 0;                                 ///< integrated states (packed size m + m(m+1)/2)
  /// Factor on the error weights: sqrt(N_m / N_n) for the held set-up, so that its WRMS norms
  /// (over N_m components) equal those of the full system, whose extra components are zero.
  double wscale = 1.0;
  std::vector<double> ycheck;  // packed (x, P) to compare with y
  /// Adaptive initial step (CvodeOptions::adaptive_initial_step): the hint for the next
  /// restart (s; 0 = let CVODE estimate it) and whether this integration started with a
  /// restart whose first step is still to be scored.
  double h0_hint_s = 0;
  bool scoring_h0 = false;

  ~Cvode() {
    if (mem) CVodeFree(&mem);
    if (nls) SUNNonlinSolFree(nls);
    if (ls) SUNLinSolFree(ls);
    if (A) SUNMatDestroy(A);
    if (y) N_VDestroy(y);
    if (abstol) N_VDestroy(abstol);
    if (ctx) SUNContext_Free(&ctx);
  }
};

struct CdEkfAccess {
  static int rhs(sunrealtype t, N_Vector y, N_Vector ydot, void* user) {
    auto* self = static_cast<CdEkf*>(user);
    try {
      self->evalRhs(t, N_VGetArrayPointer(y), N_VGetArrayPointer(ydot));
    } catch (...) {
      return -1;  // unrecoverable
    }
    return 0;
  }
  /// CVODE's error weights for scalar rtol and vector atol (its cvEwtSetSV: |y|, rtol |y| +
  /// 1 atol, 1 / that; the same operations) in one pass instead of three vector kernels.
  static int ewt(N_Vector y, N_Vector w, void* user) {
    const auto* self = static_cast<const CdEkf*>(user);
    const double ws = self->act_->wscale;
    const sunindextype n = NV_LENGTH_S(y);
    const double* yd = NV_DATA_S(y);
    const double* at = NV_DATA_S(self->act_->abstol);
    double* wd = NV_DATA_S(w);
    errorWeights(n, ws, self->opt_.rel_tol, yd, at, wd);
    return 0;
  }
  static void errorWeights(sunindextype n, double ws, double rtol, const double* yd,
                           const double* at, double* wd);
};

namespace {

/// CVODE's name of a return flag ("CV_TOO_MUCH_WORK"; the number if it has none).
std::string flagName(int flag) {
  char* name = CVodeGetReturnFlagName(flag);
  const std::string s = name ? name : std::to_string(flag);
  std::free(name);
  return s;
}

void check(int flag, const char* what) {
  if (flag < 0)
    throw std::runtime_error(fmt::format("CdEkf: CVODE {} failed ({})", what, flagName(flag)));
}

// ---------------------------------------------------------------------------------------------
// Element-wise kernels for the serial N_Vector. The distribution's libsundials_cvode is built
// without optimisation (every element access goes through the stack), which made these
// kernels over half of the filter's time for a 54-element vector; these are the same
// operations compiled with the project's flags. Installed in the ops table of the template
// vector, so every clone CVODE and the nonlinear solver make inherits them. Aliasing of
// inputs and outputs is allowed as in the reference implementation (element i is read
// before it is written).
namespace kern {

// Built twice, for AVX2 and for the baseline ISA, and chosen at load time (GCC function
// multiversioning): 4-wide loads and arithmetic for the 54-element vectors. Without FMA
// (not enabled by "avx2") every element sees the same IEEE operations, so the results are
// identical on either path.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define WHEELCHAIR_KERN __attribute__((target_clones("avx2", "default")))
#else
#define WHEELCHAIR_KERN
#endif

inline sunrealtype* D(N_Vector v) {
  return NV_DATA_S(v);
}
inline sunindextype L(N_Vector v) {
  return NV_LENGTH_S(v);
}

WHEELCHAIR_KERN void linearSum(sunrealtype a, N_Vector x, sunrealtype b, N_Vector y, N_Vector z) {
  const sunindextype n = L(x);
  const sunrealtype *xd = D(x), *yd = D(y);
  sunrealtype* zd = D(z);
#pragma GCC ivdep
  for (sunindextype i = 0; i < n; ++i) zd[i] = a * xd[i] + b * yd[i];
}
WHEELCHAIR_KERN void constant(sunrealtype c, N_Vector z) {
  const sunindextype n = L(z);
  sunrealtype* zd = D(z);
#pragma GCC ivdep
  for (sunindextype i = 0; i < n; ++i) zd[i] = c;
}
WHEELCHAIR_KERN void prod(N_Vector x, N_Vector y, N_Vector z) {
  const sunindextype n = L(x);
  const sunrealtype *xd = D(x), *yd = D(y);
  sunrealtype* zd = D(z);
#pragma GCC ivdep
  for (sunindextype i = 0; i < n; ++i) zd[i] = xd[i] * yd[i];
}
WHEELCHAIR_KERN void div(N_Vector x, N_Vector y, N_Vector z) {
  const sunindextype n = L(x);
  const sunrealtype *xd = D(x), *yd = D(y);
  sunrealtype* zd = D(z);
#pragma GCC ivdep
  for (sunindextype i = 0; i < n; ++i) zd[i] = xd[i] / yd[i];
}
WHEELCHAIR_KERN void scale(sunrealtype c, N_Vector x, N_Vector z) {
  const sunindextype n = L(x);
  const sunrealtype* xd = D(x);
  sunrealtype* zd = D(z);
#pragma GCC ivdep
  for (sunindextype i = 0; i < n; ++i) zd[i] = c * xd[i];
}
WHEELCHAIR_KERN void absv(N_Vector x, N_Vector z) {
  const sunindextype n = L(x);
  const sunrealtype* xd = D(x);
  sunrealtype* zd = D(z);
#pragma GCC ivdep
  for (sunindextype i = 0; i < n; ++i) zd[i] = std::fabs(xd[i]);
}
WHEELCHAIR_KERN void inv(N_Vector x, N_Vector z) {
  const sunindextype n = L(x);
  const sunrealtype* xd = D(x);
  sunrealtype* zd = D(z);
#pragma GCC ivdep
  for (sunindextype i = 0; i < n; ++i) zd[i] = 1.0 / xd[i];
}
WHEELCHAIR_KERN void addConst(N_Vector x, sunrealtype b, N_Vector z) {
  const sunindextype n = L(x);
  const sunrealtype* xd = D(x);
  sunrealtype* zd = D(z);
#pragma GCC ivdep
  for (sunindextype i = 0; i < n; ++i) zd[i] = xd[i] + b;
}
WHEELCHAIR_KERN sunrealtype dotProd(N_Vector x, N_Vector y) {
  const sunindextype n = L(x);
  const sunrealtype *xd = D(x), *yd = D(y);
  sunrealtype s = 0;
  for (sunindextype i = 0; i < n; ++i) s += xd[i] * yd[i];
  return s;
}
WHEELCHAIR_KERN sunrealtype maxNorm(N_Vector x) {
  const sunindextype n = L(x);
  const sunrealtype* xd = D(x);
  sunrealtype m = 0;
  for (sunindextype i = 0; i < n; ++i) m = std::max(m, std::fabs(xd[i]));
  return m;
}
WHEELCHAIR_KERN sunrealtype wrmsNorm(N_Vector x, N_Vector w) {
  const sunindextype n = L(x);
  const sunrealtype *xd = D(x), *wd = D(w);
  sunrealtype s0 = 0, s1 = 0;  // two partial sums (pairs of lanes)
  sunindextype i = 0;
  for (; i + 1 < n; i += 2) {
    const sunrealtype p0 = xd[i] * wd[i], p1 = xd[i + 1] * wd[i + 1];
    s0 += p0 * p0;
    s1 += p1 * p1;
  }
  if (i < n) {
    const sunrealtype p = xd[i] * wd[i];
    s0 += p * p;
  }
  return std::sqrt((s0 + s1) / static_cast<sunrealtype>(n));
}
WHEELCHAIR_KERN sunrealtype minv(N_Vector x) {
  const sunindextype n = L(x);
  const sunrealtype* xd = D(x);
  sunrealtype m = xd[0];
  for (sunindextype i = 1; i < n; ++i) m = std::min(m, xd[i]);
  return m;
}
WHEELCHAIR_KERN void compare(sunrealtype c, N_Vector x, N_Vector z) {
  const sunindextype n = L(x);
  const sunrealtype* xd = D(x);
  sunrealtype* zd = D(z);
#pragma GCC ivdep
  for (sunindextype i = 0; i < n; ++i) zd[i] = std::fabs(xd[i]) >= c ? 1.0 : 0.0;
}
WHEELCHAIR_KERN int linearCombination(int nvec, sunrealtype* c, N_Vector* X, N_Vector z) {
  const sunindextype n = L(z);
  sunrealtype* zd = D(z);
  if (nvec == 1) {
    scale(c[0], X[0], z);
    return 0;
  }
  if (nvec == 2) {
    linearSum(c[0], X[0], c[1], X[1], z);
    return 0;
  }
  sunrealtype* xs[64];
  if (nvec > 64) return -1;
  for (int k = 0; k < nvec; ++k) xs[k] = D(X[k]);
  for (sunindextype i = 0; i < n; ++i) {
    sunrealtype s = c[0] * xs[0][i];
    for (int k = 1; k < nvec; ++k) s += c[k] * xs[k][i];
    zd[i] = s;
  }
  return 0;
}
WHEELCHAIR_KERN int scaleAddMulti(int nvec, sunrealtype* a, N_Vector x, N_Vector* Y, N_Vector* Z) {
  const sunindextype n = L(x);
  const sunrealtype* xd = D(x);
  for (int k = 0; k < nvec; ++k) {
    const sunrealtype* yd = D(Y[k]);
    sunrealtype* zd = D(Z[k]);
    const sunrealtype ak = a[k];
#pragma GCC ivdep
    for (sunindextype i = 0; i < n; ++i) zd[i] = ak * xd[i] + yd[i];
  }
  return 0;
}
WHEELCHAIR_KERN int scaleVectorArray(int nvec, sunrealtype* c, N_Vector* X, N_Vector* Z) {
  for (int k = 0; k < nvec; ++k) scale(c[k], X[k], Z[k]);
  return 0;
}
WHEELCHAIR_KERN int linearSumVectorArray(int nvec, sunrealtype a, N_Vector* X, sunrealtype b,
                                         N_Vector* Y, N_Vector* Z) {
  for (int k = 0; k < nvec; ++k) linearSum(a, X[k], b, Y[k], Z[k]);
  return 0;
}
WHEELCHAIR_KERN int constVectorArray(int nvec, sunrealtype c, N_Vector* Z) {
  for (int k = 0; k < nvec; ++k) constant(c, Z[k]);
  return 0;
}

}  // namespace kern
}  // namespace

/// w_i = ws / (rtol |y_i| + 1 atol_i) (CdEkfAccess::ewt), 4 divisions at a time on AVX2.
WHEELCHAIR_KERN void CdEkfAccess::errorWeights(sunindextype n, double ws, double rtol,
                                               const double* yd, const double* at, double* wd) {
#pragma GCC ivdep
  for (sunindextype i = 0; i < n; ++i) wd[i] = ws / (rtol * std::fabs(yd[i]) + 1.0 * at[i]);
}

namespace {
namespace kern {

void install(N_Vector v) {
  N_Vector_Ops o = v->ops;
  o->nvlinearsum = linearSum;
  o->nvconst = constant;
  o->nvprod = prod;
  o->nvdiv = div;
  o->nvscale = scale;
  o->nvabs = absv;
  o->nvinv = inv;
  o->nvaddconst = addConst;
  o->nvdotprod = dotProd;
  o->nvmaxnorm = maxNorm;
  o->nvwrmsnorm = wrmsNorm;
  o->nvmin = minv;
  o->nvcompare = compare;
  o->nvlinearcombination = linearCombination;
  o->nvscaleaddmulti = scaleAddMulti;
  o->nvscalevectorarray = scaleVectorArray;
  o->nvlinearsumvectorarray = linearSumVectorArray;
  o->nvconstvectorarray = constVectorArray;
}

}  // namespace kern

/// Adapter of the std::function input (allocates per call; the legacy path).
struct FunctionInput final : CdInput {
  explicit FunctionInput(const InputFunction& f) : f_(f) {}
  void eval(double t, Eigen::VectorXd& u) const override { u = f_(t); }
  const InputFunction& f_;
};

}  // namespace

CdEkf::CdEkf(const CdModel& model, const CvodeOptions& options)
    : model_(model), opt_(options), n_(model.stateDim()) {
  if (n_ <= 0) throw std::invalid_argument("CdEkf: state dimension must be > 0");
  x_ = Eigen::VectorXd::Zero(n_);
  P_ = Eigen::MatrixXd::Identity(n_, n_);
  wx_.resize(n_);
  wxd_.resize(n_);
  wP_.resize(n_, n_);
  wF_.resize(n_, n_);
  wQ_.resize(n_, n_);
  wFP_.resize(n_, n_);
  const int N = n_ + packedSize(n_);
  ys_.resize(N);
  yds_.resize(N);
  cv_ = newCvode(n_);
  act_ = cv_.get();
}

std::unique_ptr<CdEkf::Cvode> CdEkf::newCvode(int m) const {
  const int N = m + packedSize(m);
  auto cv = std::make_unique<Cvode>();
  cv->m = m;
  cv->wscale = std::sqrt(static_cast<double>(N) / (n_ + packedSize(n_)));
  cv->ycheck.resize(N);
  check(SUNContext_Create(nullptr, &cv->ctx), "SUNContext_Create");
  cv->y = N_VNew_Serial(N, cv->ctx);
  cv->abstol = N_VNew_Serial(N, cv->ctx);
  if (!cv->y || !cv->abstol) throw std::runtime_error("CdEkf: N_VNew_Serial failed");
  // Before CVodeInit and the solvers clone y: the clones copy the ops table.
  kern::install(cv->y);
  kern::install(cv->abstol);
  double* at = N_VGetArrayPointer(cv->abstol);
  for (int i = 0; i < N; ++i) at[i] = (i < m) ? opt_.abs_tol_state : opt_.abs_tol_cov;
  const bool bdf = opt_.method == CvodeOptions::Method::Bdf;
  cv->mem = CVodeCreate(bdf ? CV_BDF : CV_ADAMS, cv->ctx);
  if (!cv->mem) throw std::runtime_error("CdEkf: CVodeCreate failed");
  return cv;
}

CdEkf::~CdEkf() = default;

void CdEkf::pack(double* y, int m) const {
  for (int i = 0; i < m; ++i) y[i] = x_(i);
  int k = m;
  for (int c = 0; c < m; ++c)
    for (int r = c; r < m; ++r) y[k++] = P_(r, c);
}

void CdEkf::unpack(const double* y, int m) {
  for (int i = 0; i < m; ++i) x_(i) = y[i];
  int k = m;
  for (int c = 0; c < m; ++c)
    for (int r = c; r < m; ++r) {
      P_(r, c) = y[k];
      P_(c, r) = y[k];
      ++k;
    }
}

namespace {

// Packed Riccati right-hand side: out = lower triangle (column-major) of F P + P F' + Qs, with
// P given as its packed lower triangle yP and Qs = (Q + Q') / 2 packed. F is used row-sparse:
// a kinematic model has a handful of nonzeros per row, so F P costs nnz(F) n instead of n^3.
// NC > 0: the dimension known at compile time (unrolled loops); NC = 0: n at run time. F is
// column-major with leading dimension LD (0: ld at run time), of which the leading n x n
// block is used. Work arrays P and FP: n x n.
template <int NC, int LD = NC>
inline __attribute__((always_inline)) void riccatiPacked(
    int n_rt, int ld_rt, const double* __restrict yP, const double* __restrict F,
    const double* __restrict Qs, double* __restrict out, double* __restrict P,
    double* __restrict FP) {
  const int n = NC > 0 ? NC : n_rt;
  const int ld = LD > 0 ? LD : ld_rt;  // leading dimension of F (>= n: its leading block)
  int k = 0;
  for (int c = 0; c < n; ++c)
    for (int r = c; r < n; ++r) {
      P[r + c * n] = yP[k];
      P[c + r * n] = yP[k];
      ++k;
    }
  // FPt = (F P)' = P F' (P symmetric): column r of FPt accumulates F(r, j) P(:, j) over the
  // nonzeros F(r, j), contiguous axpys of length n.
  // The first nonzero term initialises the row as 0 + F(r, j) P(:, j), the same operations as
  // a zeroed accumulator without clearing n x n entries first.
  for (int r = 0; r < n; ++r) {
    double* FPr = FP + r * n;
    int j = 0;
    while (j < n && F[r + j * ld] == 0.0) ++j;
    if (j == n) {
      for (int i = 0; i < n; ++i) FPr[i] = 0.0;
      continue;
    }
    {
      const double v = F[r + j * ld];
      const double* Pj = P + j * n;
#pragma GCC unroll 16
      for (int i = 0; i < n; ++i) FPr[i] = 0.0 + v * Pj[i];
    }
    for (++j; j < n; ++j) {
      const double v = F[r + j * ld];
      if (v == 0.0) continue;
      const double* Pj = P + j * n;
#pragma GCC unroll 16
      for (int i = 0; i < n; ++i) FPr[i] += v * Pj[i];
    }
  }
  k = 0;
  for (int c = 0; c < n; ++c)
    for (int r = c; r < n; ++r, ++k) out[k] = FP[r + c * n] + FP[c + r * n] + Qs[k];
}

// The fixed-size instantiations the wheelchair filter uses, built for AVX2 and the baseline
// ISA like the vector kernels (kern::): the same IEEE operations on either path (no FMA, no
// reassociation), so the same bits; the 9-long axpys take 2 + 1 instead of 4 + 1 steps.
WHEELCHAIR_KERN void riccatiPacked9(const double* __restrict yP, const double* __restrict F,
                                    const double* __restrict Qs, double* __restrict out,
                                    double* __restrict P, double* __restrict FP) {
  riccatiPacked<9>(9, 9, yP, F, Qs, out, P, FP);
}
WHEELCHAIR_KERN void riccatiPacked9held(const double* __restrict yP, const double* __restrict F,
                                        const double* __restrict Qs, double* __restrict out,
                                        double* __restrict P, double* __restrict FP) {
  riccatiPacked<9, 12>(9, 12, yP, F, Qs, out, P, FP);
}
WHEELCHAIR_KERN void riccatiPacked12(const double* __restrict yP, const double* __restrict F,
                                     const double* __restrict Qs, double* __restrict out,
                                     double* __restrict P, double* __restrict FP) {
  riccatiPacked<12>(12, 12, yP, F, Qs, out, P, FP);
}

template <class Mat>
void packSymmetrised(const Mat& Q, double* out) {
  const int n = static_cast<int>(Q.rows());
  int k = 0;
  for (int c = 0; c < n; ++c)
    for (int r = c; r < n; ++r) out[k++] = 0.5 * (Q(r, c) + Q(c, r));
}

}  // namespace

void CdEkf::evalRhs(double tau, const double* y, double* ydot) {
  const int n = m_;  // the integrated states; [m_, n_) are held at x_ (see setHeldTail())
  for (int i = 0; i < n; ++i) wx_(i) = y[i];
  for (int i = n; i < n_; ++i) wx_(i) = x_(i);
  u_->eval(t_ref_ + tau, wu_);  // CVODE's time is relative to t_ref_ (see integrate())
  model_.fAndF(wx_, wu_, wxd_, wF_);
  if (capture_F0_ && tau == capture_tau_) {  // F(t0) for propagateConsiderCross (integrate())
    wF0_ = wF_;
    capture_F0_ = false;
  }
  std::vector<double>& qp = n == n_ ? qPacked_ : qPackedHeld_;
  if (qp.empty() || !model_.constantQ()) {
    model_.Q(wx_, wu_, wQ_);
    qp.resize(packedSize(n));
    packSymmetrised(wQ_.topLeftCorner(n, n), qp.data());
  }
  // One state-dependent diagonal entry (the packed column c starts at c n - c (c - 1) / 2).
  const int iq = model_.varyingQIndex();
  if (iq >= 0 && iq < n) qp[iq * n - iq * (iq - 1) / 2] = model_.varyingQ(wx_, wu_);
  for (int i = 0; i < n; ++i) ydot[i] = wxd_(i);
  // With a held tail only F's leading n x n block is used (the held rows of P are zero).
  const double* F = wF_.data();
  if (n == 9 && n_ == 9)  // the wheelchair filter
    riccatiPacked9(y + n, F, qp.data(), ydot + n, wP_.data(), wFP_.data());
  else if (n == 9 && n_ == 12)  // its sensor-error states held (all closed)
    riccatiPacked9held(y + n, F, qp.data(), ydot + n, wP_.data(), wFP_.data());
  else if (n == 12)  // the wheelchair filter with its sensor-error states
    riccatiPacked12(y + n, F, qp.data(), ydot + n, wP_.data(), wFP_.data());
  else
    riccatiPacked<0, 0>(n, n_, y + n, F, qp.data(), ydot + n, wP_.data(), wFP_.data());
}

void CdEkf::reset(double t0_s, const Eigen::VectorXd& x0, const Eigen::MatrixXd& P0) {
  if (x0.size() != n_ || P0.rows() != n_ || P0.cols() != n_)
    throw std::invalid_argument("CdEkf::reset: dimension mismatch");
  t_ = t0_s;
  t_ref_ = t0_s;
  x_ = x0;
  setCovariance(P0);
  cv_->live = false;
}

void CdEkf::setCovariance(const Eigen::MatrixXd& P) {
  P_ = 0.5 * (P + P.transpose());
}

void CdEkf::setHeldTail(int count, bool consider) {
  if (count < 0 || count >= n_) throw std::invalid_argument("CdEkf::setHeldTail: bad count");
  held_tail_ = count;
  consider_tail_ = consider && count > 0;
}

namespace {
/// Y <- exp(M) Y to fourth order, Y += M Y + ... + M^4 Y / 24 (terms T <- M T / k).
/// |M| ~ |F| dt ~ 1e-2 for the chair's 2-10 ms intervals: the truncation (M^5 / 120 ~ 1e-12)
/// is far below the Magnus step's own O(dt^3) error. Fixed sizes for the wheelchair filter.
template <class MatM, class MatY, class Block>
void expTimes(const MatM& M, Block&& Y) {
  MatY T = Y;
  for (int k = 1; k <= 4; ++k) {
    const MatY MT = M.lazyProduct(T);  // (9 x 9 by 9 x 3: not Eigen's blocked GEMM)
    T = MT / static_cast<double>(k);
    Y += T;
  }
}
}  // namespace

void CdEkf::propagateConsiderCross(double dt, double t1_s, const Eigen::MatrixXd& F0) {
  // dP_xc/dt = F_xx(t) P_xc (setHeldTail): P_xc(t1) = Phi P_xc(t0) with the second-order
  // Magnus step Phi = exp(M), M = dt (F_xx(t0) + F_xx(t1)) / 2.
  const int m = n_ - held_tail_;
  u_->eval(t1_s, wu_);
  model_.F(x_, wu_, wF_);
  if (m == 9 && held_tail_ == 3) {  // the wheelchair filter with its sensor-error states
    const Eigen::Matrix<double, 9, 9> M =
        (0.5 * dt) * (F0.topLeftCorner<9, 9>() + wF_.topLeftCorner<9, 9>());
    expTimes<Eigen::Matrix<double, 9, 9>, Eigen::Matrix<double, 9, 3>>(M,
                                                                       P_.topRightCorner<9, 3>());
  } else {
    wM_ = (0.5 * dt) * (F0.topLeftCorner(m, m) + wF_.topLeftCorner(m, m));
    expTimes<Eigen::MatrixXd, Eigen::MatrixXd>(wM_, P_.topRightCorner(m, held_tail_));
  }
  P_.bottomLeftCorner(held_tail_, m) = P_.topRightCorner(m, held_tail_).transpose();
}

bool CdEkf::heldTailIsZero() const {
  if (held_tail_ == 0) return false;
  return (P_.bottomRows(held_tail_).array() == 0.0).all() &&
         (P_.rightCols(held_tail_).array() == 0.0).all();
}

void CdEkf::zeroCovarianceRowsCols(int i, int count) {
  P_.middleRows(i, count).setZero();
  P_.middleCols(i, count).setZero();
}

void CdEkf::propagate(double t1_s, const InputFunction& u) {
  const FunctionInput in(u);
  integrate(t1_s, in, false);
}

void CdEkf::propagate(double t1_s, const CdInput& u, bool continuous) {
  integrate(t1_s, u, continuous);
}

void CdEkf::initCvode(Cvode& cv, double tau0) {
  // The first integration: CVODE's memory, tolerances, solver and limits (once per setup).
  const int N = cv.m + packedSize(cv.m);
  Cvode* const cv_ = &cv;  // (the set-up being initialised)
  void* mem = cv_->mem;
  check(CVodeInit(mem, &CdEkfAccess::rhs, tau0, cv_->y), "CVodeInit");
  if (opt_.rel_tol >= 0 && std::all_of(NV_DATA_S(cv_->abstol), NV_DATA_S(cv_->abstol) + N,
                                       [](double a) { return a > 0; }))
    check(CVodeWFtolerances(mem, &CdEkfAccess::ewt), "CVodeWFtolerances");
  else  // CVODE's own weights, with its check for a zero weight denominator
    check(CVodeSVtolerances(mem, opt_.rel_tol, cv_->abstol), "CVodeSVtolerances");
  check(CVodeSetUserData(mem, this), "CVodeSetUserData");
  // Failures are reported by the exception of integrate() (one line naming the interval),
  // not by CVODE's own print to stderr.
  check(CVodeSetErrHandlerFn(
            mem, [](int, const char*, const char*, char*, void*) {}, nullptr),
        "CVodeSetErrHandlerFn");
  if (opt_.method == CvodeOptions::Method::Adams) {
    cv_->nls = SUNNonlinSol_FixedPoint(cv_->y, 0, cv_->ctx);
    if (!cv_->nls) throw std::runtime_error("CdEkf: SUNNonlinSol_FixedPoint failed");
    check(CVodeSetNonlinearSolver(mem, cv_->nls), "CVodeSetNonlinearSolver");
  } else {
    cv_->A = SUNDenseMatrix(N, N, cv_->ctx);
    cv_->ls = SUNLinSol_Dense(cv_->y, cv_->A, cv_->ctx);
    if (!cv_->A || !cv_->ls) throw std::runtime_error("CdEkf: dense linear solver failed");
    check(CVodeSetLinearSolver(mem, cv_->ls, cv_->A), "CVodeSetLinearSolver");
  }
  check(CVodeSetMaxNumSteps(mem, opt_.max_num_steps), "CVodeSetMaxNumSteps");
  check(CVodeSetNonlinConvCoef(mem, opt_.nonlin_conv_coef), "CVodeSetNonlinConvCoef");
  if (opt_.max_step_s > 0) check(CVodeSetMaxStep(mem, opt_.max_step_s), "CVodeSetMaxStep");
  if (opt_.max_order > 0) check(CVodeSetMaxOrd(mem, opt_.max_order), "CVodeSetMaxOrd");
}

/// Adds the interval's CVODE work (steps, f-evaluations, error-test failures, nonlinear
/// iterations since the set-up's last call) to stats_, and after a restart scores the first
/// step for the next restart's initial step hint.
void CdEkf::countSteps(Cvode& cv, double dt, double scale) {
  long nst = 0, nfe = 0, netf = 0, nni = 0;
  CVodeGetNumSteps(cv.mem, &nst);
  CVodeGetNumRhsEvals(cv.mem, &nfe);
  CVodeGetNumErrTestFails(cv.mem, &netf);
  CVodeGetNumNonlinSolvIters(cv.mem, &nni);
  stats_.steps += nst - cv.nst;
  stats_.rhs_evals += nfe - cv.nfe;
  stats_.error_test_fails += netf - cv.netf;
  stats_.nonlin_iters += nni - cv.nni;
  if (cv.scoring_h0) {
    // Restarts come every few ms in similar conditions, so the first step that worked last
    // time is a better guess than CVHin's conservative estimate (which also costs
    // f-evaluations): grow it by 10 % after a restart interval without error-test failure,
    // halve it after one with failures. The error test still decides every step.
    double h0 = 0;
    CVodeGetActualInitStep(cv.mem, &h0);
    const double next = netf == cv.netf ? std::min(1.1 * h0, 1.1 * dt) : 0.5 * h0;
    cv.h0_hint_s = next > 1e-12 * scale ? next : 0.0;
    cv.scoring_h0 = false;
  }
  cv.nst = nst;
  cv.nfe = nfe;
  cv.netf = netf;
  cv.nni = nni;
}

void CdEkf::integrate(double t1_s, const CdInput& u, bool continuous) {
  if (!(t1_s >= t_)) throw std::invalid_argument("CdEkf::propagate: time goes backwards");
  const double dt = t1_s - t_;
  if (dt == 0.0) return;
  // CVODE integrates in time relative to the reset time t_ref_: an absolute UNIX stamp
  // (~1.7e9 s) would leave it eps * t = 4e-7 s of resolution and make every interval "too
  // short" below. Differences of two stamps of similar size are exact (Sterbenz), so tau0 and
  // tau1 carry all the information the stamps have, whatever the clock offset.
  const double tau0 = t_ - t_ref_, tau1 = t1_s - t_ref_;
  if (!std::isfinite(tau1))
    throw std::runtime_error("CdEkf::propagate: non-finite time " + std::to_string(t1_s));
  const double scale = std::max(1.0, std::max(std::fabs(tau0), std::fabs(tau1)));
  struct Clear {
    const CdInput*& p;
    ~Clear() { p = nullptr; }
  } clear{u_};
  u_ = &u;
  if (dt < 1e-9 * scale) {
    // Too short for CVODE's first step heuristics: one explicit Euler step (exact to O(dt^2)).
    const int N = n_ + packedSize(n_);
    m_ = n_;
    pack(ys_.data(), n_);
    evalRhs(tau0, ys_.data(), yds_.data());
    for (int i = 0; i < N; ++i) ys_[i] += dt * yds_[i];
    unpack(ys_.data(), n_);
    t_ = t1_s;
    ++stats_.short_intervals;
    cv_->live = false;
    if (cvHeld_) cvHeld_->live = false;
    return;
  }
  // The held tail (setHeldTail()) while its rows of P are exactly zero: integrate only the
  // leading m states (same equations: the held rows of F, Q and P are zero).
  // A consider tail (its states do not enter f) is always held: its cross-covariance is
  // carried by the transition matrix after the interval (propagateConsiderCross).
  const int m = n_ - (consider_tail_ || heldTailIsZero() ? held_tail_ : 0);
  const bool cross =
      consider_tail_ && m < n_ && !(P_.topRightCorner(m, held_tail_).array() == 0.0).all();
  if (m < n_ && !cvHeld_) cvHeld_ = newCvode(m);
  Cvode* const other = m < n_ ? cv_.get() : cvHeld_.get();
  if (other) other->live = false;  // a mode switch restarts
  act_ = m < n_ ? cvHeld_.get() : cv_.get();
  m_ = m;
  Cvode* const cv_ = act_;  // (the set-up used for this interval)
  double* y = N_VGetArrayPointer(cv_->y);
  void* mem = cv_->mem;
  // Continue the running integration when nothing jumped since it stopped at t_.
  bool resume = false;
  if (continuous && cv_->live && cv_->t_live == tau0) {
    pack(cv_->ycheck.data(), m);
    resume = std::equal(cv_->ycheck.begin(), cv_->ycheck.end(), y);
  }
  cv_->live = false;
  if (!resume) {
    pack(y, m);
    if (!cv_->initialised) {
      initCvode(*cv_, tau0);
      cv_->initialised = true;
    } else {
      check(CVodeReInit(mem, tau0, cv_->y), "CVodeReInit");
    }
    cv_->nst = cv_->nfe = cv_->netf = cv_->nni = 0;  // (Re)Init resets CVODE's counters
    ++stats_.restarts;
    if (opt_.adaptive_initial_step) {
      // 0 asks CVODE for its own estimate (CVHin), as on the first restart.
      check(CVodeSetInitStep(mem, std::min(cv_->h0_hint_s, dt)), "CVodeSetInitStep");
      cv_->scoring_h0 = true;
    }
  }
  // Never step past t1: u(t) is only defined on [t0, t1].
  check(CVodeSetStopTime(mem, tau1), "CVodeSetStopTime");

  // After a restart CVODE's first right-hand side is f(tau0, y0), whose Jacobian is F(t0):
  // evalRhs keeps it for the consider cross-covariance instead of a second evaluation here.
  capture_F0_ = cross && !resume;
  capture_tau_ = tau0;
  double tret = tau0;
  const int flag = CVode(mem, tau1, cv_->y, &tret, CV_NORMAL);
  if (cross && (capture_F0_ || resume)) {  // no restart (or no first evaluation at t0)
    capture_F0_ = false;
    u.eval(t_, wu_);
    model_.F(x_, wu_, wF0_);
  }
  if (flag < 0) {
    // Name the interval (absolute times) and CVODE's reason; the caller adds the record.
    cv_->live = false;
    throw std::runtime_error(fmt::format(
        "CVODE failed ({}) integrating from t = {:.6f} s to {:.6f} s (reached {:.6f} s)",
        flagName(flag), t_, t1_s, t_ref_ + tret));
  }
  countSteps(*cv_, dt, scale);
  ++stats_.intervals;
  unpack(y, m);
  if (cross) propagateConsiderCross(dt, t1_s, wF0_);
  t_ = t1_s;
  cv_->live = true;
  cv_->t_live = tau1;
}

double CdEkf::nis(const Eigen::VectorXd& y, const Eigen::MatrixXd& H,
                  const Eigen::MatrixXd& R) const {
  const Eigen::MatrixXd S = H * P_ * H.transpose() + R;
  return y.dot(S.ldlt().solve(y));
}

UpdateResult josephUpdateLdlt(Eigen::VectorXd& x, Eigen::MatrixXd& P, const Eigen::VectorXd& y,
                              const Eigen::MatrixXd& H, const Eigen::MatrixXd& R, double gate) {
  UpdateResult r;
  r.dof = static_cast<int>(y.size());
  r.innovation = y;
  // Small matrices (n <= ~10, m <= 2): coefficient-based products, no GEMM blocking.
  const Eigen::MatrixXd PHt = P.lazyProduct(H.transpose());
  r.S = H.lazyProduct(PHt) + R;
  r.S = 0.5 * (r.S + r.S.transpose());
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(r.S);
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 0)) {
    // A degenerate measurement (zero or non-finite innovation covariance, e.g. from a
    // zero-length encoder interval) is rejected and counted like a gated one: one bad sample
    // must not end a whole replay.
    r.nis = std::numeric_limits<double>::infinity();
    r.accepted = false;
    return r;
  }
  r.nis = y.dot(ldlt.solve(y));
  if (gate > 0 && !(r.nis <= gate)) {
    r.accepted = false;
    return r;
  }
  const Eigen::MatrixXd K = ldlt.solve(PHt.transpose()).transpose();  // P H' S^-1
  x += K * y;
  // Joseph form (I - K H) P (I - K H)' + K R K', evaluated without n x n x n products:
  // A = (I - K H) P = P - K (P H')'  (P symmetric), then A (I - K H)' = A - (A H') K'.
  Eigen::MatrixXd A = P;
  A.noalias() -= K.lazyProduct(PHt.transpose());
  const Eigen::MatrixXd AHt = A.lazyProduct(H.transpose());
  const Eigen::MatrixXd KR = K.lazyProduct(R);
  Eigen::MatrixXd Pn = A;
  Pn.noalias() -= AHt.lazyProduct(K.transpose());
  Pn.noalias() += KR.lazyProduct(K.transpose());
  P = 0.5 * (Pn + Pn.transpose());
  r.accepted = true;
  return r;
}

namespace {

// The closed-form path, with fixed sizes where the caller knows them (N, M) so that Eigen
// unrolls the tiny products; Eigen::Dynamic gives the same code with stack storage of fixed
// capacity (kMaxN x 2).
constexpr int kMaxN = 16;

template <int N, int M>
UpdateResult josephSmall(Eigen::VectorXd& x, Eigen::MatrixXd& P, const Eigen::VectorXd& y,
                         const Eigen::MatrixXd& H, const Eigen::MatrixXd& R, double gate) {
  constexpr int kN = N == Eigen::Dynamic ? kMaxN : N;
  constexpr int kM = M == Eigen::Dynamic ? 2 : M;
  using MatNN = Eigen::Matrix<double, N, N, Eigen::ColMajor, kN, kN>;
  using MatNM = Eigen::Matrix<double, N, M, Eigen::ColMajor, kN, kM>;
  using MatMN = Eigen::Matrix<double, M, N, Eigen::RowMajor, kM, kN>;
  using MatMM = Eigen::Matrix<double, M, M, Eigen::ColMajor, kM, kM>;
  using VecM = Eigen::Matrix<double, M, 1, Eigen::ColMajor, kM, 1>;
  const int n = static_cast<int>(P.rows());
  const int m = static_cast<int>(y.size());
  UpdateResult r;
  r.dof = m;
  r.innovation = y;
  const MatNN Pf = P;
  const MatMN Hf = H;
  const MatMM Rf = R;
  const VecM yf = y;
  MatNM PHt(n, m);
  PHt.noalias() = Pf.lazyProduct(Hf.transpose());
  MatMM S(m, m);
  S.noalias() = Hf.lazyProduct(PHt);
  S += Rf;
  MatMM Sinv(m, m);
  bool positive = false;
  if (m == 1) {
    positive = S(0, 0) > 0 && std::isfinite(S(0, 0));
    if (positive) Sinv(0, 0) = 1.0 / S(0, 0);
  } else {
    const double s01 = 0.5 * (S(0, 1) + S(1, 0));
    S(0, 1) = S(1, 0) = s01;
    const double det = S(0, 0) * S(1, 1) - s01 * s01;
    // Positive definite: leading minors > 0 (det relative to the diagonal product guards
    // against a numerically singular S).
    positive = S(0, 0) > 0 && S(1, 1) > 0 && det > 1e-14 * S(0, 0) * S(1, 1) && std::isfinite(det);
    if (positive) {
      Sinv(0, 0) = S(1, 1) / det;
      Sinv(1, 1) = S(0, 0) / det;
      Sinv(0, 1) = Sinv(1, 0) = -s01 / det;
    }
  }
  r.S = S;
  if (!positive) {
    // A degenerate measurement (zero or non-finite innovation covariance, e.g. from a
    // zero-length encoder interval) is rejected and counted like a gated one: one bad sample
    // must not end a whole replay.
    r.nis = std::numeric_limits<double>::infinity();
    r.accepted = false;
    return r;
  }
  r.nis = yf.dot(Sinv * yf);
  if (gate > 0 && !(r.nis <= gate)) {
    r.accepted = false;
    return r;
  }
  MatNM K(n, m);
  K.noalias() = PHt.lazyProduct(Sinv);  // P H' S^-1 (S^-1 symmetric)
  x.noalias() += K * yf;
  // Joseph form, as in josephUpdateLdlt: A = P - K (P H')', P+ = A - (A H') K' + K R K'.
  MatNN A = Pf;
  A.noalias() -= K.lazyProduct(PHt.transpose());
  MatNM AHt(n, m);
  AHt.noalias() = A.lazyProduct(Hf.transpose());
  MatNM KR(n, m);
  KR.noalias() = K.lazyProduct(Rf);
  A.noalias() -= AHt.lazyProduct(K.transpose());
  A.noalias() += KR.lazyProduct(K.transpose());
  P = 0.5 * (A + A.transpose());
  r.accepted = true;
  return r;
}

}  // namespace

UpdateResult josephUpdate(Eigen::VectorXd& x, Eigen::MatrixXd& P, const Eigen::VectorXd& y,
                          const Eigen::MatrixXd& H, const Eigen::MatrixXd& R, double gate) {
  const int n = static_cast<int>(P.rows());
  const int m = static_cast<int>(y.size());
  // Every sensor of the chair gives m <= 2 (encoder pair, gyro, sonar, Pozyx x/y): S is
  // inverted in closed form and the work matrices live on the stack; the LDLT path's
  // allocations and triangular-solve set-up were most of the update's cost. The physics
  // filter's n = 9 (12 with its sensor-error states) gets fully fixed sizes.
  if (n == 9 && m == 1) return josephSmall<9, 1>(x, P, y, H, R, gate);
  if (n == 9 && m == 2) return josephSmall<9, 2>(x, P, y, H, R, gate);
  if (n == 12 && m == 1) return josephSmall<12, 1>(x, P, y, H, R, gate);
  if (n == 12 && m == 2) return josephSmall<12, 2>(x, P, y, H, R, gate);
  if (m >= 1 && m <= 2 && n <= kMaxN)
    return josephSmall<Eigen::Dynamic, Eigen::Dynamic>(x, P, y, H, R, gate);
  return josephUpdateLdlt(x, P, y, H, R, gate);
}

UpdateResult CdEkf::update(const Eigen::VectorXd& y, const Eigen::MatrixXd& H,
                           const Eigen::MatrixXd& R, double gate) {
  return josephUpdate(x_, P_, y, H, R, gate);
}

UpdateResult CdEkf::correct(Measurement& m, double gate) {
  return estimation::correct(x_, P_, m, gate);
}

}  // namespace wheelchair::estimation
