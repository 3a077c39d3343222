#include "libwheelchair/stats/LeastSquares.h"

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
    s.singular_values = svd.singularValues();
    s.V = svd.matrixV();
    const double smax = s.singular_values(0);
    s.rank = 0;
    for (long k = 0; k < p; ++k)
      if (s.singular_values(k) > opt.rank_tol * smax) ++s.rank;
    const double smin = s.singular_values(p - 1);
    s.condition_number = smin > 0 ? smax / smin : std::numeric_limits<double>::infinity();
    s.condition_number_identifiable =
        s.rank > 0 ? smax / s.singular_values(s.rank - 1) : std::numeric_limits<double>::infinity();
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

  // (X_s'X_s)^+ on the retained subspace.
  const Eigen::MatrixXd P = Vr * sr.array().pow(-2).matrix().asDiagonal() * Vr.transpose();
  const double sigma2 = s.residuals.squaredNorm() / std::max<long>(1, n - r);
  const Eigen::MatrixXd cov_naive_s = sigma2 * P;
  const Eigen::MatrixXd S =
      hacScoreCovariance(Xs, s.residuals, time_index, block, std::max(0, opt.hac_lags));
  const double small_sample = double(n) / std::max<long>(1, n - r);
  const Eigen::MatrixXd cov_s = small_sample * P * S * P;
  const Eigen::MatrixXd Dinv = s.column_scale.cwiseInverse().asDiagonal();
  s.cov = Dinv * cov_s * Dinv;
  s.cov_naive = Dinv * cov_naive_s * Dinv;

  // Effective number of rows: how much the autocorrelation inflates the variance.
  double ratio = 0;
  for (int k = 0; k < r; ++k) {
    const double vh = Vr.col(k).dot(cov_s * Vr.col(k));
    const double vn = Vr.col(k).dot(cov_naive_s * Vr.col(k));
    ratio += vh > 0 ? vn / vh : 1.0;
  }
  rs.n_effective = r > 0 ? n * ratio / r : 0;

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

LinearFit fitLinear(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, const Groups& groups,
                    int lags) {
  return fitLinear(Eigen::MatrixXd(X), y, groups, lags);
}

LinearFit fitLinear(Eigen::MatrixXd&& X, const Eigen::VectorXd& y, const Groups& groups, int lags) {
  LinearFit f;
  const int n = static_cast<int>(y.size());
  const int p = static_cast<int>(X.cols());
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
  std::vector<long> time_index(n, 0);
  std::vector<int> block(n, -1);
  for (std::size_t g = 0; g < groups.size(); ++g)
    for (int i = std::max(0, groups[g].first); i < std::min(n, groups[g].second); ++i)
      time_index[i] = i - groups[g].first, block[i] = static_cast<int>(g);
  for (int i = 0; i < n; ++i)  // rows outside every group: each its own block
    if (block[i] < 0) block[i] = -1 - i;
  LsOptions opt;
  opt.hac_lags = std::max(0, lags);
  opt.rank_tol = 1e-10;
  LsSolution s = solve(std::move(X), y, time_index, block, opt);
  f.rank = s.rank;
  if (s.rank < p) return f;
  f.beta = s.beta;
  f.cov = s.cov;
  f.rss = s.residuals.squaredNorm();
  f.residual = std::move(s.residuals);
  f.ok = true;
  return f;
}

}  // namespace wheelchair::stats
