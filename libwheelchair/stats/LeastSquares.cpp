#include "libwheelchair/stats/LeastSquares.h"

#include <Eigen/QR>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>
#include <utility>

namespace wheelchair::stats {

namespace {

// Per-block dense score matrices (p x T), time steps without rows hold zeros.
struct BlockSeries {
  long t0 = 0;
  Eigen::MatrixXd G;
};

std::map<int, BlockSeries> scoreSeries(const Eigen::MatrixXd& X, const Eigen::VectorXd& e,
                                       const std::vector<long>& ti, const std::vector<int>& blk) {
  std::map<int, std::pair<long, long>> range;
  for (std::size_t r = 0; r < ti.size(); ++r) {
    auto it = range.find(blk[r]);
    if (it == range.end())
      range[blk[r]] = {ti[r], ti[r]};
    else {
      it->second.first = std::min(it->second.first, ti[r]);
      it->second.second = std::max(it->second.second, ti[r]);
    }
  }
  std::map<int, BlockSeries> out;
  for (auto& [b, rg] : range) {
    BlockSeries s;
    s.t0 = rg.first;
    s.G = Eigen::MatrixXd::Zero(X.cols(), rg.second - rg.first + 1);
    out[b] = std::move(s);
  }
  for (std::size_t r = 0; r < ti.size(); ++r) {
    auto& s = out[blk[r]];
    s.G.col(ti[r] - s.t0) += X.row(r).transpose() * e(r);
  }
  return out;
}

}  // namespace

Eigen::MatrixXd hacScoreCovariance(const Eigen::MatrixXd& X, const Eigen::VectorXd& e,
                                   const std::vector<long>& ti, const std::vector<int>& blk,
                                   int lags) {
  const auto series = scoreSeries(X, e, ti, blk);
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(X.cols(), X.cols());
  for (const auto& [b, s] : series) {
    const long T = s.G.cols();
    S += s.G * s.G.transpose();
    for (long l = 1; l <= lags && l < T; ++l) {
      const double w = 1.0 - double(l) / (lags + 1);
      const Eigen::MatrixXd C = s.G.leftCols(T - l) * s.G.rightCols(T - l).transpose();
      S += w * (C + C.transpose());
    }
  }
  return S;
}

Eigen::MatrixXd LsSolution::nullDirections() const {
  const int p = static_cast<int>(V.cols());
  Eigen::MatrixXd N(p, p - rank);
  for (int k = rank; k < p; ++k) {
    Eigen::VectorXd d = V.col(k).cwiseQuotient(column_scale);
    N.col(k - rank) = d / d.norm();
  }
  return N;
}

bool LsSolution::isEstimable(const Eigen::VectorXd& w, double tol) const {
  const Eigen::VectorXd ws = w.cwiseQuotient(column_scale);
  const double n = ws.norm();
  if (n == 0) return true;
  const int p = static_cast<int>(V.cols());
  if (rank == p) return true;
  const Eigen::VectorXd proj = V.rightCols(p - rank).transpose() * ws;
  return proj.norm() <= tol * n;
}

double LsSolution::standardError(const Eigen::VectorXd& w) const {
  return std::sqrt(std::max(0.0, w.dot(cov * w)));
}

double LsSolution::standardErrorNaive(const Eigen::VectorXd& w) const {
  return std::sqrt(std::max(0.0, w.dot(cov_naive * w)));
}

void LsSolution::setCovariances(const Eigen::MatrixXd& Vr, const Eigen::VectorXd& sr,
                                const Eigen::MatrixXd& S_hac, double rss, long n,
                                const Eigen::VectorXd& inv_scale) {
  const int r = rank;
  const Eigen::MatrixXd P = Vr * sr.array().pow(-2).matrix().asDiagonal() * Vr.transpose();
  const double sigma2 = rss / std::max<long>(1, n - r);
  const Eigen::MatrixXd cov_naive_s = sigma2 * P;
  const double small_sample = double(n) / std::max<long>(1, n - r);
  const Eigen::MatrixXd cov_s = small_sample * P * S_hac * P;
  const Eigen::MatrixXd Dinv = inv_scale.asDiagonal();
  cov = Dinv * cov_s * Dinv;
  cov_naive = Dinv * cov_naive_s * Dinv;
  // Effective number of rows: how much the autocorrelation inflates the variance.
  double ratio = 0;
  for (int k = 0; k < r; ++k) {
    const double vh = Vr.col(k).dot(cov_s * Vr.col(k));
    const double vn = Vr.col(k).dot(cov_naive_s * Vr.col(k));
    ratio += vh > 0 ? vn / vh : 1.0;
  }
  residual.n_effective = r > 0 ? n * ratio / r : 0;
}

void TsqrAccumulator::add(const Eigen::Ref<const Eigen::MatrixXd>& X,
                          const Eigen::Ref<const Eigen::VectorXd>& y) {
  const long nb = X.rows(), p = inv_scale_.size();
  if (nb == 0) return;
  W_.resize(R_.rows() + nb, p + 1);
  W_.topRows(R_.rows()) = R_;
  W_.bottomRows(nb).leftCols(p) = X * inv_scale_.asDiagonal();
  W_.bottomRows(nb).col(p) = y;
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(W_);
  const long k = std::min<long>(W_.rows(), p + 1);
  R_ = qr.matrixQR().topRows(k).triangularView<Eigen::Upper>();
}

Eigen::MatrixXd TsqrAccumulator::triangle() const {
  const long p = inv_scale_.size();
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(p + 1, p + 1);
  out.topRows(R_.rows()) = R_;
  return out;
}

namespace {

// solveLeastSquares on the design X, which it owns and equilibrates in place (fitLinear's
// designs are up to n x p = 10^6 x 14 doubles on a long drive: a copy less matters,
// docs/benchmarks.md "Memory"), and the caller's y.
LsSolution solve(Eigen::MatrixXd X, const Eigen::VectorXd& y, const std::vector<long>& time_index,
                 const std::vector<int>& block, const LsOptions& opt) {
  const long n = X.rows(), p = X.cols();
  if (y.size() != n || long(time_index.size()) != n || long(block.size()) != n)
    throw std::invalid_argument("solveLeastSquares: inconsistent input sizes");
  if (n < p) throw std::invalid_argument("solveLeastSquares: fewer rows than parameters");

  LsSolution s;
  // Column equilibration: unit 2-norm columns (an all-zero column keeps scale 1 and shows up
  // as a zero singular value, i.e. an undetermined parameter).
  s.column_scale = X.colwise().norm().transpose();
  for (long j = 0; j < p; ++j)
    if (!(s.column_scale(j) > 0)) s.column_scale(j) = 1.0;
  const Eigen::VectorXd inv_scale = s.column_scale.cwiseInverse();
  for (long j = 0; j < p; ++j) X.col(j) *= inv_scale(j);  // X * diag(inv_scale), in place
  const Eigen::MatrixXd& Xs = X;

  Eigen::MatrixXd Vr;
  Eigen::VectorXd sr, beta_s;
  {  // the SVD's n x p work matrices are freed before the score series are built
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(Xs, Eigen::ComputeThinU | Eigen::ComputeFullV);
    s.setSpectrum(svd, opt.rank_tol);
    Vr = s.V.leftCols(s.rank);
    sr = s.singular_values.head(s.rank);
    beta_s =
        Vr * (sr.cwiseInverse().asDiagonal() * (svd.matrixU().leftCols(s.rank).transpose() * y));
  }
  const int r = s.rank;
  s.beta = beta_s.cwiseQuotient(s.column_scale);

  s.residuals = y - Xs * beta_s;
  auto& rs = s.residual;
  rs.n_rows = static_cast<std::size_t>(n);
  rs.dof = static_cast<int>(n - r);
  rs.rms = std::sqrt(s.residuals.squaredNorm() / n);
  rs.mean = s.residuals.mean();
  rs.max_abs = s.residuals.cwiseAbs().maxCoeff();
  rs.rms_y = std::sqrt(y.squaredNorm() / n);
  rs.r_squared = 1.0 - s.residuals.squaredNorm() / std::max(y.squaredNorm(), 1e-300);

  s.setCovariances(
      Vr, sr, hacScoreCovariance(Xs, s.residuals, time_index, block, std::max(0, opt.hac_lags)),
      s.residuals.squaredNorm(), n, s.column_scale.cwiseInverse());

  // Lag-1 autocorrelation of the per-time-step residual sum, within blocks.
  {
    Eigen::MatrixXd ones = Eigen::MatrixXd::Ones(n, 1);
    const auto series = scoreSeries(ones, s.residuals, time_index, block);
    double c0 = 0, c1 = 0;
    for (const auto& [b, ser] : series) {
      const Eigen::RowVectorXd g = ser.G.row(0);
      c0 += g.squaredNorm();
      if (g.size() > 1) c1 += g.head(g.size() - 1).dot(g.tail(g.size() - 1));
    }
    rs.lag1_autocorr = c0 > 0 ? c1 / c0 : 0;
  }
  return s;
}

}  // namespace

LsSolution solveLeastSquares(const LsInput& in, const LsOptions& opt) {
  return solve(in.X, in.y, in.time_index, in.block, opt);
}

LsSolution solveLeastSquares(LsInput&& in, const LsOptions& opt) {
  return solve(std::move(in.X), in.y, in.time_index, in.block, opt);
}

Groups singleGroup(int n) {
  return {{0, n}};
}

namespace {

// Rows per block of the blocked fit (work matrices of a few (block + p) x p doubles).
constexpr long kFitBlockRows = kDesignBlockRows;

// The (p + 1) x (p + 1) triangle [R c; 0 rho] of the equilibrated [X D^-1, y] (TsqrAccumulator),
// kFitBlockRows rows at a time.
// `rows(r0, nb)`: rows [r0, r0 + nb) of the n x p design (a view of a stored matrix, or a
// block made on demand: fitLinear(DesignRows, ...)).
template <class Rows>
Eigen::MatrixXd blockedQr(const Rows& rows, long n, const Eigen::VectorXd& y,
                          const Eigen::VectorXd& inv_scale) {
  TsqrAccumulator acc(inv_scale);
  for (long r0 = 0; r0 < n; r0 += kFitBlockRows) {
    const long nb = std::min(kFitBlockRows, n - r0);
    acc.add(rows(r0, nb), y.segment(r0, nb));
  }
  return acc.triangle();
}

// Newey-West S of the scores g_i = (X D^-1)_i' e_i of the rows of each group (one series per
// group, lags never cross a group boundary; a row in no group is its own series), made block
// of rows by block: the p x (lags + block) window holds the block's scores and the `lags`
// before it. The same sums as hacScoreCovariance() with one row per time step, in another order.
template <class Rows>
Eigen::MatrixXd blockedHac(const Rows& rows, long n, long p, const Eigen::VectorXd& e,
                           const Eigen::VectorXd& inv_scale, const Groups& groups, int lags) {
  const long L = std::max(0, lags);
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(p, p), G(p, L + kFitBlockRows), C;
  std::vector<char> in_group(static_cast<std::size_t>(n), 0);
  for (const auto& [a0, b0] : groups) {
    const long a = std::max<long>(0, a0), b = std::min<long>(n, b0);
    if (a >= b) continue;
    G.leftCols(L).setZero();  // no scores before the group's first row
    for (long c0 = a; c0 < b; c0 += kFitBlockRows) {
      const long nb = std::min(kFitBlockRows, b - c0);
      G.middleCols(L, nb) =
          (rows(c0, nb) * inv_scale.asDiagonal()).transpose() * e.segment(c0, nb).asDiagonal();
      const auto Gc = G.middleCols(L, nb);
      S.noalias() += Gc * Gc.transpose();
      for (long l = 1; l <= L; ++l) {  // pairs (t - l, t), t in this block
        C.noalias() = G.middleCols(L - l, nb) * Gc.transpose();
        S += (1.0 - double(l) / (L + 1)) * (C + C.transpose());
      }
      if (L > 0) G.leftCols(L) = Eigen::MatrixXd(G.middleCols(nb, L));
    }
    std::fill(in_group.begin() + a, in_group.begin() + b, 1);
  }
  for (long i = 0; i < n; ++i)
    if (!in_group[static_cast<std::size_t>(i)]) {
      const Eigen::VectorXd g = rows(i, 1).row(0).transpose().cwiseProduct(inv_scale) * e(i);
      S.noalias() += g * g.transpose();
    }
  return S;
}

}  // namespace

namespace {

// fitLinear on the design whose rows `rows(r0, nb)` gives and whose column 2-norms are `scale`;
// `subtractFit(beta, residual)` takes X beta from the residual (y on entry).
template <class Rows, class SubtractFit>
LinearFit fitLinearRows(const Rows& rows, long n, long p, Eigen::VectorXd scale,
                        const Eigen::VectorXd& y, const Groups& groups, int lags,
                        const SubtractFit& subtractFit) {
  LinearFit f;
  f.residual = y;
  f.rss = y.squaredNorm();
  if (p == 0) {
    f.beta.resize(0);
    f.cov.resize(0, 0);
    f.ok = true;
    return f;
  }
  f.beta = Eigen::VectorXd::Zero(p);
  f.cov = Eigen::MatrixXd::Identity(p, p) * 1e300;
  if (n <= p) return f;
  // Column equilibration (unit 2-norm columns; an all-zero column keeps scale 1).
  for (long j = 0; j < p; ++j)
    if (!(scale(j) > 0)) scale(j) = 1.0;
  const Eigen::VectorXd inv_scale = scale.cwiseInverse();
  // X D^-1 = Q R, R = U diag(s) V': the singular values and V of X D^-1 are those of R.
  const Eigen::MatrixXd Rc = blockedQr(rows, n, y, inv_scale);
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(Rc.topLeftCorner(p, p),
                                              Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::VectorXd& sv = svd.singularValues();
  long r = 0;
  for (long k = 0; k < p; ++k)
    if (sv(k) > 1e-10 * sv(0)) ++r;
  f.rank = static_cast<int>(r);
  if (r < p) return f;
  const Eigen::MatrixXd& V = svd.matrixV();
  const Eigen::VectorXd beta_s =
      V * (sv.cwiseInverse().asDiagonal() * (svd.matrixU().transpose() * Rc.col(p).head(p)));
  f.beta = beta_s.cwiseProduct(inv_scale);
  subtractFit(f.beta, f.residual);
  f.rss = f.residual.squaredNorm();
  // HAC sandwich in the equilibrated metric, (X_s'X_s)^-1 S (X_s'X_s)^-1, mapped back.
  const Eigen::MatrixXd P = V * sv.array().pow(-2).matrix().asDiagonal() * V.transpose();
  const Eigen::MatrixXd S = blockedHac(rows, n, p, f.residual, inv_scale, groups, lags);
  const double small_sample = double(n) / double(n - r);
  f.cov = inv_scale.asDiagonal() * (small_sample * P * S * P) * inv_scale.asDiagonal();
  f.ok = true;
  return f;
}

}  // namespace

LinearFit fitLinear(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, const Groups& groups,
                    int lags) {
  const long n = y.size(), p = X.cols();
  if (p > 0 && n > p && X.rows() != n)
    throw std::invalid_argument("fitLinear: inconsistent input sizes");
  auto rows = [&X](long r0, long nb) { return X.middleRows(r0, nb); };
  const Eigen::VectorXd scale =
      p > 0 && n > p ? Eigen::VectorXd(X.colwise().norm().transpose()) : Eigen::VectorXd();
  return fitLinearRows(
      rows, n, p, scale, y, groups, lags,
      [&X](const Eigen::VectorXd& beta, Eigen::VectorXd& e) { e.noalias() -= X * beta; });
}

LinearFit fitLinear(const DesignRows& rows, long p, const Eigen::VectorXd& y, const Groups& groups,
                    int lags) {
  const long n = y.size();
  Eigen::MatrixXd block;
  auto view = [&](long r0, long nb) -> const Eigen::MatrixXd& {
    rows(r0, nb, block);
    if (block.rows() != nb || block.cols() != p)
      throw std::invalid_argument("fitLinear: design block of the wrong size");
    return block;
  };
  Eigen::VectorXd scale = Eigen::VectorXd::Zero(std::max<long>(p, 0));
  if (p > 0 && n > p) {  // column 2-norms, block by block
    for (long r0 = 0; r0 < n; r0 += kFitBlockRows)
      scale += view(r0, std::min(kFitBlockRows, n - r0)).colwise().squaredNorm().transpose();
    scale = scale.cwiseSqrt();
  }
  return fitLinearRows(view, n, p, scale, y, groups, lags,
                       [&](const Eigen::VectorXd& beta, Eigen::VectorXd& e) {
                         for (long r0 = 0; r0 < n; r0 += kFitBlockRows) {
                           const long nb = std::min(kFitBlockRows, n - r0);
                           e.segment(r0, nb).noalias() -= view(r0, nb) * beta;
                         }
                       });
}

LinearFit fitLinear(Eigen::MatrixXd&& X, const Eigen::VectorXd& y, const Groups& groups, int lags) {
  const Eigen::MatrixXd design = std::move(X);  // freed on return, as before
  return fitLinear(design, y, groups, lags);
}

}  // namespace wheelchair::stats
