// Generic continuous-discrete extended Kalman filter (Lewis, Xie & Popa 2008, section 5.3.3):
// a continuous-time process model with discrete, asynchronous measurements.
//
//   between measurements:  xdot = f(x, u(t)),   Pdot = F P + P F' + Q      (F = df/dx)
//   at a measurement z:    y = z - h(x),  S = H P H' + R,  K = P H' S^-1,
//                          x += K y,  P = (I - K H) P (I - K H)' + K R K'   (Joseph form)
//
// Q is the continuous-time process-noise spectral density (units of x^2 per second). The
// state and the Riccati ODE are integrated TOGETHER by SUNDIALS CVODE 6.4 (the covariance as
// its packed lower triangle, so it stays exactly symmetric). One CVODE memory is created once.
// Every propagate() integrates to t1 with CVodeSetStopTime(t1), so CVODE never steps past it
// and u(t) is only evaluated on [time(), t1]. The integration is RE-INITIALISED (CVodeReInit:
// back to order 1 and a new initial step) only when it has to be: when the state or the
// covariance changed since the previous propagate() (a measurement update, setState, ...) or
// when the caller says that u(t) is not continuous with the previous interval. Otherwise CVODE
// simply continues (same step size, order and history), which is exact continuation of one
// integration (docs/estimation.md, "CVODE settings").
//
// Default method Adams-Moulton with fixed-point (functional) iteration: the system is not
// stiff (time constants of seconds, intervals of milliseconds), so no Jacobian of the
// augmented (x, P) system is needed. BDF + dense Newton (finite-difference Jacobian) is
// available for stiff models.
//
// Performance: the right-hand side is allocation-free (work space sized once, F used row-sparse
// in F P), and the CVODE vectors use optimised element-wise kernels of this file instead of the
// distribution's (unoptimised) serial N_Vector kernels (docs/benchmarks.md).
//
// The caller computes innovations (so that it can wrap angles) and decides what the gate
// is; update() returns the NIS and whether the measurement passed the gate. A rejected
// measurement leaves the state untouched.
//
// Example:
//   struct Lin : CdModel { ... };            // f, F, Q
//   CdEkf ekf(model, CvodeOptions{});
//   ekf.reset(0.0, x0, P0);
//   ekf.propagate(0.1, [](double t) { return Eigen::VectorXd::Zero(1); });
//   auto r = ekf.update(z - H * ekf.x(), H, R, chi2Quantile(0.999, 1));
#pragma once

#include <Eigen/Core>

#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace wheelchair::estimation {

struct Measurement;  // estimation/Measurement.h

/// A continuous-time process model xdot = f(x, u) with Jacobian and noise density.
class CdModel {
 public:
  virtual ~CdModel() = default;
  virtual int stateDim() const = 0;
  /// xdot = f(x, u).
  virtual void f(const Eigen::VectorXd& x, const Eigen::VectorXd& u,
                 Eigen::VectorXd& xdot) const = 0;
  /// F = df/dx (stateDim x stateDim).
  virtual void F(const Eigen::VectorXd& x, const Eigen::VectorXd& u, Eigen::MatrixXd& F) const = 0;
  /// f and F in one call (what every right-hand side evaluation needs); override when the
  /// two share work (e.g. trigonometry).
  virtual void fAndF(const Eigen::VectorXd& x, const Eigen::VectorXd& u, Eigen::VectorXd& xdot,
                     Eigen::MatrixXd& Fx) const {
    f(x, u, xdot);
    F(x, u, Fx);
  }
  /// Q: continuous-time process-noise spectral density (stateDim x stateDim, symmetric PSD).
  virtual void Q(const Eigen::VectorXd& x, const Eigen::VectorXd& u, Eigen::MatrixXd& Q) const = 0;
  /// True when Q depends on neither x nor u: CdEkf then evaluates it once.
  virtual bool constantQ() const { return false; }
  /// A constant Q but for one diagonal entry Q(i, i), i = varyingQIndex() (-1: none): CdEkf
  /// evaluates Q once and rewrites only that entry with varyingQ() at each right-hand side.
  virtual int varyingQIndex() const { return -1; }
  /// Q(i, i), i = varyingQIndex(), at (x, u).
  virtual double varyingQ(const Eigen::VectorXd& /*x*/, const Eigen::VectorXd& /*u*/) const {
    return 0.0;
  }
};

/// u(t) over one propagation interval.
using InputFunction = std::function<Eigen::VectorXd(double t_s)>;

/// u(t) for the allocation-free propagation path (evaluated at every right-hand side call).
class CdInput {
 public:
  virtual ~CdInput() = default;
  /// Writes u(t_s) into u (assign a fixed-size vector: no allocation once u has its size).
  virtual void eval(double t_s, Eigen::VectorXd& u) const = 0;
};

/// CVODE settings (the [estimator] keys cvode_*).
struct CvodeOptions {
  enum class Method { Adams, Bdf };
  Method method = Method::Adams;  ///< Adams + fixed-point iteration, or BDF + dense Newton
  double rel_tol = 1e-4;          ///< relative tolerance (-)
  double abs_tol_state = 1e-5;    ///< absolute tolerance on the state (state units)
  double abs_tol_cov = 1e-9;      ///< absolute tolerance on covariance entries (state units^2)
  /// Safety factor of the nonlinear (corrector) convergence test (-): CVODE's default is 0.1;
  /// the local error test still bounds the step, so a looser corrector only saves
  /// f-evaluations (docs/estimation.md, "CVODE settings").
  double nonlin_conv_coef = 0.5;
  /// Initial step after a restart: true = the previous restart's first step, grown by 10 %
  /// after an interval without error-test failure and halved after one with failures;
  /// false = CVODE's own estimate (CVHin) at every restart (docs/estimation.md).
  bool adaptive_initial_step = true;
  long max_num_steps = 50000;  ///< per interval
  double max_step_s = 0.0;     ///< 0: no limit
  int max_order = 0;           ///< 0: CVODE's default (12 Adams, 5 BDF)
  /// Re-initialise CVODE at every sample of a linearly interpolated input (its kinks), as
  /// before; false: integrate through the kinks under error control (docs/estimation.md).
  bool restart_at_input_samples = false;
};

/// Result of one measurement update.
struct UpdateResult {
  bool accepted = false;
  double nis = 0;  ///< y' S^-1 y
  int dof = 0;     ///< measurement dimension
  Eigen::VectorXd innovation;
  Eigen::MatrixXd S;
};

/// Counters of the integrator, summed over all intervals.
struct CvodeStats {
  long intervals = 0;
  long steps = 0;
  long rhs_evals = 0;
  long short_intervals = 0;  ///< intervals too short for CVODE, done by one Euler step
  long restarts = 0;         ///< intervals that started with CVodeInit / CVodeReInit
  long error_test_fails = 0;
  long nonlin_iters = 0;
};

class CdEkf {
 public:
  /// The model must outlive the filter.
  CdEkf(const CdModel& model, const CvodeOptions& options);
  ~CdEkf();
  CdEkf(const CdEkf&) = delete;
  CdEkf& operator=(const CdEkf&) = delete;

  void reset(double t0_s, const Eigen::VectorXd& x0, const Eigen::MatrixXd& P0);

  /// Integrates state and covariance from time() to t1_s (t1_s >= time()) with input u(t).
  /// The integration is always re-initialised at time() (u may jump there).
  /// Throws std::runtime_error when CVODE fails (what(): CVODE's reason and the interval).
  /// Times are the caller's clock (e.g. UNIX time): internally CVODE integrates in time
  /// relative to the reset() time, so the result does not depend on the clock offset.
  void propagate(double t1_s, const InputFunction& u);
  /// The same with an allocation-free input. `continuous`: u(t) is the continuation of the
  /// input of the previous propagate() (same function, no jump at time()); then, if the state
  /// and covariance were not changed in between, CVODE continues without re-initialisation.
  /// `u` is only used during the call.
  void propagate(double t1_s, const CdInput& u, bool continuous);

  /// Measurement update with innovation y = z - h(x), Jacobian H, noise R. The measurement
  /// is applied only if NIS <= gate (gate <= 0: no gating).
  UpdateResult update(const Eigen::VectorXd& innovation, const Eigen::MatrixXd& H,
                      const Eigen::MatrixXd& R, double gate);

  /// The library's one update path (estimation/Measurement.h correct()): innovation z - h with
  /// the angular rows wrapped, gate, Joseph form with the non-positive-definite guard.
  UpdateResult correct(Measurement& m, double gate);

  /// NIS of a would-be update, without changing anything.
  double nis(const Eigen::VectorXd& innovation, const Eigen::MatrixXd& H,
             const Eigen::MatrixXd& R) const;

  double time() const { return t_; }
  const Eigen::VectorXd& x() const { return x_; }
  const Eigen::MatrixXd& P() const { return P_; }
  /// Direct access (angle wrapping, resets of augmented states); P is re-symmetrised.
  void setState(const Eigen::VectorXd& x) { x_ = x; }
  /// Zeroes rows and columns [i, i + count) of P (exactly symmetric, no reallocation).
  void zeroCovarianceRowsCols(int i, int count);
  /// Declares the last `count` states held (0: none): the model guarantees that their rates,
  /// their rows of F and their rows and columns of Q are zero. While their rows and columns of
  /// P are also exactly zero (e.g. sensor-error states closed at their prior mean), propagate()
  /// integrates only the leading n - count states and their covariance (a second CVODE set-up
  /// of that size, made on first use): the same equations, since the held rows of
  /// F P + P F' + Q stay zero; the held means stay constant. Example: the 12-state wheelchair
  /// filter with all sensor-error groups closed integrates 9 + 45 = 54 components, not 90.
  ///
  /// `consider` = true: the held states do not enter f either (their COLUMNS of F are zero
  /// too; e.g. sensor errors that act only on measurements), so their covariance may be
  /// non-zero while held (Schmidt "consider" states, or states whose random walk the caller
  /// adds at its updates). Split P = [[P_xx, P_xc], [P_cx, P_cc]] (x: leading m = n - count
  /// states, c: the held tail). With F = [[F_xx, 0], [0, 0]] and Q_xc = Q_cc = 0 the Riccati
  /// equation decouples exactly:
  ///   dP_xx/dt = F_xx P_xx + P_xx F_xx' + Q_xx   (CVODE, as without the tail)
  ///   dP_xc/dt = F_xx P_xc                       (P_xc(t1) = Phi(t1, t0) P_xc(t0))
  ///   dP_cc/dt = 0
  /// so propagate() always integrates only the leading states with CVODE and carries the
  /// cross-covariance with the transition matrix of the linearised leading dynamics,
  /// Phi ~ exp(dt (F_xx(t0) + F_xx(t1)) / 2) (second-order Magnus / trapezoid: exact for a
  /// constant F, local error O(dt^3) otherwise; the exponential to 4th order), F evaluated at
  /// the interval's end states. Cost: two F evaluations and four m x m by m x count products
  /// per interval, only while P_xc != 0. Example: the 12-state wheelchair filter with its
  /// closed sensor-error states held at their prior variance: 54 CVODE components + 27 cross
  /// terms, not 90 (docs/estimation.md, "Closed states as consider states").
  void setHeldTail(int count, bool consider = false);
  void setCovariance(const Eigen::MatrixXd& P);
  const CvodeStats& stats() const { return stats_; }
  const CvodeOptions& options() const { return opt_; }

 private:
  struct Cvode;
  friend struct CdEkfAccess;
  /// Right-hand side at CVODE's time tau = t - t_ref_ (s).
  void evalRhs(double tau, const double* y, double* ydot);
  /// (x, P) of the leading m states packed as (x, lower triangle of P column-major).
  void pack(double* y, int m) const;
  void unpack(const double* y, int m);
  void integrate(double t1_s, const CdInput& u, bool continuous);
  /// A CVODE set-up for the leading m states (vectors, tolerances, memory).
  std::unique_ptr<Cvode> newCvode(int m) const;
  /// CVodeInit and the solver set-up of the first integration, at CVODE time tau0 (s).
  void initCvode(Cvode& cv, double tau0);
  void countSteps(Cvode& cv, double dt, double scale);
  /// The held tail is declared and its rows and columns of P are exactly zero.
  bool heldTailIsZero() const;
  /// P_xc <- Phi P_xc over [t0, t1] for a consider tail (setHeldTail), from F at the state
  /// before (fx0, u0) and after (x_, u at t1) the interval.
  void propagateConsiderCross(double dt, double t1_s, const Eigen::MatrixXd& F0);

  const CdModel& model_;
  CvodeOptions opt_;
  int n_ = 0;
  double t_ = 0;      ///< current time (s, the caller's clock, e.g. UNIX time)
  double t_ref_ = 0;  ///< reset time: CVODE integrates in t - t_ref_ (s)
  Eigen::VectorXd x_;
  Eigen::MatrixXd P_;
  const CdInput* u_ = nullptr;
  // Work space of the right-hand side (sized once).
  Eigen::VectorXd wx_, wu_, wxd_;
  Eigen::MatrixXd wP_, wF_, wQ_, wFP_;
  std::vector<double> ys_, yds_;     // packed scratch
  std::vector<double> qPacked_;      // packed (Q + Q') / 2 when the model's Q is constant
  std::vector<double> qPackedHeld_;  // the same for the leading n - held_tail_ states
  int held_tail_ = 0;                // states held constant while their P rows are zero
  bool consider_tail_ = false;       // ... or always, their cross-covariance carried by Phi
  Eigen::MatrixXd wF0_, wM_;         // consider tail: F(t0), Magnus exponent
  // Consider tail after a restart: wF0_ is taken from CVODE's first right-hand side, which is
  // evaluated at (tau, y) = (capture_tau_, the packed state at t0), instead of a separate F.
  bool capture_F0_ = false;
  double capture_tau_ = 0;         // (s, CVODE's time)
  int m_ = 0;                      // states integrated in the current interval
  std::unique_ptr<Cvode> cv_;      // all n states
  std::unique_ptr<Cvode> cvHeld_;  // the leading n - held_tail_ (made on first use)
  Cvode* act_ = nullptr;           // the set-up of the current interval
  CvodeStats stats_;
};

/// Joseph-form measurement update of (x, P) with innovation y, gated at NIS <= gate (gate <= 0:
/// always applied). Used by CdEkf::update and by the discrete baseline filter. When
/// S = H P H' + R is not positive definite the measurement is rejected (nis = inf,
/// accepted = false) and (x, P) are left unchanged. For m <= 2 and n <= 16 (every sensor of
/// the chair) S is inverted in closed form with stack work space; otherwise
/// josephUpdateLdlt is used.
UpdateResult josephUpdate(Eigen::VectorXd& x, Eigen::MatrixXd& P, const Eigen::VectorXd& y,
                          const Eigen::MatrixXd& H, const Eigen::MatrixXd& R, double gate);

/// The same update for any dimension, through an LDLT factorisation of S (the reference the
/// closed-form path is tested against).
UpdateResult josephUpdateLdlt(Eigen::VectorXd& x, Eigen::MatrixXd& P, const Eigen::VectorXd& y,
                              const Eigen::MatrixXd& H, const Eigen::MatrixXd& R, double gate);

/// Packed lower triangle (column-major) size of an n x n symmetric matrix.
inline int packedSize(int n) {
  return n * (n + 1) / 2;
}

}  // namespace wheelchair::estimation
