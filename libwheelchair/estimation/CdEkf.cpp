#include "libwheelchair/estimation/CdEkf.h"

#include <cvode/cvode.h>
#include <nvector/nvector_serial.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>
#include <sunnonlinsol/sunnonlinsol_fixedpoint.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
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
};

namespace {

void check(int flag, const char* what) {
  if (flag < 0)
    throw std::runtime_error(std::string("CdEkf: CVODE ") + what + " failed, flag " +
                             std::to_string(flag));
}

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

  cv_ = std::make_unique<Cvode>();
  const int N = n_ + packedSize(n_);
  check(SUNContext_Create(nullptr, &cv_->ctx), "SUNContext_Create");
  cv_->y = N_VNew_Serial(N, cv_->ctx);
  cv_->abstol = N_VNew_Serial(N, cv_->ctx);
  if (!cv_->y || !cv_->abstol) throw std::runtime_error("CdEkf: N_VNew_Serial failed");
  double* at = N_VGetArrayPointer(cv_->abstol);
  for (int i = 0; i < N; ++i) at[i] = (i < n_) ? opt_.abs_tol_state : opt_.abs_tol_cov;
  const bool bdf = opt_.method == CvodeOptions::Method::Bdf;
  cv_->mem = CVodeCreate(bdf ? CV_BDF : CV_ADAMS, cv_->ctx);
  if (!cv_->mem) throw std::runtime_error("CdEkf: CVodeCreate failed");
}

CdEkf::~CdEkf() = default;

void CdEkf::pack(double* y) const {
  for (int i = 0; i < n_; ++i) y[i] = x_(i);
  int k = n_;
  for (int c = 0; c < n_; ++c)
    for (int r = c; r < n_; ++r) y[k++] = P_(r, c);
}

void CdEkf::unpack(const double* y) {
  for (int i = 0; i < n_; ++i) x_(i) = y[i];
  int k = n_;
  for (int c = 0; c < n_; ++c)
    for (int r = c; r < n_; ++r) {
      P_(r, c) = y[k];
      P_(c, r) = y[k];
      ++k;
    }
}

void CdEkf::evalRhs(double t, const double* y, double* ydot) {
  for (int i = 0; i < n_; ++i) wx_(i) = y[i];
  int k = n_;
  for (int c = 0; c < n_; ++c)
    for (int r = c; r < n_; ++r) {
      wP_(r, c) = y[k];
      wP_(c, r) = y[k];
      ++k;
    }
  wu_ = (*u_)(t);
  model_.f(wx_, wu_, wxd_);
  model_.F(wx_, wu_, wF_);
  model_.Q(wx_, wu_, wQ_);
  wFP_.noalias() = wF_ * wP_;
  for (int i = 0; i < n_; ++i) ydot[i] = wxd_(i);
  k = n_;
  for (int c = 0; c < n_; ++c)
    for (int r = c; r < n_; ++r)
      ydot[k++] = wFP_(r, c) + wFP_(c, r) + 0.5 * (wQ_(r, c) + wQ_(c, r));
}

void CdEkf::reset(double t0_s, const Eigen::VectorXd& x0, const Eigen::MatrixXd& P0) {
  if (x0.size() != n_ || P0.rows() != n_ || P0.cols() != n_)
    throw std::invalid_argument("CdEkf::reset: dimension mismatch");
  t_ = t0_s;
  x_ = x0;
  setCovariance(P0);
}

void CdEkf::setCovariance(const Eigen::MatrixXd& P) {
  P_ = 0.5 * (P + P.transpose());
}

void CdEkf::propagate(double t1_s, const InputFunction& u) {
  if (!(t1_s >= t_)) throw std::invalid_argument("CdEkf::propagate: time goes backwards");
  const double dt = t1_s - t_;
  if (dt == 0.0) return;
  u_ = &u;
  const double scale = std::max(1.0, std::max(std::fabs(t_), std::fabs(t1_s)));
  if (dt < 1e-9 * scale) {
    // Too short for CVODE's first step heuristics: one explicit Euler step (exact to O(dt^2)).
    const int N = n_ + packedSize(n_);
    std::vector<double> y(N), yd(N);
    pack(y.data());
    evalRhs(t_, y.data(), yd.data());
    for (int i = 0; i < N; ++i) y[i] += dt * yd[i];
    unpack(y.data());
    t_ = t1_s;
    ++stats_.short_intervals;
    return;
  }
  pack(N_VGetArrayPointer(cv_->y));
  void* mem = cv_->mem;
  if (!cv_->initialised) {
    check(CVodeInit(mem, &CdEkfAccess::rhs, t_, cv_->y), "CVodeInit");
    check(CVodeSVtolerances(mem, opt_.rel_tol, cv_->abstol), "CVodeSVtolerances");
    check(CVodeSetUserData(mem, this), "CVodeSetUserData");
    if (opt_.method == CvodeOptions::Method::Adams) {
      cv_->nls = SUNNonlinSol_FixedPoint(cv_->y, 0, cv_->ctx);
      if (!cv_->nls) throw std::runtime_error("CdEkf: SUNNonlinSol_FixedPoint failed");
      check(CVodeSetNonlinearSolver(mem, cv_->nls), "CVodeSetNonlinearSolver");
    } else {
      const int N = n_ + packedSize(n_);
      cv_->A = SUNDenseMatrix(N, N, cv_->ctx);
      cv_->ls = SUNLinSol_Dense(cv_->y, cv_->A, cv_->ctx);
      if (!cv_->A || !cv_->ls) throw std::runtime_error("CdEkf: dense linear solver failed");
      check(CVodeSetLinearSolver(mem, cv_->ls, cv_->A), "CVodeSetLinearSolver");
    }
    check(CVodeSetMaxNumSteps(mem, opt_.max_num_steps), "CVodeSetMaxNumSteps");
    if (opt_.max_step_s > 0) check(CVodeSetMaxStep(mem, opt_.max_step_s), "CVodeSetMaxStep");
    if (opt_.max_order > 0) check(CVodeSetMaxOrd(mem, opt_.max_order), "CVodeSetMaxOrd");
    cv_->initialised = true;
  } else {
    check(CVodeReInit(mem, t_, cv_->y), "CVodeReInit");
  }
  // Never step past t1: u(t) is only defined on [t0, t1].
  check(CVodeSetStopTime(mem, t1_s), "CVodeSetStopTime");

  double tret = t_;
  const int flag = CVode(mem, t1_s, cv_->y, &tret, CV_NORMAL);
  u_ = nullptr;
  check(flag, "CVode");
  long nst = 0, nfe = 0;
  CVodeGetNumSteps(mem, &nst);
  CVodeGetNumRhsEvals(mem, &nfe);
  stats_.steps += nst;
  stats_.rhs_evals += nfe;
  ++stats_.intervals;
  unpack(N_VGetArrayPointer(cv_->y));
  t_ = t1_s;
}

double CdEkf::nis(const Eigen::VectorXd& y, const Eigen::MatrixXd& H,
                  const Eigen::MatrixXd& R) const {
  const Eigen::MatrixXd S = H * P_ * H.transpose() + R;
  return y.dot(S.ldlt().solve(y));
}

UpdateResult josephUpdate(Eigen::VectorXd& x, Eigen::MatrixXd& P, const Eigen::VectorXd& y,
                          const Eigen::MatrixXd& H, const Eigen::MatrixXd& R, double gate) {
  const int n = static_cast<int>(x.size());
  UpdateResult r;
  r.dof = static_cast<int>(y.size());
  r.innovation = y;
  const Eigen::MatrixXd PHt = P * H.transpose();
  r.S = H * PHt + R;
  r.S = 0.5 * (r.S + r.S.transpose());
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(r.S);
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 0))
    throw std::runtime_error("josephUpdate: innovation covariance is not positive definite");
  r.nis = y.dot(ldlt.solve(y));
  if (gate > 0 && !(r.nis <= gate)) {
    r.accepted = false;
    return r;
  }
  const Eigen::MatrixXd K = ldlt.solve(PHt.transpose()).transpose();  // P H' S^-1
  x += K * y;
  const Eigen::MatrixXd IKH = Eigen::MatrixXd::Identity(n, n) - K * H;
  const Eigen::MatrixXd Pn = IKH * P * IKH.transpose() + K * R * K.transpose();
  P = 0.5 * (Pn + Pn.transpose());
  r.accepted = true;
  return r;
}

UpdateResult CdEkf::update(const Eigen::VectorXd& y, const Eigen::MatrixXd& H,
                           const Eigen::MatrixXd& R, double gate) {
  return josephUpdate(x_, P_, y, H, R, gate);
}

}  // namespace wheelchair::estimation
