// Batch evaluation of recordings: for every recording, every trajectory variant of the paper's
// Fig. 5 (+ the baseline filter) against the recording's ground truth (docs/evaluation.md,
// "Batch evaluation").
//
//   variant        trajectory
//   ekf            physics CD-EKF (estimation::runEstimator, [estimator] options, filter=physics)
//   encoders       dead reckoning, encoders only (estimation::deadReckoningEncoders)
//   encoders_gyro  dead reckoning, encoder v + gyro omega (estimation::deadReckoningEncoderGyro)
//   baseline       kinematic discrete EKF (filter=baseline), when BatchOptions::baseline
//
// Command-driven recordings (estimation::selectEstimator, the rule `filter` uses too: landmark
// sightings or a landmark map and no encoder/IMU/sonar/Pozyx stream, e.g. `wheelchair import
// --format mrclam`) get two rows instead:
//
//   ekf            command-driven EKF on commands + landmark range-bearing, map known
//                  (estimation::runCommandDrivenEkf; options from the configuration's
//                  [mrclam_filter] / [mrclam_response] sections, config/mrclam.ini; absent =
//                  nominal response, default noise)
//   commands       open-loop dead reckoning of the commands through the same model
//                  (estimation::deadReckoningCommands), started at the EKF's landmark
//                  initialisation: the "encoders only" analogue
//
// Both are in the map frame (= the Vicon frame for MRCLAM), so `--alignment none` is
// meaningful for them as well as the default se2.
//
// Ground truth: the simulator's truth when BatchOptions::truth names one for the recording
// (`evaluate --truth`: body poses in the start frame, with heading, lever arm 0), else the
// GROUND_TRUTH stream (motion-capture poses, with heading, lever arm 0) when the recording has
// one, else the POZYX stream (tag positions in the anchor frame, no heading, lever arm [pozyx]
// lever_x_m, lever_y_m), else none (only d_path_m and loop_error_m are then available).
// When the filters FUSE the Pozyx ([estimator] use_pozyx = 1 and the recording has POZYX),
// Pozyx is no longer an independent truth for the ekf and baseline rows: with no other truth
// they are still scored against it, but their ground_truth says "pozyx_fused" and
// BatchOptions::warning says so (the dead-reckoning rows do not use Pozyx and stay "pozyx").
//
// Recordings are processed by a pool of std::threads; every recording is evaluated on its
// own (own copy of the configuration), and rows are returned in input order (file, then the
// variant order above), so the result is identical to a serial run whatever the job count.
// A recording that cannot be read or evaluated yields ONE row with an empty variant and the
// message in `error`; a variant that fails alone gets its own error row. Neither stops the
// batch.
//
// Example:
//   auto cfg = config::WheelchairConfig::load("config/wheelchair.ini");
//   BatchOptions opt;  opt.metrics.alignment = Alignment::SE2;  opt.jobs = 4;
//   BatchResult r = runBatch({"a.rawlog", "b.rawlog"}, cfg, opt);
//   writeBatchCsv("metrics.csv", r, cfg);          // + metrics.csv.config.ini
//   writeBatchJson("metrics.json", r, cfg, opt);   // configuration inside
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/estimation/CommandDrivenEkf.h"
#include "libwheelchair/estimation/DeadReckoning.h"
#include "libwheelchair/estimation/EstimationTypes.h"
#include "libwheelchair/evaluation/Metrics.h"
#include "libwheelchair/io/Recording.h"

#include <Eigen/Core>

#include <cstddef>
#include <functional>
#include <map>
#include <string>
#include <vector>

namespace wheelchair::evaluation {

enum class GroundTruthSource { None, Pozyx, GroundTruthStream, SimulatorTruth };
/// "none", "pozyx", "ground_truth", "simulator"
const char* toString(GroundTruthSource s);

struct GroundTruth {
  GroundTruthSource source = GroundTruthSource::None;
  std::vector<Position2DStamped> samples;                 ///< strictly increasing time
  Eigen::Vector2d lever_arm_m = Eigen::Vector2d::Zero();  ///< tracked point in the body frame
};

/// The recording's ground truth (see the header comment). Samples sorted by time; of equal
/// timestamps the last one is kept.
GroundTruth groundTruthOf(const io::Recording& rec, const config::WheelchairConfig& cfg);

/// Estimates -> trajectory (x, y, phi of the canonical state), strictly increasing time (of
/// equal timestamps the last one is kept).
Trajectory toTrajectory(const estimation::EstimationResult& res);
Trajectory toTrajectory(const std::vector<estimation::DeadReckoningSample>& dr);
Trajectory toTrajectory(const std::vector<estimation::CommandDrivenEstimate>& est);

/// Estimate sink keeping only the pose (x, y, phi of the canonical state; 32 B per estimate
/// instead of ~0.5 kB): trajectory() equals toTrajectory() of the stored estimates.
/// Example:
///   TrajectorySink poses;
///   auto res = estimation::runEstimator(rec, cfg, opt, poses);
///   Trajectory t = poses.take();
class TrajectorySink : public estimation::EstimateSink {
 public:
  void add(const estimation::EstimateSample& e) override {
    poses_.push_back({e.t_s, e.x(2), e.x(3), e.x(4)});
  }
  /// Room for n poses at once (a long drive's trajectory without the doubling slack).
  void reserve(std::size_t n) { poses_.reserve(n); }
  /// The poses, strictly increasing in time (of equal timestamps the last); empties the sink.
  Trajectory take();

 private:
  Trajectory poses_;
};

/// Estimate sink streaming the pose (x, y, phi of the canonical state) to a TUM file.
class TumEstimateSink : public estimation::EstimateSink {
 public:
  explicit TumEstimateSink(const std::string& path, const std::vector<std::string>& comments = {})
      : tum_(path, comments) {}
  void add(const estimation::EstimateSample& e) override {
    tum_.add({e.t_s, e.x(2), e.x(3), e.x(4)});
  }
  void commit() { tum_.commit(); }

 private:
  TumWriter tum_;
};

/// Variant names in their fixed order.
const std::vector<std::string>& variantNames();  ///< ekf, encoders, encoders_gyro, baseline
/// Variants of command-driven recordings, in their fixed order: ekf, commands.
const std::vector<std::string>& commandDrivenVariantNames();

/// All trajectory variants of one recording, with the filters' full outputs (for plots).
struct RecordingEstimates {
  estimation::EstimationResult ekf, baseline;
  std::vector<estimation::DeadReckoningSample> encoders, encoders_gyro;
  bool has_baseline = false;
  /// Per variant (variantNames() order; baseline only when computed): the error message of a
  /// variant whose computation threw ("" = ok).
  std::vector<std::pair<std::string, std::string>> errors;
  Trajectory trajectory(const std::string& variant) const;
};

/// Runs the EKF (and the baseline when `with_baseline`) and both dead reckonings. The
/// estimator options come from cfg's [estimator] section (filter overridden per variant).
/// A failing variant is recorded in `errors`, the others are still computed.
/// With `ekf_sink` / `baseline_sink`, that filter streams its estimates there instead
/// (its EstimationResult keeps counts, statistics and warnings, no `estimates`: memory does not
/// grow with the drive; the estimates are bit-identical).
RecordingEstimates estimateVariants(const io::Recording& rec, const config::WheelchairConfig& cfg,
                                    bool with_baseline,
                                    estimation::EstimateSink* ekf_sink = nullptr,
                                    estimation::EstimateSink* baseline_sink = nullptr);

/// Where streamVariants sends each variant's output as it is produced. A variant whose sink
/// is unset (nullptr / empty function) is not run and gets no `errors` entry.
struct VariantSinks {
  estimation::EstimateSink* ekf = nullptr;
  std::function<void(const estimation::DeadReckoningSample&)> encoders, encoders_gyro;
  estimation::EstimateSink* baseline = nullptr;
};

/// estimateVariants over a rawlog read as a stream (io/RawlogStream.h; `sum` from
/// io::scanRawlogSalvaging), for a configuration without [model_extensions] (throws
/// std::invalid_argument with one; load the recording then). The variants run one after the
/// other in variantNames() order, each reading the file once and streaming its estimates or
/// dead-reckoning samples to its sink (bit-identical to estimateVariants on
/// io::readRawlog(rawlog); a dead reckoning's samples as deadReckoningEncoders/EncoderGyro
/// return them, before toTrajectory's sort); after each, `done(variant, error)` ("" = ok, the
/// messages of estimateVariants). Returns the filters' results (counts, statistics, warnings;
/// no `estimates`), `errors` and `has_baseline`; the dead-reckoning vectors stay empty. Memory:
/// what the sinks keep. Example:
///   TrajectorySink ekf;
///   VariantSinks sinks; sinks.ekf = &ekf;
///   auto r = streamVariants("d.rawlog", io::scanRawlog("d.rawlog"), cfg, sinks, {});
RecordingEstimates streamVariants(
    const std::string& rawlog, const io::RecordingSummary& sum, const config::WheelchairConfig& cfg,
    const VariantSinks& sinks,
    const std::function<void(const std::string& variant, const std::string& error)>& done);

/// Sorted by time (stable), then strictly increasing times: of equal timestamps the last pose
/// wins (what toTrajectory does; in place when already in order).
void sortByTimeKeepLast(Trajectory& t);

/// Both variants of a command-driven recording (see the header comment).
struct CommandDrivenEstimates {
  estimation::CommandDrivenEkfResult ekf;
  std::vector<estimation::CommandDrivenEstimate> commands;
  /// Per variant (commandDrivenVariantNames() order): the error message ("" = ok).
  std::vector<std::pair<std::string, std::string>> errors;
  Trajectory trajectory(const std::string& variant) const;
};

/// Runs the command-driven EKF and the open-loop command dead reckoning. Options from cfg's
/// [mrclam_filter] / [mrclam_response] sections. What the recording lacks (commands,
/// sightings, the landmark map) or a failed landmark initialisation is reported in `errors`
/// (the commands variant then starts at the origin at the first command).
CommandDrivenEstimates estimateCommandDrivenVariants(const io::Recording& rec,
                                                     const config::WheelchairConfig& cfg);

struct BatchOptions {
  MetricOptions metrics;  ///< alignment etc.; lever_arm_m is set from the ground truth
  unsigned jobs = 0;      ///< worker threads; 0 = std::thread::hardware_concurrency()
  bool baseline = true;   ///< also evaluate the baseline filter
  /// Damaged rawlogs: use the complete records before the break (io::readRawlogSalvaging)
  /// and report where it broke through `warning` (called serialised, from worker threads).
  bool salvage = false;
  std::function<void(const std::string&)> warning;
  /// Simulator truth files (NAME.truth.json of `wheelchair simulate`) by recording path as
  /// given: used as that recording's ground truth (header comment).
  std::map<std::string, std::string> truth;
  /// Called (serialised, from worker threads) after each recording: (done, total, path).
  std::function<void(std::size_t, std::size_t, const std::string&)> progress;
};

struct BatchRow {
  std::string recording;     ///< the path as given
  std::string variant;       ///< "" for a recording that failed as a whole
  std::string ground_truth;  ///< toString(GroundTruthSource)
  Metrics metrics;
  std::size_t n_estimates = 0;  ///< samples of the estimated trajectory
  std::string error;            ///< "" = ok
  /// Why the variant does not apply to this recording ("" = it does), e.g. "no gyro (imu)
  /// readings": such a row is listed as n/a, not computed and not a failure.
  std::string not_applicable;
};

struct BatchResult {
  std::vector<BatchRow> rows;
  std::size_t recordings = 0;
  std::size_t failed_recordings = 0;  ///< recordings with at least one error row
  Alignment alignment = Alignment::SE2;
  double align_first_s = 0;
  bool anyFailed() const { return failed_recordings > 0; }
};

/// Parses none | origin | se2 | se2-first:SECONDS into `o`; throws std::invalid_argument.
void parseAlignment(const std::string& text, MetricOptions& o);
/// The textual form parseAlignment accepts ("se2-first:10").
std::string alignmentText(Alignment a, double first_s);

/// Why wheelchair `variant` (variantNames()) cannot be computed from `rec`, "" when it can:
/// encoders needs ENCODERS readings, encoders_gyro ENCODERS and IMU, ekf/baseline any of
/// ENCODERS, IMU or SONAR.
std::string variantNotApplicable(const std::string& variant, const io::Recording& rec);
std::string variantNotApplicable(const std::string& variant, const io::RecordingSummary& rec);

/// Evaluates one recording (never throws: failures become error rows).
std::vector<BatchRow> evaluateRecording(const std::string& path,
                                        const config::WheelchairConfig& cfg,
                                        const BatchOptions& options);
/// Evaluates `files` in parallel; rows in input order (see the header comment).
BatchResult runBatch(const std::vector<std::string>& files, const config::WheelchairConfig& cfg,
                     const BatchOptions& options);

/// CSV (header + one line per row, numbers %.9g, "nan" when unavailable, the error quoted).
/// Columns: recording,variant,ground_truth,d_path_m,d_path_gt_m,terminal_error_m,loop_error_m,
/// ate_rmse_m,ate_mean_m,ate_median_m,ate_max_m,ate_std_m,rpe_1m_m,rpe_5m_m,n_rpe_1m,n_rpe_5m,
/// heading_drift_deg,heading_drift_method,n_matched,n_gt,n_outliers,n_estimates,alignment,
/// align_x_m,align_y_m,align_theta_deg,error,not_applicable. A not-applicable row has "n/a"
/// in every metric column and the reason in not_applicable.
std::string batchCsv(const BatchResult& r);
/// Fixed-width console table (one line per row: path length, terminal error, ATE RMSE / max,
/// RPE over 1 m, heading drift, with units in the header; "n/a" / "FAILED" rows say why).
std::string batchTable(const BatchResult& r);
/// Writes batchCsv atomically to `path` and the configuration used (full INI text, preceded by
/// comment lines naming its origin and the alignment) to `path` + ".config.ini".
void writeBatchCsv(const std::string& path, const BatchResult& r,
                   const config::WheelchairConfig& cfg);
/// JSON: {"alignment", "config_origin", "config" (full INI text), "recordings",
/// "failed_recordings", "rows": [{recording, variant, ground_truth, metrics..., error,
/// not_applicable}]} (NaN -> null; a not-applicable row has null metrics).
std::string batchJson(const BatchResult& r, const config::WheelchairConfig& cfg);
void writeBatchJson(const std::string& path, const BatchResult& r,
                    const config::WheelchairConfig& cfg);
/// Markdown: a metrics table and the configuration in a fenced block.
std::string batchMarkdown(const BatchResult& r, const config::WheelchairConfig& cfg,
                          bool include_config = true);
void writeBatchMarkdown(const std::string& path, const BatchResult& r,
                        const config::WheelchairConfig& cfg);

}  // namespace wheelchair::evaluation
