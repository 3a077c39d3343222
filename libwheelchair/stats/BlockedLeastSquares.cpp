#include "libwheelchair/stats/BlockedLeastSquares.h"

#include <Eigen/QR>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <stdexcept>

namespace wheelchair::stats {

namespace {

constexpr long kWindowSteps = 2048;  // time steps per product of the HAC sums

// Rows must come grouped by block with non-decreasing time steps (header comment).
class OrderCheck {
 public:
  void operator()(int block, long t) {
    if (started_ && block == block_) {
      if (t < t_) throw std::invalid_argument("solveLeastSquaresBlocked: time steps out of order");
    } else {
      if (started_) done_.insert(block_);
      if (done_.count(block))
        throw std::invalid_argument("solveLeastSquaresBlocked: rows of a block not consecutive");
      block_ = block;
      started_ = true;
    }
    t_ = t;
  }

 private:
  bool started_ = false;
  int block_ = 0;
  long t_ = 0;
  std::set<int> done_;
};

// Newey-West S = sum_{|l|<=L} (1 - |l|/(L+1)) sum_t g_t g_{t-l}' of per-time-step scores that
// arrive in order (block by block, steps non-decreasing): the p x (L + kWindowSteps) window
// holds the L steps before the pending ones (zeros before a block's first step and for steps
// without rows), as fitLinear's blockedHac does for one row per step.
class HacSums {
 public:
  HacSums(long p, int lags)
      : L_(std::max(0, lags)),
        S_(Eigen::MatrixXd::Zero(p, p)),
        G_(Eigen::MatrixXd::Zero(p, L_ + kWindowSteps)) {}

  void add(int block, long t, const Eigen::VectorXd& g) {
    if (!started_ || block != block_ || t - t_ > L_ + 1) {  // a fresh series (nothing to lag)
      flush();
      G_.leftCols(L_).setZero();
      newStep();
    } else {
      for (long k = t_; k < t; ++k) newStep();  // steps without rows are zero scores
    }
    started_ = true;
    block_ = block;
    t_ = t;
    G_.col(L_ + nb_ - 1) += g;
  }
  Eigen::MatrixXd finish() {
    flush();
    return S_;
  }

 private:
  void newStep() {
    if (nb_ == kWindowSteps) flush();
    G_.col(L_ + nb_).setZero();
    ++nb_;
  }
  void flush() {
    if (nb_ == 0) return;
    const auto Gc = G_.middleCols(L_, nb_);
    S_.noalias() += Gc * Gc.transpose();
    for (long l = 1; l <= L_; ++l) {  // pairs (t - l, t), t pending
      C_.noalias() = G_.middleCols(L_ - l, nb_) * Gc.transpose();
      S_ += (1.0 - double(l) / (L_ + 1)) * (C_ + C_.transpose());
    }
    if (L_ > 0) G_.leftCols(L_) = Eigen::MatrixXd(G_.middleCols(nb_, L_));
    nb_ = 0;
  }

  long L_;
  Eigen::MatrixXd S_, G_, C_;
  long nb_ = 0;  // pending steps in the window
  bool started_ = false;
  int block_ = 0;
  long t_ = 0;
};

// Lag-1 autocorrelation sums of the per-time-step residual sums, within blocks.
class Lag1Sums {
 public:
  void add(int block, long t, double e) {
    if (started_ && block == block_ && t == t_) {
      cur_ += e;
      return;
    }
    close();
    adjacent_ = started_ && block == block_ && t == t_ + 1;
    started_ = true;
    block_ = block;
    t_ = t;
    cur_ = e;
  }
  double finish() {
    close();
    started_ = false;
    return c0_ > 0 ? c1_ / c0_ : 0;
  }

 private:
  void close() {
    if (!started_) return;
    c0_ += cur_ * cur_;
    if (adjacent_) c1_ += prev_ * cur_;
    prev_ = cur_;
  }
  bool started_ = false, adjacent_ = false;
  int block_ = 0;
  long t_ = 0;
  double cur_ = 0, prev_ = 0, c0_ = 0, c1_ = 0;
};

void checkSizes(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, const std::vector<long>& ti,
                const std::vector<int>& blk, int p) {
  const long n = X.rows();
  if (X.cols() != p || y.size() != n || long(ti.size()) != n || long(blk.size()) != n)
    throw std::invalid_argument("solveLeastSquaresBlocked: inconsistent input sizes");
}

// Pass 2: the (p + 1) x (p + 1) triangle [R c; 0 rho] of the equilibrated [X D^-1, y].
Eigen::MatrixXd tsqr(const LsRowSource& rows, int p, const Eigen::VectorXd& inv_scale) {
  TsqrAccumulator acc(inv_scale);
  rows([&](const Eigen::MatrixXd& X, const Eigen::VectorXd& y, const std::vector<long>& ti,
           const std::vector<int>& blk) {
    checkSizes(X, y, ti, blk, p);
    acc.add(X, y);
  });
  return acc.triangle();
}

}  // namespace

LsSolution solveLeastSquaresBlocked(const LsRowSource& rows, int p, const LsOptions& opt) {
  // Pass 1: column norms.
  Eigen::VectorXd ss = Eigen::VectorXd::Zero(p);
  double yy = 0;
  long n = 0;
  rows([&](const Eigen::MatrixXd& X, const Eigen::VectorXd& y, const std::vector<long>& ti,
           const std::vector<int>& blk) {
    checkSizes(X, y, ti, blk, p);
    if (X.rows() == 0) return;
    ss += X.colwise().squaredNorm().transpose();
    yy += y.squaredNorm();
    n += X.rows();
  });
  if (n < p) throw std::invalid_argument("solveLeastSquares: fewer rows than parameters");

  LsSolution s;
  s.column_scale = ss.cwiseSqrt();
  for (long j = 0; j < p; ++j)
    if (!(s.column_scale(j) > 0)) s.column_scale(j) = 1.0;
  const Eigen::VectorXd inv_scale = s.column_scale.cwiseInverse();

  // Pass 2: R of X D^-1, its SVD, the solution.
  const Eigen::MatrixXd Rc = tsqr(rows, p, inv_scale);
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(Rc.topLeftCorner(p, p),
                                              Eigen::ComputeFullU | Eigen::ComputeFullV);
  s.setSpectrum(svd, opt.rank_tol);
  const int r = s.rank;
  const Eigen::MatrixXd Vr = s.V.leftCols(r);
  const Eigen::VectorXd sr = s.singular_values.head(r);
  const Eigen::VectorXd beta_s = Vr * (sr.cwiseInverse().asDiagonal() *
                                       (svd.matrixU().leftCols(r).transpose() * Rc.col(p).head(p)));
  s.beta = beta_s.cwiseQuotient(s.column_scale);

  // Pass 3: residuals, HAC sums, lag-1 autocorrelation.
  double ee = 0, e_sum = 0, e_max = 0;
  HacSums hac(p, std::max(0, opt.hac_lags));
  Lag1Sums lag1;
  OrderCheck order;
  Eigen::MatrixXd Xs;
  Eigen::VectorXd e;
  rows([&](const Eigen::MatrixXd& X, const Eigen::VectorXd& y, const std::vector<long>& ti,
           const std::vector<int>& blk) {
    checkSizes(X, y, ti, blk, p);
    Xs = X * inv_scale.asDiagonal();
    e = y - Xs * beta_s;
    for (long i = 0; i < X.rows(); ++i) {
      order(blk[i], ti[i]);
      ee += e(i) * e(i);
      e_sum += e(i);
      e_max = std::max(e_max, std::abs(e(i)));
      hac.add(blk[i], ti[i], Xs.row(i).transpose() * e(i));
      lag1.add(blk[i], ti[i], e(i));
    }
  });
  auto& rs = s.residual;
  rs.n_rows = static_cast<std::size_t>(n);
  rs.dof = static_cast<int>(n - r);
  rs.rms = std::sqrt(ee / n);
  rs.mean = e_sum / n;
  rs.max_abs = e_max;
  rs.rms_y = std::sqrt(yy / n);
  rs.r_squared = 1.0 - ee / std::max(yy, 1e-300);
  rs.lag1_autocorr = lag1.finish();

  // Covariances as solveLeastSquares: (X_s'X_s)^+ on the retained subspace, the HAC sandwich.
  s.setCovariances(Vr, sr, hac.finish(), ee, n, inv_scale);
  return s;
}

}  // namespace wheelchair::stats
