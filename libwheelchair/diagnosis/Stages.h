// Internals of the diagnosis (exposed for the tests and the campaign): the per-recording
// streams, the stage 1 (kinematic) and stage 2 (dynamic) residual rows with the columns of
// every catalogue term, and the forward selection engine. See Diagnosis.h for the overview.
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/effects/Effect.h"
#include "libwheelchair/io/Recording.h"
#include "libwheelchair/stats/Selection.h"
#include "libwheelchair/stats/Statistics.h"

#include <Eigen/Core>

#include <functional>
#include <string>
#include <vector>

namespace wheelchair::diagnosis {

struct DiagnosisOptions;

/// One recording's streams, sorted by time, duplicates dropped, ticks unwrapped and turned
/// into rim distances (m, not yet scale-corrected).
struct Streams {
  std::vector<double> te, sR, sL;  ///< encoder times and cumulative rim distances
  std::vector<double> tg, gz;      ///< gyro z
  std::vector<double> tm, iR, iL;  ///< motor currents
  std::vector<io::PozyxSample> pozyx;
  std::vector<io::GroundTruthPoseSample> gt;
  double t_begin = 0, t_end = 0;
  bool hasEncoders() const { return te.size() >= 3; }
  bool hasGyro() const { return tg.size() >= 3; }
  bool hasMotors() const { return tm.size() >= 3; }
};

Streams makeStreams(const io::Recording& rec, const config::WheelchairConfig& cfg);

/// What makeStreams reads of a recording's IMU and motor samples, as columns in stored order
/// (16 and 24 B a sample instead of the recording's 64 and 40: a rawlog read as a stream,
/// diagnosis/RawlogInput.h), and the recording's first and last time over all its streams
/// (io::Recording::startTime / endTime, e.g. io::RecordingSummary::start_s / end_s).
struct StreamColumns {
  std::vector<double> tg, gz;      ///< gyro z (s, rad/s)
  std::vector<double> tm, iR, iL;  ///< motor currents (s, A)
  double start_s = 0, end_s = 0;
};
/// makeStreams of a recording whose IMU and motor samples are `cols` (rec.imu and rec.motors
/// are not read): the same streams, sample for sample; the columns become the streams (no
/// copy when they are in time order).
Streams makeStreams(const io::Recording& rec, StreamColumns&& cols,
                    const config::WheelchairConfig& cfg);

/// Samples with t in [a, b] of every stream.
Streams cropStreams(const Streams& s, double a, double b);
/// cropStreams(s, a, b) for each range [a, b] of `ranges`, consuming `s`: each column of s is
/// released once its crops are made, so the crops and s are never both held whole (memory).
std::vector<Streams> cropStreams(Streams&& s, const std::vector<std::pair<double, double>>& ranges);
/// The parts (each sorted by time, in time order, e.g. adjacent crops of one recording's
/// streams) as one: of each stream, a part's samples later than every sample taken so far, so
/// a sample two parts share (a crop boundary) is taken once. Without `with_motors` the motor
/// currents are left out. t_begin, t_end: the first part's, the last part's.
/// E.g. joinStreams({&crop(s, a, c), &crop(s, c, b)}, true) == crop(s, a, b).
Streams joinStreams(const std::vector<const Streams*>& parts, bool with_motors);
/// joinStreams of the parts, consuming them: each column of the parts is released once it is
/// joined, so the parts and the result are never both held whole (memory).
Streams joinStreams(std::vector<Streams>&& parts, bool with_motors);

/// Sensor corrections applied before building rows (identity by default).
struct Corrections {
  double enc_scale[2] = {1, 1};  ///< reported / true distance, right, left
  double gyro_scale = 1, gyro_bias = 0;
  double delay_imu = 0, delay_enc = 0, delay_motors = 0;  ///< stamps lag truth by this (s)

  bool operator==(const Corrections& o) const {
    return enc_scale[0] == o.enc_scale[0] && enc_scale[1] == o.enc_scale[1] &&
           gyro_scale == o.gyro_scale && gyro_bias == o.gyro_bias && delay_imu == o.delay_imu &&
           delay_enc == o.delay_enc && delay_motors == o.delay_motors;
  }
};

/// The regression columns of the stages: every effect's kinematicColumns() / driveColumns(), in
/// registry order (effects/Effect.h).
const std::vector<effects::KinematicColumn>& kinematicColumns();
const std::vector<effects::DriveColumn>& driveColumns();
/// Index of a column of a stage by name; throws std::logic_error when there is none.
int columnIndex(effects::Stage stage, const std::string& name);

/// Stage 1 rows: one per window of encoder samples, y = gyro integral - odometric heading
/// change (rad). Columns: kinematicColumns() (gyro_bias T, gyro_scale (dR - dL)/l_w,
/// encoder_scale/right dR/l_w, encoder_scale/left -dL/l_w, sensor_delay/imu
/// -(omega(t1) - omega(t0))).
struct KinRows {
  Eigen::VectorXd y;
  Eigen::MatrixXd X;
  std::vector<double> t0, t1, v, omega, phi;
  stats::Groups groups;
  double noise_var_per_s = 0;  ///< predicted variance of y: gyro white noise part (per second)
  double noise_var_const = 0;  ///< ... tick quantisation part (per window)
};
KinRows kinematicRows(const std::vector<Streams>& recs, const Corrections& c,
                      const config::WheelchairConfig& cfg, const DiagnosisOptions& opt);

/// A stage's catalogue design X (rows() x cols(): the stage's columns, kinematicColumns() or
/// driveColumns()), stored or made block of rows by block (DynRows::design(): the stage 2
/// design is not stored; memory, docs/benchmarks.md). A view: the matrix or the rows it makes
/// its blocks from must outlive it. Implicit from a stored matrix, e.g.
///   CatalogueDesign X = k.X;                      // a view of KinRows' stored design
///   Eigen::MatrixXd b; X.block(0, 100, b);        // b = k.X.topRows(100)
class CatalogueDesign {
 public:
  /// Fills `out` with rows [r0, r0 + nb) of the design (nb <= stats::kDesignBlockRows).
  using Block = std::function<void(long r0, long nb, Eigen::MatrixXd& out)>;
  CatalogueDesign(const Eigen::MatrixXd& X)  // NOLINT: implicit, a view of a stored design
      : rows_(X.rows()), cols_(X.cols()), X_(&X) {}
  CatalogueDesign(long rows, long cols, Block block)
      : rows_(rows), cols_(cols), block_(std::move(block)) {}
  long rows() const { return rows_; }
  long cols() const { return cols_; }
  /// Rows [r0, r0 + nb) into `out` (nb x cols()).
  void block(long r0, long nb, Eigen::MatrixXd& out) const;
  /// Rows [r0, r0 + nb) times S (cols() x k) into `out` (nb x k): X.middleRows(r0, nb) * S.
  void blockTimes(long r0, long nb, const Eigen::MatrixXd& S, Eigen::MatrixXd& out) const;
  /// X * S (rows() x k), made block by block.
  Eigen::MatrixXd times(const Eigen::MatrixXd& S) const;
  /// The whole design (rows() x cols(); for small row sets only).
  Eigen::MatrixXd matrix() const { return times(Eigen::MatrixXd::Identity(cols_, cols_)); }

 private:
  long rows_ = 0, cols_ = 0;
  const Eigen::MatrixXd* X_ = nullptr;
  Block block_;
};

/// Stage 2 rows: per grid sample the right and then the left motor equation error (A),
/// y = filtered current - nominal model current. Columns: driveColumns() (asymmetry right/left,
/// Coulomb right/left, payload per kg, slope cos/sin, motors delay), not stored (64 B a row;
/// memory, docs/benchmarks.md): design() makes them block by block from the row's signals
/// (effects::DriveColumn::value of the row's effects::DriveSample).
/// The unmodeled-term library (names in dynLibNames()) is not stored as a matrix either (16
/// doubles a row): libColumn() makes a column from the per-row signals.
struct DynRows {
  Eigen::VectorXd y;
  /// What both motors' rows of a grid sample share, stored once per grid sample (memory,
  /// docs/benchmarks.md): row k (right rows 0..nR-1, then left rows nR..2 nR-1) is grid sample
  /// step(k). Time (s), v (m/s), omega (rad/s), their derivatives, heading phi (rad) and its
  /// filtered cos/sin. E.g. the time of row k: grid.t[step(k)].
  struct Grid {
    std::vector<double> t, v, omega, vdot, omegadot, phi, cos_phi, sin_phi;
  } grid;
  /// Per row, the rest of the library: the motor's rim speed u (m/s), its smoothed sign
  /// sgn(u) and the motor's filtered current (A).
  std::vector<double> u, sgn_u, current;
  /// Per row, the time derivative of the motor's nominal model current (A/s; the delay
  /// column's signal).
  std::vector<double> dcurrent_model;
  /// The constants of the drive columns (effects::DriveSample): motor viscous friction per
  /// torque constant theta5 (A s/rad), 1 / (gearbox efficiency x torque constant) (A/(N m)),
  /// wheel radius r (m), gear ratio, half the weight on the drive wheels Mg/2 (N).
  double theta5 = 0, alpha = 0, wheel_radius_m = 0, gear_ratio = 0, half_weight_N = 0;
  stats::Groups groups;
  /// Grid sample of row k (k < nR: the right motor's row; else the left motor's).
  int step(int k) const {
    const int nR = static_cast<int>(y.size() / 2);
    return k < nR ? k : k - nR;
  }
  /// Motor of row k: 0 right, 1 left.
  int side(int k) const { return k < static_cast<int>(y.size() / 2) ? 0 : 1; }
  double noise_var = 0;  ///< predicted variance of y from the current-sensor noise
  /// Per grid sample: castorSwivelMoment of the filtered v, omega (library term
  /// "castor_swivel").
  std::vector<double> castor;
  /// Library column j over rows [r0, r0 + n): 1, v, omega, vdot, omegadot, sgn(u), |u|, u^2,
  /// v*omega, omega^2, cos(phi), sin(phi), i_self, i_other (the other motor's current),
  /// v*|v| (a drag's signed square), sgn(omega) = tanh(omega / 0.02 rad/s) (a dry
  /// moment's sign; from the filtered rate) and castor_swivel (castorSwivelMoment).
  Eigen::VectorXd libColumn(int j, int r0, int n) const;
  /// Rows [r0, r0 + nb) of the catalogue design (nb x driveColumns().size()).
  void designBlock(long r0, long nb, Eigen::MatrixXd& out) const;
  /// The catalogue design, made block by block (a view of these rows: they must outlive it).
  CatalogueDesign design() const;
};

/// Where the castors swivel (options of the library term "castor_swivel"): swivel axes at
/// (x_m, +-half_spacing_m) in the body frame (x forward, y left, origin the axle midpoint),
/// relaxation_m the distance a castor rolls while it turns round (its trail, lengthened by
/// tyre compliance and swivel friction).
struct CastorGeometry {
  double x_m = 0.45, half_spacing_m = 0.22, relaxation_m = 0.08;
};
/// The yaw moment per unit of swivel friction of two trailing castors (issue 16 item 3: the
/// castors turning round at the start of a turn or a reversal), N m per N m. Each castor's
/// swivel angle b (rad, relative to the body x axis; 0 = trailing a forward motion) follows an
/// ideal trailing castor of relaxation length d = relaxation_m, driven by its axis' velocity
/// (vx, vy) = (v - omega y_i, omega x):
///   db/dt = (vy cos b - vx sin b) / d - omega        (b = 0 at the first sample)
/// and dry swivel friction M_s opposing db/dt loads the body, through the lateral force at the
/// wheel (M_s / d) and the bearing's reaction, with a yaw moment
///   M = -M_s sum_i tanh((db_i/dt) / 0.3 rad/s) ((x cos b_i + y_i sin b_i) / d - 1).
/// Returned: sum_i tanh(...) (...) (the column; a load opposing the swivel is a positive
/// coefficient). Zero while the castors roll without swivelling (straight lines, steady
/// turns): it is not spanned by omega, omegadot or sgn(omega). t_s, v_m_s, omega_rad_s: one
/// continuous segment's samples. Example: a turn on the spot from rest (v = 0, omega = 0.5
/// rad/s): both castors swivel through ~90 deg in ~0.3 s, the column is ~ +9 each meanwhile,
/// then 0 while the turn goes on.
std::vector<double> castorSwivelMoment(const std::vector<double>& t_s,
                                       const std::vector<double>& v_m_s,
                                       const std::vector<double>& omega_rad_s,
                                       const CastorGeometry& g);
/// The stage 2 rows of the recordings' streams with the corrections c. `copied` (optional):
/// called with the index of each recording once its encoders and motor currents are copied
/// (corrected) and no longer read here, e.g. to set them aside (memory: docs/benchmarks.md,
/// "Tenth round").
DynRows dynamicRows(const std::vector<Streams>& recs, const Corrections& c,
                    const config::WheelchairConfig& cfg, const DiagnosisOptions& opt,
                    const std::function<void(std::size_t)>& copied = {});
const std::vector<std::string>& dynLibNames();

/// A catalogue term: its columns are X * S (S selects/combines base columns).
struct Candidate {
  std::string name;    ///< e.g. "encoder_scale/right"
  std::string effect;  ///< catalogue id
  Eigen::MatrixXd S;
  std::vector<std::string> conflicts;  ///< names that cannot be accepted together with it
  std::function<bool(const Eigen::VectorXd& coef)> plausible;
};

/// The catalogue terms of a stage: every effect's residualTerms() of that stage, in registry
/// order, with S selecting the stage's columns.
std::vector<Candidate> stageCandidates(effects::Stage stage, const effects::TermOptions& o);

struct SelectionStep {
  int candidate = -1;
  stats::Evidence evidence;
  double rss0_fit = 0, rss1_fit = 0, rss0_val = 0, rss1_val = 0;
  double lr_val = 0, lr_val_expected = 0, n_eff_val = 0;
  bool val_tested = false;
  Eigen::VectorXd coef;  ///< this candidate's coefficients at acceptance
};

struct Selection {
  std::vector<int> accepted;
  std::vector<SelectionStep> steps;         ///< one per accepted candidate
  stats::LinearFit fit;                     ///< final joint fit (columns: accepted in order)
  std::vector<std::pair<int, int>> ranges;  ///< coefficient range of each accepted candidate
  std::vector<std::string> log;             ///< why candidates were rejected (last round)
  /// What the drive could not tell apart (for info.cannot_tell): readings of the data none of
  /// which it rejects, and what would have to be driven to tell them apart.
  std::vector<std::string> cannot_tell;
};

/// Views of the caller's rows (no copy of the regression matrices; they must outlive it).
struct SelectionData {
  const Eigen::VectorXd &y_fit, &y_val;
  CatalogueDesign X_fit, X_val;  ///< views (stored, or made block by block)
  const stats::Groups &g_fit, &g_val;
  int lags = 5;
  /// Relevance: the RMS of a term's contribution over the fit rows must reach this (units of
  /// y), i.e. min_relevance x the configured noise of one sensor sample; below it a term is
  /// within the approximation error of the reconstruction and not reported.
  double min_contribution_rms = 0;
};

/// The diagnosis' multiple-testing rule over a catalogue of m terms: alpha, min_bic_drop of
/// the options, Bonferroni level alpha / m (stats/Selection.h).
stats::SelectionRule selectionRule(const DiagnosisOptions& opt, std::size_t m);

/// stats::selectTerms over the candidates with selectionRule(opt, cands.size()).
Selection forwardSelect(const SelectionData& d, const std::vector<Candidate>& cands,
                        const DiagnosisOptions& opt, const std::vector<int>& forced = {});

/// Design of the accepted candidates, in order (made block by block when X is).
Eigen::MatrixXd acceptedDesign(const CatalogueDesign& X, const std::vector<Candidate>& cands,
                               const std::vector<int>& accepted);
/// The same design as X * S: S (X.cols() x k) stacks the accepted candidates' S, in order.
Eigen::MatrixXd acceptedSelector(const CatalogueDesign& X, const std::vector<Candidate>& cands,
                                 const std::vector<int>& accepted);
/// The same design made block of rows by block (never stored; memory, docs/benchmarks.md) for
/// stats::fitLinear(DesignRows, ...). What X views must outlive the result.
stats::DesignRows acceptedRows(const CatalogueDesign& X, const std::vector<Candidate>& cands,
                               const std::vector<int>& accepted);
/// fitLinear(acceptedDesign(X, cands, accepted), y, groups, lags) without the design (same
/// numbers up to rounding: the column norms are summed block by block).
stats::LinearFit fitAccepted(const CatalogueDesign& X, const Eigen::VectorXd& y,
                             const std::vector<Candidate>& cands, const std::vector<int>& accepted,
                             const stats::Groups& groups, int lags);
/// acceptedDesign(X, cands, accepted) * coef, block of rows by block.
Eigen::VectorXd acceptedPrediction(const CatalogueDesign& X, const std::vector<Candidate>& cands,
                                   const std::vector<int>& accepted, const Eigen::VectorXd& coef);

}  // namespace wheelchair::diagnosis
