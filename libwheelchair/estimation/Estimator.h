// The estimators' common interface and the driver that runs one over a recording.
//
// runEstimator() merges every measurement of an io::Recording into ONE time-ordered event
// sequence (each stream sorted by time first; equal timestamps ordered by the fixed stream
// priority encoders < gyro < sonar < Pozyx, then by value), so the result does not depend on
// the order in which samples were stored or arrived. Its rawlog overload does the same merge
// while reading the file as a stream, in a window of the file's measured lateness
// (io/RawlogStream.h), with bit-identical results; runEstimatorOnePass reads a time-ordered
// file once, without the scan that measures the lateness. Motor currents are not events: they are
// the input signal u(t) of the physics filter (InputSignal), whose sample times become extra
// integration breakpoints in zero-order-hold mode (u jumps there); piecewise-linear u is
// continuous and is integrated through (docs/estimation.md, "CVODE settings").
//
// Example:
//   auto cfg = config::WheelchairConfig::load("config/wheelchair.ini");
//   EkfOptions opt;  opt.loadFromConfig(cfg.ini());
//   EstimationResult res = runEstimator(recording, cfg, opt);
//   const EstimateSample& last = res.final();
//   double nis = res.stats(Sensor::Gyro).meanNis();
#pragma once

#include "libwheelchair/estimation/CdEkf.h"
#include "libwheelchair/estimation/EkfOptions.h"
#include "libwheelchair/estimation/EstimationTypes.h"
#include "libwheelchair/estimation/Measurement.h"
#include "libwheelchair/io/RawlogStream.h"
#include "libwheelchair/io/Recording.h"
#include "libwheelchair/sensors/Encoders.h"

#include <Eigen/Core>

#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <vector>

namespace wheelchair::config {
class WheelchairConfig;
}

namespace wheelchair::estimation {

/// Motor currents u(t) = (i_R, i_L) from samples: linear interpolation between samples or
/// zero-order hold of the last one; before the first sample its value is held, after the last
/// the last one. No samples: u = 0.
class InputSignal {
 public:
  explicit InputSignal(InputInterpolation mode = InputInterpolation::Linear) : mode_(mode) {}
  /// Replaces the samples (sorted by time here; of equal times the last in sorted order wins).
  void setSamples(std::vector<io::MotorSample> samples);
  /// Adds a sample (streaming use; may arrive out of order).
  void add(const io::MotorSample& s);
  /// u at t (right limit at a sample time in Hold mode).
  Eigen::Vector2d at(double t_s) const;
  /// Forgets samples before the last one at or before t (streaming use: u(t) for times >= t
  /// is unchanged; the memory is released in amortised batches).
  void discardBefore(double t_s);
  /// Sample times strictly inside (t0, t1): where u(t) has a kink or a jump.
  std::vector<double> breakpoints(double t0_s, double t1_s) const;
  /// First sample time strictly after t (+infinity when there is none).
  double nextSampleAfter(double t_s) const;
  /// Whether t is exactly a sample time (u has a kink or a jump there).
  bool isSampleTime(double t_s) const;
  /// u(t) on [t0, t1] when no breakpoint lies inside: exact for both modes.
  InputFunction segment(double t0_s, double t1_s) const;
  bool empty() const { return t_.empty(); }
  InputInterpolation mode() const { return mode_; }

 private:
  InputInterpolation mode_;
  std::vector<double> t_;
  std::vector<Eigen::Vector2d> u_;
  /// Index of the sample interval of the last at() call: CVODE asks for nearby times in
  /// sequence, so the search starts there (one object per filter run; not shared by threads).
  mutable std::size_t hint_ = 0;
};

/// What every filter implements (physics CD-EKF and the kinematic baseline). Calls must come
/// in non-decreasing time; the caller predicts to a measurement's time before passing it.
class Estimator {
 public:
  Estimator(const config::WheelchairConfig& cfg, const EkfOptions& opt);
  virtual ~Estimator() = default;

  /// Initial state at t0 (standstill at the origin of the start frame, obstacle per options).
  virtual void start(double t0_s) = 0;
  /// Propagates the state (no measurement) to t_s >= time().
  virtual void predictTo(double t_s) = 0;
  virtual double time() const = 0;
  /// Current estimate in the canonical layout.
  virtual EstimateSample estimate() const = 0;

  /// Encoder sample that starts the first speed interval (resets the accumulators).
  virtual void encoderStart(double t_s) = 0;
  /// Mean speeds over [iv.t0_s, iv.t1_s] (measurement time iv.t1_s).
  virtual void encoderInterval(const sensors::WheelSpeedInterval& iv) = 0;
  void gyro(double t_s, double gyro_z_rad_s);
  /// Sonar range (m): 0 or outside [min, max] is a dropout; the first valid one initialises the
  /// obstacle (initial_obstacle = first_sonar); repeated gated readings re-initialise it.
  void sonar(double t_s, double range_m);
  /// Pozyx tag position in the anchor frame (m): mapped into the start frame
  /// (pozyx_anchor_*), a measurement of the tag at its lever arm ([pozyx] lever_x_m,
  /// lever_y_m, body frame), gated; after pozyx_inflate_after_rejections consecutive gated
  /// readings the position covariance is inflated until the reading fits (EkfOptions.h).
  void pozyx(double t_s, const Eigen::Vector2d& p_anchor_m);

  /// Whether record() keeps every update attempt in result().nis (default true; counts and
  /// NIS statistics are kept either way).
  void keepNisRecords(bool keep) { keep_nis_records_ = keep; }
  const EstimationResult& result() const { return res_; }
  EstimationResult& result() { return res_; }
  const EkfOptions& options() const { return opt_; }

  /// The filter's own state vector (its layout: WheelchairEkf.h, BaselineEkf.h).
  virtual const Eigen::VectorXd& state() const = 0;
  // The filter's measurement models linearised at a state x of its own layout
  // (estimation/Measurement.h): z, h(x), H = dh/dx, R in the filter's preallocated storage,
  // valid until the next call for that sensor. The updates use them at state(); the tests
  // check each H against central differences of h.
  virtual Measurement& gyroModel(const Eigen::VectorXd& x, double z_rad_s, double R) = 0;
  virtual Measurement& sonarModel(const Eigen::VectorXd& x, double z_m, double R) = 0;
  /// z_start: the tag position in the start frame (m).
  virtual Measurement& pozyxModel(const Eigen::VectorXd& x, const Eigen::Vector2d& z_start,
                                  const Eigen::Matrix2d& R) = 0;

 protected:
  /// The one update path (Measurement.h correct() on the filter's state), then the filter's
  /// angle wrapping. The state is already at the measurement time.
  virtual UpdateResult correct(Measurement& m, double gate) = 0;
  virtual bool obstacleInitialised() const = 0;
  /// Obstacle at `range` along the sonar axis, covariance from the sonar datasheet.
  virtual void initObstacleFromSonar(double range_m) = 0;
  /// Adds var_m2 to the variances of the position (x, y) (the filter found itself drifted).
  virtual void inflatePositionCovariance(double var_m2) = 0;

  /// Books an update attempt: counts, NIS statistics, rejected list.
  void record(Sensor s, double t_s, const UpdateResult& r, double gate);
  /// NIS gate for a dof-dimensional measurement (0: no gating).
  double gate(int dof) const;
  /// Covariance of the encoder mean speeds (v, omega) over an interval of dt seconds:
  /// tick quantisation (difference of two uniform errors, var = 1/6 tick^2 per wheel) plus the
  /// configured per-wheel noise.
  Eigen::Matrix2d encoderNoise(double dt_s) const;
  /// (v, omega) covariance of independent per-wheel rim-speed errors of variance var_u
  /// (m^2/s^2 each): diag(var_u / 2, 2 var_u / l_w^2), v = (uR + uL) / 2, omega = (uR - uL) / l_w.
  Eigen::Matrix2d wheelSpeedNoise(double var_u_m2_s2) const;
  /// Sonar body-frame mount and the obstacle covariance (body frame, Cartesian) of a sonar
  /// reading: along the beam sonar_noise_m, across it range * bearing sigma.
  Eigen::Vector2d sonarPointBody(double range_m) const;
  Eigen::Matrix2d sonarPointCovBody(double range_m) const;
  /// Initial obstacle from the options (body frame, Cartesian) and its covariance.
  Eigen::Vector2d configObstacle() const;
  Eigen::Matrix2d configObstacleCov() const;
  SensorStats& stats(Sensor s) { return res_.sensors[static_cast<int>(s)]; }

  EkfOptions opt_;  ///< sensor defaults resolved
  double wheel_radius_m_, track_width_m_, wheel_rad_per_tick_;
  double sonar_min_m_, sonar_max_m_, sonar_yaw_rad_;
  Eigen::Vector2d sonar_offset_m_, pozyx_lever_m_;
  EstimationResult res_;

 private:
  mutable std::map<int, double> gates_;
  int consecutive_sonar_rejections_ = 0;
  int consecutive_pozyx_rejections_ = 0;
  /// A Pozyx reading has passed the gate: one rejected from the first on is a wrong anchor
  /// frame (pozyx_anchor_*), not a drift, and is never forced in.
  bool pozyx_accepted_ = false;
  bool sonar_failing_ = false;  ///< the last sonar reading was a dropout (episode counting)
  bool keep_nis_records_ = true;
};

/// The filter selected by opt.filter. `input` (motor currents) must outlive it; the baseline
/// ignores it.
std::unique_ptr<Estimator> makeEstimator(const config::WheelchairConfig& cfg, const EkfOptions& opt,
                                         const InputSignal* input);

/// Runs the selected filter over a whole recording (see the header comment). `progress`, when
/// set, is called with the fraction of measurements processed (0..1) about every 1 %.
/// Times may be on any clock (0 or UNIX time; results do not depend on the offset, see
/// docs/estimation.md "Clock offset"). A failure of the filter (e.g. CVODE after a clock jump)
/// throws std::runtime_error naming the stream, the sample index as stored and its time:
/// "IMU sample 2000 (t = 1701000020.007752 s): CVODE failed (CV_TOO_MUCH_WORK) ...".
EstimationResult runEstimator(const io::Recording& rec, const config::WheelchairConfig& cfg,
                              const EkfOptions& opt,
                              const std::function<void(double)>& progress = {});

/// The same run with every estimate passed to `sink` as it is produced instead of stored:
/// the result has counts, statistics, rejections, warnings, n_estimates and the last estimate
/// (final()), but no `estimates` and no per-update `nis` records, so memory does not grow
/// with the drive. The estimates are bit-identical to the stored ones. Example:
///   EstimatesCsvWriter csv("est.csv");               // estimation/EstimateWriters.h
///   auto res = runEstimator(rec, cfg, opt, csv);
///   csv.commit();
EstimationResult runEstimator(const io::Recording& rec, const config::WheelchairConfig& cfg,
                              const EkfOptions& opt, EstimateSink& sink,
                              const std::function<void(double)>& progress = {});

/// The same streamed run over a rawlog read as a stream (io/RawlogStream.h): `summary` is
/// its io::scanRawlog (or scanRawlogSalvaging), the samples are read a second time and merged
/// in a window of summary.lateness_s seconds, the input signal is kept only around the
/// filter's time. Memory does not grow with the drive; results and estimates are
/// bit-identical to runEstimator(io::readRawlog(rawlog), ...) (a damaged file is used up to
/// its break, as with --salvage). Example:
///   const auto sum = io::scanRawlogSalvaging("d.rawlog", salvage, &warning);
///   auto res = runEstimator("d.rawlog", sum, cfg, opt, csv);
EstimationResult runEstimator(const std::string& rawlog, const io::RecordingSummary& summary,
                              const config::WheelchairConfig& cfg, const EkfOptions& opt,
                              EstimateSink& sink, const std::function<void(double)>& progress = {});

/// The same streamed run reading the file ONCE, without the scan: the file is assumed in time
/// order (lateness 0: what import, simulate and capture write) and summarised while it is read
/// (`summary`: io::scanRawlog's result). Results and estimates are those of the two-pass
/// runEstimator above; nullopt when that cannot be guaranteed, after the sink has seen
/// estimates that must then be discarded: a sample out of time order, no motor currents (the
/// merge would hold the whole drive waiting for them), no measurements. Then scan and use
/// the two-pass overload. The caller applies the salvage rule to summary.report.broken
/// afterwards (the samples up to a break are used). Saves one decompression of the file
/// (~0.3 s per recorded hour; docs/benchmarks.md). Example:
///   io::RecordingSummary sum;
///   auto res = runEstimatorOnePass("d.rawlog", cfg, opt, csv, sum);
///   if (!res) { sum = io::scanRawlog("d.rawlog"); res = runEstimator("d.rawlog", sum, ...); }
std::optional<EstimationResult> runEstimatorOnePass(
    const std::string& rawlog, const config::WheelchairConfig& cfg, const EkfOptions& opt,
    EstimateSink& sink, io::RecordingSummary& summary,
    const std::function<void(double)>& progress = {});

/// The selected filter run on samples as they arrive (`wheelchair capture --health`): the
/// same merge (EventMerger) and the same per-event step as runEstimator, fed by push() in
/// arrival order instead of from a file. A sample is released to the filter once a later one
/// has been pushed (all samples before the latest pushed time are taken as complete), and
/// the first measurement only once the motor currents are known past it when
/// `motors_expected`. A sample older than the latest one pushed (it arrived beyond the
/// capture's reorder window) cannot be merged any more: it is skipped and counted (late()).
/// So the live result equals runEstimator on the captured file when nothing arrived late.
/// A filter failure throws std::runtime_error naming the sample as runEstimator does (the
/// object is then unusable). Times: the recording clock (s). Example:
///   LiveEstimator live(cfg, opt, /*motors_expected=*/true);
///   for (const auto& s : arriving) {
///     live.push(s);
///     for (; printed < live.health().size(); ++printed) print(live.health()[printed]);
///   }
///   live.finish();                          // processes the rest; result() complete
class LiveEstimator {
 public:
  LiveEstimator(const config::WheelchairConfig& cfg, const EkfOptions& opt, bool motors_expected);
  ~LiveEstimator();
  LiveEstimator(const LiveEstimator&) = delete;
  LiveEstimator& operator=(const LiveEstimator&) = delete;
  /// One sample (any stream; streams the options leave out are dropped).
  void push(const io::AnySample& s);
  /// No more samples: processes what is left and completes result() (health, CVODE stats).
  void finish();
  /// The health events so far (physics filter; in time order). After finish() the same list
  /// as result().health.
  const std::vector<HealthEvent>& health() const;
  /// Earliest sample time pushed (s; +infinity before the first): the recording's start.
  double startTime() const;
  /// Samples skipped because they arrived after a later one had been released.
  std::size_t late() const;
  const EstimationResult& result() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The two families of estimators: the wheelchair filters (physics CD-EKF or baseline, on
/// encoders / gyro / sonar / Pozyx) and the command-driven EKF (commands + landmark
/// range-bearing, map known; CommandDrivenEkf.h).
enum class EstimatorFamily { Wheelchair, CommandDriven };

/// Which family runs a recording, the one rule of `filter` and `evaluate`. `forced`: ""
/// (automatic), "physics" or "baseline" (wheelchair), "command" (command-driven). Automatic:
/// command-driven when the recording has landmark sightings or a landmark map and none of
/// the wheelchair filters' streams (ENCODERS, IMU, SONAR, POZYX); the wheelchair filters
/// otherwise (a wheelchair drive that also saw landmarks is a wheelchair drive). Example:
///   if (selectEstimator(rec) == EstimatorFamily::CommandDriven) runCommandDrivenEkf(...);
EstimatorFamily selectEstimator(const io::RecordingSummary& rec, const std::string& forced = "");
EstimatorFamily selectEstimator(const io::Recording& rec, const std::string& forced = "");

}  // namespace wheelchair::estimation
