// solveLeastSquares (LeastSquares.h) on rows that are never all in memory (issue 13, memory):
// the caller produces the rows block by block, as often as asked, and the solution is made in
// three passes over them:
//
//   1. the column 2-norms (the equilibration D) and n;
//   2. a Householder QR of the equilibrated [X D^-1, y], block of rows by block (TSQR, as
//      fitLinear): [R c; 0 rho], X D^-1 = Q R, c = Q'y. The SVD of the p x p triangle R gives
//      the singular values and right singular vectors V of X D^-1 (R = U S V'), so
//      beta_s = V_r S_r^-1 U_r' c on the retained subspace (rank_tol as solveLeastSquares);
//   3. the residuals e = y - X D^-1 beta_s: their statistics, the Newey-West sums of the
//      per-time-step scores g_t = sum over the rows of step t of (X D^-1)_r' e_r (lags within a
//      block, steps without rows count as zeros: exactly hacScoreCovariance's series) and the
//      lag-1 autocorrelation of the per-step residual sums.
//
// The same LsSolution as solveLeastSquares up to rounding (another summation order; the
// singular values that are zero in exact arithmetic are rounding noise in both, ~1e-16 of the
// largest, and differ), except `residuals`, which is left empty. Memory: a few (block + p) x p
// matrices and the (L + 2048) x p window of scores, whatever n (L = hac_lags).
//
// Rows must come grouped by block (all rows of a block consecutive) with non-decreasing
// time_index within a block, in the same order on every pass (std::invalid_argument otherwise).
//
// Example:
//   LsRowSource rows = [&](const LsBlockVisitor& visit) {
//     for (each block of rows) visit(Xb, yb, time_index_b, block_b);
//   };
//   LsSolution s = solveLeastSquaresBlocked(rows, 5, LsOptions{.hac_lags = 200});
#pragma once

#include "libwheelchair/stats/LeastSquares.h"

#include <functional>
#include <vector>

namespace wheelchair::stats {

/// Receives one block of rows: X (rows x p), y, and per row the time step and block id.
using LsBlockVisitor =
    std::function<void(const Eigen::MatrixXd& X, const Eigen::VectorXd& y,
                       const std::vector<long>& time_index, const std::vector<int>& block)>;
/// Calls the visitor on consecutive blocks of all rows, in the same order on every call.
using LsRowSource = std::function<void(const LsBlockVisitor&)>;

/// solveLeastSquares over rows produced by `rows` (three passes, see the header comment); p
/// columns. Throws std::invalid_argument on fewer rows than columns or misordered rows.
LsSolution solveLeastSquaresBlocked(const LsRowSource& rows, int p, const LsOptions& opt = {});

}  // namespace wheelchair::stats
