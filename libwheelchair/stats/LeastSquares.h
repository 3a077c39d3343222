// Linear least squares done carefully: column equilibration, a rank-revealing SVD, the
// minimum-norm solution on the numerically identifiable subspace, and standard errors that
// survive coloured (autocorrelated) residuals.
//
// Why not (Y'Y)^-1 Y'l as in eq. (5): forming Y'Y squares the condition number, and the
// paper's 5-column regressor is rank-deficient by construction (docs/identification.md), so
// Y'Y is singular in exact arithmetic; no amount of extra precision makes theta_2 and
// theta_3 separable. The SVD of the equilibrated matrix tells which directions are
// determined and which are not, and the solution is reported only on the former.
//
// Standard errors: rows come from signals filtered at a few Hz and sampled at 50-100 Hz, so
// neighbouring residuals are strongly correlated and the textbook sigma^2 (X'X)^-1 is far too
// small. The covariance here is the Newey-West (Bartlett kernel) HAC sandwich
//   Cov = (X'X)^+ S (X'X)^+,  S = sum_{|l|<=L} (1 - |l|/(L+1)) sum_t g_t g_{t-l}',
//   g_t = sum over the rows of time step t of x_r e_r,
// with lags taken only within one block (a recording segment); rows of the same time step
// (the right and left motor) are grouped, so their correlation is accounted for too.
//
// This is the one HAC least squares of the library: identification calls it with rows grouped
// by time step (right and left motor), the diagnosis through fitLinear() with contiguous row
// GROUPS (one series per group, lags never cross a group boundary). The SVD is preferred to a
// QR with (X'X)^-1 for the covariance: it never forms X'X (whose condition number is the
// square), and it handles a rank-deficient design explicitly.
//
// Example:
//   LsInput in{X, y, time_index, block};
//   LsSolution s = solveLeastSquares(in, LsOptions{.hac_lags = 200});
//   if (s.isEstimable(w)) double est = w.dot(s.beta), se = std::sqrt(w.dot(s.cov * w));
//   LinearFit f = fitLinear(X, y, {{0, n}}, 10);   // full-rank fit of one series, 10 lags
#pragma once

#include <Eigen/Core>

#include <functional>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace wheelchair::stats {

struct LsInput {
  Eigen::MatrixXd X;             ///< n x p regressor
  Eigen::VectorXd y;             ///< n observations
  std::vector<long> time_index;  ///< per row: time-step index (rows of one step share it)
  std::vector<int> block;        ///< per row: block id; no correlation across blocks
};

struct LsOptions {
  int hac_lags = 200;      ///< Bartlett bandwidth L in time steps (0: White / iid)
  double rank_tol = 1e-9;  ///< singular values below rank_tol * sigma_max are treated as 0
};

struct ResidualStats {
  std::size_t n_rows = 0;
  int dof = 0;     ///< n_rows - rank
  double rms = 0;  ///< root mean square residual (units of y)
  double mean = 0;
  double max_abs = 0;
  double rms_y = 0;          ///< rms of y, for reference
  double r_squared = 0;      ///< 1 - RSS/TSS (TSS about zero: the model has no intercept)
  double lag1_autocorr = 0;  ///< of the per-time-step summed residual, within blocks
  double n_effective = 0;    ///< n_rows * (naive variance / HAC variance), averaged over
                             ///< estimable coordinates: how many independent rows the data
                             ///< are worth
};

struct LsSolution {
  Eigen::VectorXd beta;             ///< minimum-norm solution (in the scaled metric)
  Eigen::MatrixXd cov;              ///< HAC covariance of beta (valid for estimable w'beta)
  Eigen::MatrixXd cov_naive;        ///< sigma^2 (X'X)^+ (iid assumption), for comparison
  Eigen::VectorXd column_scale;     ///< the 2-norm of each column (0 for an all-zero column)
  Eigen::VectorXd singular_values;  ///< of the equilibrated matrix, descending
  Eigen::MatrixXd V;                ///< its right singular vectors (columns), scaled coords
  int rank = 0;
  double condition_number = 0;               ///< sigma_max / sigma_min of the equilibrated matrix
                                             ///< (inf when rank-deficient)
  double condition_number_identifiable = 0;  ///< sigma_max / sigma_rank (retained subspace)
  ResidualStats residual;
  Eigen::VectorXd residuals;

  /// Null-space basis in parameter coordinates (unit-norm columns, scaled metric mapped
  /// back: direction d of beta such that X d ~ 0).
  Eigen::MatrixXd nullDirections() const;
  /// True when w'beta does not depend on the undetermined directions (relative tolerance).
  bool isEstimable(const Eigen::VectorXd& w, double tol = 1e-6) const;
  double estimate(const Eigen::VectorXd& w) const { return w.dot(beta); }
  double standardError(const Eigen::VectorXd& w) const;
  double standardErrorNaive(const Eigen::VectorXd& w) const;
  /// Sets singular_values, V, rank (singular values above rank_tol * sigma_max) and the two
  /// condition numbers from an SVD of the equilibrated design (or of its R factor).
  template <class Svd>
  void setSpectrum(const Svd& svd, double rank_tol);
  /// Sets cov (the HAC sandwich n/(n-r) P S P with P = (X_s'X_s)^+ = V_r diag(s_r^-2) V_r' on
  /// the retained subspace, S the Newey-West sum of the scores), cov_naive (sigma^2 P, sigma^2
  /// = rss / (n - r)), both mapped back by diag(inv_scale), and residual.n_effective.
  void setCovariances(const Eigen::MatrixXd& Vr, const Eigen::VectorXd& sr,
                      const Eigen::MatrixXd& S_hac, double rss, long n,
                      const Eigen::VectorXd& inv_scale);
};

template <class Svd>
void LsSolution::setSpectrum(const Svd& svd, double rank_tol) {
  singular_values = svd.singularValues();
  V = svd.matrixV();
  const long p = singular_values.size();
  const double smax = singular_values(0), smin = singular_values(p - 1);
  rank = 0;
  for (long k = 0; k < p; ++k)
    if (singular_values(k) > rank_tol * smax) ++rank;
  const double inf = std::numeric_limits<double>::infinity();
  condition_number = smin > 0 ? smax / smin : inf;
  condition_number_identifiable = rank > 0 ? smax / singular_values(rank - 1) : inf;
}

/// Householder QR of the equilibrated [X D^-1, y] (D^-1 = diag(inv_scale)) fed block of rows by
/// block (TSQR: the triangle of the rows so far is stacked on the next block and factorised
/// again). triangle() is the (p + 1) x (p + 1) upper triangle [R c; 0 rho] with X D^-1 = Q R,
/// Q'y = c and rho^2 the residual sum of squares. Memory: (block + p + 1) x (p + 1) doubles.
class TsqrAccumulator {
 public:
  explicit TsqrAccumulator(const Eigen::VectorXd& inv_scale)
      : inv_scale_(inv_scale), R_(0, inv_scale.size() + 1) {}
  void add(const Eigen::Ref<const Eigen::MatrixXd>& X, const Eigen::Ref<const Eigen::VectorXd>& y);
  Eigen::MatrixXd triangle() const;

 private:
  Eigen::VectorXd inv_scale_;
  Eigen::MatrixXd R_, W_;
};

LsSolution solveLeastSquares(const LsInput& in, const LsOptions& opt = {});
/// The same, consuming `in.X` (equilibrated in place instead of copied: the design of a long
/// drive is ~25 MB per recorded hour and column; same numbers).
LsSolution solveLeastSquares(LsInput&& in, const LsOptions& opt = {});

/// Newey-West S matrix of per-time-step scores (helper, exposed for tests).
Eigen::MatrixXd hacScoreCovariance(const Eigen::MatrixXd& X, const Eigen::VectorXd& e,
                                   const std::vector<long>& time_index,
                                   const std::vector<int>& block, int lags);

/// Half-open index ranges [begin, end) of contiguous series in a stacked vector.
using Groups = std::vector<std::pair<int, int>>;

/// One group covering all n samples.
Groups singleGroup(int n);

struct LinearFit {
  Eigen::VectorXd beta;
  Eigen::MatrixXd cov;  ///< Newey-West (Bartlett) sandwich covariance of beta
  Eigen::VectorXd residual;
  double rss = 0;
  int rank = 0;
  bool ok = false;  ///< false when the design is rank deficient (beta = 0, residual = y)
};

/// Full-rank least squares y ~ X beta with the Newey-West covariance of solveLeastSquares()
/// (each group one block of consecutive time steps, one row per step; rows outside every group
/// are independent), Bartlett bandwidth `lags`, rank tolerance 1e-10 (relative, equilibrated
/// columns). Not ok (and beta = 0) when the design is rank deficient or has no more rows than
/// columns.
/// Made block of rows by block, never copying the n x p design (memory, docs/benchmarks.md):
/// the equilibrated [X D^-1, y] is reduced by a blocked Householder QR (TSQR) to its
/// (p + 1) x (p + 1) triangle [R c; 0 rho]; the SVD of R gives the singular values and V of
/// X D^-1 (X D^-1 = Q R, R = U S V'), beta = D^-1 V S^-1 U'c; the HAC scores are summed block
/// by block with the `lags` scores before each block kept. Extra memory: the residual (n) and
/// a few (2048 + p) x p work matrices. Equal to the unblocked SVD solution up to rounding
/// (relative ~1e-12 on beta and cov; tests/stats).
LinearFit fitLinear(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, const Groups& groups,
                    int lags);
/// The same on a design the caller no longer needs (a temporary): freed when the fit returns.
LinearFit fitLinear(Eigen::MatrixXd&& X, const Eigen::VectorXd& y, const Groups& groups, int lags);

/// Rows per block of a design made block by block (fitLinear(DesignRows, ...) asks for blocks
/// of at most this many rows; the diagnosis makes its library designs in the same blocks).
constexpr long kDesignBlockRows = 2048;

/// Fills `out` with rows [r0, r0 + nb) of an n x p design (nb <= kDesignBlockRows; `out` is resized
/// by the callee), the same rows on every call.
using DesignRows = std::function<void(long r0, long nb, Eigen::MatrixXd& out)>;
/// The same fit on a design that is never stored: made block of rows by block by `rows` (p
/// columns, n = y.size() rows; each block asked for several times: column norms, QR, residual,
/// HAC scores). Equal to fitLinear(X, ...) on the same rows up to rounding (the column norms
/// are summed by blocks). Memory: the residual and a few 2048 x p blocks. E.g. a 1.26 M-row,
/// 14-column library fit needs ~0.5 MB instead of its 141 MB design:
///   fitLinear([&](long r0, long nb, Eigen::MatrixXd& B) { B = X.middleRows(r0, nb); }, p, y, g,
///   5);
LinearFit fitLinear(const DesignRows& rows, long p, const Eigen::VectorXd& y, const Groups& groups,
                    int lags);

}  // namespace wheelchair::stats
