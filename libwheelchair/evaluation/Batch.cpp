#include "libwheelchair/evaluation/Batch.h"
#include "libwheelchair/estimation/ModelExtensions.h"

#include "libwheelchair/estimation/EkfOptions.h"
#include "libwheelchair/estimation/Estimator.h"
#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/RawlogStream.h"
#include "libwheelchair/simulation/Simulator.h"
#include "libwheelchair/util/AtomicFile.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <thread>

namespace wheelchair::evaluation {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Sorted by t_s (stable), then strictly increasing times: of equal timestamps the last
// sample wins.
// Done in place (no copy of a long trajectory) when the input is already time-ordered.
template <class T>
void sortByTimeKeepLast(std::vector<T>& v) {
  const auto less = [](const T& a, const T& b) { return a.t_s < b.t_s; };
  if (!std::is_sorted(v.begin(), v.end(), less)) std::stable_sort(v.begin(), v.end(), less);
  std::size_t n = 0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (n > 0 && v[n - 1].t_s == v[i].t_s)
      v[n - 1] = v[i];
    else
      v[n++] = v[i];
  }
  v.resize(n);
}

std::string oneLine(std::string s) {
  for (char& c : s)
    if (c == '\n' || c == '\r') c = ' ';
  return s;
}

std::string num(double v) {
  if (std::isnan(v)) return "nan";
  return fmt::format("{:.9g}", v);
}

estimation::EkfOptions ekfOptions(const config::WheelchairConfig& cfg,
                                  estimation::FilterKind kind) {
  estimation::EkfOptions opt;
  opt.loadFromConfig(cfg.ini(), "estimator");
  opt.filter = kind;
  return opt;
}

/// BatchOptions::warning, serialised over the worker threads.
void warn(const BatchOptions& options, const std::string& text) {
  if (!options.warning) return;
  static std::mutex warning_mutex;
  const std::lock_guard<std::mutex> lock(warning_mutex);
  options.warning(text);
}

/// The simulator's truth (`wheelchair simulate`'s NAME.truth.json) as ground truth: body
/// poses in the start frame with heading, lever arm 0. Throws naming the file.
GroundTruth simulatorTruth(const std::string& path) {
  GroundTruth g;
  g.source = GroundTruthSource::SimulatorTruth;
  try {
    for (const auto& s : simulation::readTruth(path).truth.samples)
      g.samples.push_back({s.t_s, s.x_m, s.y_m, s.phi_rad});
  } catch (const std::exception& e) {
    throw std::runtime_error("truth " + path + ": " + e.what());
  }
  if (g.samples.empty()) throw std::runtime_error("truth " + path + ": no trajectory");
  sortByTimeKeepLast(g.samples);
  return g;
}

}  // namespace

const char* toString(GroundTruthSource s) {
  switch (s) {
    case GroundTruthSource::Pozyx:
      return "pozyx";
    case GroundTruthSource::GroundTruthStream:
      return "ground_truth";
    case GroundTruthSource::SimulatorTruth:
      return "simulator";
    default:
      return "none";
  }
}

GroundTruth groundTruthOf(const io::Recording& rec, const config::WheelchairConfig& cfg) {
  GroundTruth g;
  if (!rec.ground_truth.empty()) {
    g.source = GroundTruthSource::GroundTruthStream;
    for (const auto& s : rec.ground_truth) g.samples.push_back({s.t_s, s.x_m, s.y_m, s.phi_rad});
  } else if (!rec.pozyx.empty()) {
    g.source = GroundTruthSource::Pozyx;
    g.lever_arm_m = {cfg.pozyx.lever_x_m, cfg.pozyx.lever_y_m};
    for (const auto& s : rec.pozyx) g.samples.push_back({s.t_s, s.x_m, s.y_m});
  }
  sortByTimeKeepLast(g.samples);
  return g;
}

Trajectory toTrajectory(const estimation::EstimationResult& res) {
  Trajectory t;
  t.reserve(res.estimates.size());
  for (const auto& e : res.estimates) t.push_back({e.t_s, e.x(2), e.x(3), e.x(4)});
  sortByTimeKeepLast(t);
  return t;
}

Trajectory TrajectorySink::take() {
  Trajectory t;
  t.swap(poses_);
  sortByTimeKeepLast(t);
  return t;
}

Trajectory toTrajectory(const std::vector<estimation::DeadReckoningSample>& dr) {
  Trajectory t;
  t.reserve(dr.size());
  for (const auto& s : dr) t.push_back({s.t_s, s.x_m, s.y_m, s.phi_rad});
  sortByTimeKeepLast(t);
  return t;
}

Trajectory toTrajectory(const std::vector<estimation::CommandDrivenEstimate>& est) {
  Trajectory t;
  t.reserve(est.size());
  for (const auto& e : est) t.push_back({e.t_s, e.x_m, e.y_m, e.phi_rad});
  sortByTimeKeepLast(t);
  return t;
}

const std::vector<std::string>& commandDrivenVariantNames() {
  static const std::vector<std::string> v{"ekf", "commands"};
  return v;
}

Trajectory CommandDrivenEstimates::trajectory(const std::string& variant) const {
  if (variant == "ekf") return toTrajectory(ekf.trajectory);
  if (variant == "commands") return toTrajectory(commands);
  throw std::invalid_argument("unknown command-driven trajectory variant '" + variant + "'");
}

CommandDrivenEstimates estimateCommandDrivenVariants(const io::Recording& rec,
                                                     const config::WheelchairConfig& cfg) {
  CommandDrivenEstimates r;
  const auto opt = estimation::loadCommandDrivenEkfOptions(cfg.ini());
  const auto missing = estimation::missingForCommandDrivenEkf(rec);
  std::string ekf_error;
  if (!missing.empty()) {
    ekf_error = "the command-driven EKF needs ";
    for (std::size_t i = 0; i < missing.size(); ++i) ekf_error += (i ? "; " : "") + missing[i];
  } else {
    try {
      r.ekf = estimation::runCommandDrivenEkf(rec, io::landmarkMap(rec), opt);
      if (!r.ekf.initialised)
        ekf_error = fmt::format(
            "no landmark initialisation: no two sightings of mapped landmarks at least {} m "
            "apart within {} s",
            opt.init_min_separation_m, opt.init_window_s);
      else if (r.ekf.trajectory.empty())
        ekf_error = "the command-driven EKF produced no estimate";
    } catch (const std::exception& e) {
      ekf_error = e.what();
    }
  }
  r.errors.emplace_back("ekf", ekf_error);
  std::string cmd_error;
  try {
    if (rec.joystick.empty()) throw std::runtime_error("no command stream (JOYSTICK)");
    if (r.ekf.initialised) {
      r.commands = estimation::deadReckoningCommands(
          rec, opt, r.ekf.t_start_s,
          {r.ekf.start_pose_xy(0), r.ekf.start_pose_xy(1), r.ekf.start_phi_rad},
          r.ekf.start_velocity);
    } else {
      double t0 = rec.joystick.front().t_s;
      for (const auto& j : rec.joystick) t0 = std::min(t0, j.t_s);
      r.commands = estimation::deadReckoningCommands(rec, opt, t0, Eigen::Vector3d::Zero(),
                                                     Eigen::Vector2d::Zero());
    }
    if (r.commands.empty()) throw std::runtime_error("the command dead reckoning is empty");
  } catch (const std::exception& e) {
    cmd_error = e.what();
  }
  r.errors.emplace_back("commands", cmd_error);
  return r;
}

const std::vector<std::string>& variantNames() {
  static const std::vector<std::string> v{"ekf", "encoders", "encoders_gyro", "baseline"};
  return v;
}

Trajectory RecordingEstimates::trajectory(const std::string& variant) const {
  if (variant == "ekf") return toTrajectory(ekf);
  if (variant == "baseline") return toTrajectory(baseline);
  if (variant == "encoders") return toTrajectory(encoders);
  if (variant == "encoders_gyro") return toTrajectory(encoders_gyro);
  throw std::invalid_argument("unknown trajectory variant '" + variant + "'");
}

namespace {
/// Runs one variant: "" when it succeeded, else the reason it failed (the other variants run).
std::string errorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}
}  // namespace

RecordingEstimates estimateVariants(const io::Recording& raw_rec,
                                    const config::WheelchairConfig& raw_cfg, bool with_baseline,
                                    estimation::EstimateSink* ekf_sink,
                                    estimation::EstimateSink* baseline_sink) {
  // A corrected configuration ([model_extensions] from `wheelchair diagnose`) calibrates the
  // sensors and the drive train for every variant.
  const auto ext = estimation::ModelExtensions::fromConfig(raw_cfg.ini());
  const config::WheelchairConfig cfg = ext.adjustConfig(raw_cfg);
  io::Recording corrected;  // a copy only when the extensions change the recording
  if (!ext.empty()) corrected = ext.apply(raw_rec, cfg);
  const io::Recording& rec = ext.empty() ? raw_rec : corrected;
  RecordingEstimates r;
  r.has_baseline = with_baseline;
  auto attempt = [&](const std::string& name, const std::function<void()>& f) {
    r.errors.emplace_back(name, errorOf(f));
  };
  // The filter's estimates stored, or streamed to `sink` when there is one.
  auto run = [&](estimation::FilterKind kind, estimation::EstimateSink* sink) {
    const auto opt = ekfOptions(cfg, kind);
    return sink ? estimation::runEstimator(rec, cfg, opt, *sink)
                : estimation::runEstimator(rec, cfg, opt);
  };
  attempt("ekf", [&] {
    r.ekf = run(estimation::FilterKind::Physics, ekf_sink);
    if (r.ekf.n_estimates == 0) throw std::runtime_error("the EKF produced no estimate");
  });
  attempt("encoders", [&] {
    r.encoders =
        estimation::deadReckoningEncoders(rec.encoders, cfg.encoders.params, cfg.vehicle.geom);
    if (r.encoders.empty()) throw std::runtime_error("no encoder samples");
  });
  attempt("encoders_gyro", [&] {
    r.encoders_gyro = estimation::deadReckoningEncoderGyro(rec.encoders, rec.imu,
                                                           cfg.encoders.params, cfg.vehicle.geom);
    if (r.encoders_gyro.empty()) throw std::runtime_error("no encoder/gyro samples");
  });
  if (with_baseline)
    attempt("baseline", [&] {
      r.baseline = run(estimation::FilterKind::Baseline, baseline_sink);
      if (r.baseline.n_estimates == 0)
        throw std::runtime_error("the baseline produced no estimate");
    });
  return r;
}

RecordingEstimates streamVariants(
    const std::string& rawlog, const io::RecordingSummary& sum, const config::WheelchairConfig& cfg,
    const VariantSinks& sinks,
    const std::function<void(const std::string& variant, const std::string& error)>& done) {
  if (!estimation::ModelExtensions::fromConfig(cfg.ini()).empty())
    throw std::invalid_argument(
        "streamVariants: a configuration with [model_extensions] needs the recording in memory");
  RecordingEstimates r;
  r.has_baseline = sinks.baseline != nullptr;
  auto attempt = [&](const std::string& name, const std::function<void()>& f) {
    const std::string err = errorOf(f);
    r.errors.emplace_back(name, err);
    if (done) done(name, err);
  };
  auto deadReckoning = [&](bool with_gyro, const char* empty_error,
                           const std::function<void(const estimation::DeadReckoningSample&)>& f) {
    const auto run = estimation::deadReckonRawlog(rawlog, sum, with_gyro, cfg.encoders.params,
                                                  cfg.vehicle.geom, f);
    if (run.samples == 0) throw std::runtime_error(empty_error);
  };
  if (sinks.ekf)
    attempt("ekf", [&] {
      r.ekf = estimation::runEstimator(
          rawlog, sum, cfg, ekfOptions(cfg, estimation::FilterKind::Physics), *sinks.ekf);
      if (r.ekf.n_estimates == 0) throw std::runtime_error("the EKF produced no estimate");
    });
  if (sinks.encoders)
    attempt("encoders", [&] { deadReckoning(false, "no encoder samples", sinks.encoders); });
  if (sinks.encoders_gyro)
    attempt("encoders_gyro",
            [&] { deadReckoning(true, "no encoder/gyro samples", sinks.encoders_gyro); });
  if (sinks.baseline)
    attempt("baseline", [&] {
      r.baseline = estimation::runEstimator(
          rawlog, sum, cfg, ekfOptions(cfg, estimation::FilterKind::Baseline), *sinks.baseline);
      if (r.baseline.n_estimates == 0)
        throw std::runtime_error("the baseline produced no estimate");
    });
  return r;
}

void sortByTimeKeepLast(Trajectory& t) {
  sortByTimeKeepLast<Pose2DStamped>(t);
}

namespace {

// The wheelchair variants of estimateVariants, one after the other: each trajectory (or its
// error) is passed to `f` and dropped before the next is computed. The rawlog is read as a
// stream by every variant (io/RawlogStream.h: the filters stream their poses into a
// TrajectorySink, dead reckoning its samples), so the peak is one pose trajectory, not the
// recording; a configuration with model extensions needs the corrected recording in memory.
void forEachVariantTrajectory(
    const std::string& path, const io::RecordingSummary& sum,
    const config::WheelchairConfig& raw_cfg, bool with_baseline,
    const std::function<void(const std::string&, const std::string&, Trajectory)>& f) {
  const auto ext = estimation::ModelExtensions::fromConfig(raw_cfg.ini());
  const config::WheelchairConfig cfg = ext.adjustConfig(raw_cfg);
  std::optional<io::Recording> rec;
  if (!ext.empty()) rec = ext.apply(io::readRawlogSalvaging(path, true, nullptr), cfg);
  auto attempt = [&](const std::string& name, const std::function<Trajectory()>& make) {
    Trajectory t;
    std::string err;
    try {
      t = make();
    } catch (const std::exception& e) {
      err = e.what();
    }
    f(name, err, std::move(t));
  };
  auto filter = [&](estimation::FilterKind kind, const char* empty_error) {
    TrajectorySink poses;
    const auto opt = ekfOptions(cfg, kind);
    using io::StreamKind;  // at most one pose per measurement: sized once
    poses.reserve((opt.use_encoders ? sum.count(StreamKind::Encoders) : 0) +
                  (opt.use_gyro ? sum.count(StreamKind::Imu) : 0) +
                  (opt.use_sonar ? sum.count(StreamKind::Sonar) : 0) +
                  (opt.use_pozyx ? sum.count(StreamKind::Pozyx) : 0));
    const auto res = rec ? estimation::runEstimator(*rec, cfg, opt, poses)
                         : estimation::runEstimator(path, sum, cfg, opt, poses);
    if (res.n_estimates == 0) throw std::runtime_error(empty_error);
    return poses.take();
  };
  auto deadReckoning = [&](bool with_gyro, const char* empty_error) {
    const auto& p = cfg.encoders.params;
    Trajectory t;
    if (rec) {
      t = toTrajectory(
          with_gyro
              ? estimation::deadReckoningEncoderGyro(rec->encoders, rec->imu, p, cfg.vehicle.geom)
              : estimation::deadReckoningEncoders(rec->encoders, p, cfg.vehicle.geom));
    } else {
      // At most one sample per encoder sample and gyro time: sized once.
      t.reserve(sum.count(io::StreamKind::Encoders) +
                (with_gyro ? sum.count(io::StreamKind::Imu) : 0));
      estimation::deadReckonRawlog(path, sum, with_gyro, p, cfg.vehicle.geom,
                                   [&](const estimation::DeadReckoningSample& s) {
                                     t.push_back({s.t_s, s.x_m, s.y_m, s.phi_rad});
                                   });
      sortByTimeKeepLast(t);
    }
    if (t.empty()) throw std::runtime_error(empty_error);
    return t;
  };
  attempt("ekf",
          [&] { return filter(estimation::FilterKind::Physics, "the EKF produced no estimate"); });
  attempt("encoders", [&] { return deadReckoning(false, "no encoder samples"); });
  attempt("encoders_gyro", [&] { return deadReckoning(true, "no encoder/gyro samples"); });
  if (with_baseline)
    attempt("baseline", [&] {
      return filter(estimation::FilterKind::Baseline, "the baseline produced no estimate");
    });
}

/// The streams groundTruthOf reads (GROUND_TRUTH, POZYX) of a rawlog, and its meta.
io::Recording groundTruthStreams(const std::string& path) {
  io::Recording rec;
  io::RawlogSampleReader in(path);
  io::AnySample s;
  std::size_t k = 0;
  while (in.next(s, k)) {
    const auto kind = io::kindOf(s);
    if (kind == io::StreamKind::GroundTruth || kind == io::StreamKind::Pozyx) io::append(rec, s);
  }
  return rec;
}

}  // namespace

void parseAlignment(const std::string& text, MetricOptions& o) {
  if (text == "none") {
    o.alignment = Alignment::None;
  } else if (text == "origin") {
    o.alignment = Alignment::Origin;
  } else if (text == "se2") {
    o.alignment = Alignment::SE2;
  } else if (text.rfind("se2-first:", 0) == 0) {
    const std::string v = text.substr(10);
    std::size_t used = 0;
    double s = 0;
    try {
      s = std::stod(v, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (v.empty() || used != v.size() || !(s > 0) || !std::isfinite(s))
      throw std::invalid_argument("alignment 'se2-first:SECONDS' needs a positive number, got '" +
                                  text + "'");
    o.alignment = Alignment::SE2FirstSeconds;
    o.align_first_s = s;
  } else {
    throw std::invalid_argument("unknown alignment '" + text +
                                "' (none | origin | se2 | se2-first:SECONDS)");
  }
}

std::string alignmentText(Alignment a, double first_s) {
  // The command-line spelling: toString's, with the window for the first-seconds form.
  return a == Alignment::SE2FirstSeconds ? "se2-first:" + num(first_s) : toString(a);
}

std::string variantNotApplicable(const std::string& variant, const io::RecordingSummary& rec) {
  using io::StreamKind;
  const bool enc = rec.count(StreamKind::Encoders) >= 2, gyro = rec.count(StreamKind::Imu) > 0;
  if ((variant == "encoders" || variant == "encoders_gyro") && !enc)
    return "no encoder (encoders) readings";
  if (variant == "encoders_gyro" && !gyro) return "no gyro (imu) readings";
  if ((variant == "ekf" || variant == "baseline") && !enc && !gyro && !rec.count(StreamKind::Sonar))
    return "no encoder, gyro or sonar readings";
  return "";
}

std::string variantNotApplicable(const std::string& variant, const io::Recording& rec) {
  return variantNotApplicable(variant, io::summarize(rec));
}

std::vector<BatchRow> evaluateRecording(const std::string& path,
                                        const config::WheelchairConfig& shared_cfg,
                                        const BatchOptions& options) {
  std::vector<BatchRow> rows;
  try {
    // Own copy: nothing of the configuration is shared between worker threads.
    const auto cfg = config::WheelchairConfig::fromText(shared_cfg.text(), shared_cfg.origin());
    std::string salvaged;
    // Pass 1 (io/RawlogStream.h): what the file holds, the salvage rule; the variants then
    // read it as a stream. Command-driven recordings (small: MRCLAM) are read whole.
    const io::RecordingSummary sum = io::scanRawlogSalvaging(path, options.salvage, &salvaged);
    if (!salvaged.empty()) warn(options, salvaged);
    const bool command_driven =
        estimation::selectEstimator(sum) == estimation::EstimatorFamily::CommandDriven;
    const io::Recording rec =
        command_driven ? io::readRawlogSalvaging(path, true, nullptr) : groundTruthStreams(path);
    const auto truth_file = options.truth.find(path);
    const GroundTruth gt = truth_file != options.truth.end() ? simulatorTruth(truth_file->second)
                                                             : groundTruthOf(rec, cfg);
    // The filters fuse the Pozyx: scored against it, they are not independently evaluated.
    const bool pozyx_fused = !command_driven && gt.source == GroundTruthSource::Pozyx &&
                             ekfOptions(cfg, estimation::FilterKind::Physics).use_pozyx &&
                             sum.count(io::StreamKind::Pozyx) > 0;
    if (pozyx_fused)
      warn(options, path +
                        ": the filters fuse the Pozyx (use_pozyx = 1), so the ekf and baseline "
                        "rows scored against it are not an independent evaluation (ground "
                        "truth 'pozyx_fused'); give the simulator's truth (--truth) or record a "
                        "GROUND_TRUTH stream");
    MetricOptions mo = options.metrics;
    mo.lever_arm_m = gt.lever_arm_m;
    const auto addRow = [&](const std::string& variant, const std::string& err,
                            const std::function<Trajectory()>& trajectory) {
      BatchRow row;
      row.recording = path;
      row.variant = variant;
      row.ground_truth = toString(gt.source);
      if (pozyx_fused && (variant == "ekf" || variant == "baseline"))
        row.ground_truth = "pozyx_fused";
      row.error = oneLine(err);
      if (!command_driven) row.not_applicable = variantNotApplicable(variant, sum);
      if (!row.not_applicable.empty()) row.error.clear();
      if (err.empty() && row.not_applicable.empty()) {
        try {
          const Trajectory t = trajectory();
          row.n_estimates = t.size();
          row.metrics = computeMetrics(t, gt.samples, mo);
        } catch (const std::exception& e) {
          row.error = oneLine(e.what());
        }
      }
      rows.push_back(std::move(row));
    };
    // Command-driven recordings (MRCLAM): ekf + commands; others: the wheelchair variants,
    // streamed one at a time (memory flat in the drive's length).
    if (command_driven) {
      const CommandDrivenEstimates cd = estimateCommandDrivenVariants(rec, cfg);
      for (const auto& [variant, err] : cd.errors)
        addRow(variant, err, [&, v = variant] { return cd.trajectory(v); });
    } else {
      forEachVariantTrajectory(
          path, sum, cfg, options.baseline,
          [&](const std::string& variant, const std::string& err, Trajectory t) {
            addRow(variant, err, [&t] { return std::move(t); });
          });
    }
  } catch (const std::exception& e) {
    rows.clear();
    BatchRow row;
    row.recording = path;
    row.ground_truth = toString(GroundTruthSource::None);
    row.error = oneLine(e.what());
    if (row.error.empty()) row.error = "unknown error";
    rows.push_back(std::move(row));
  }
  return rows;
}

BatchResult runBatch(const std::vector<std::string>& files, const config::WheelchairConfig& cfg,
                     const BatchOptions& options) {
  BatchResult out;
  out.recordings = files.size();
  out.alignment = options.metrics.alignment;
  out.align_first_s = options.metrics.align_first_s;
  std::vector<std::vector<BatchRow>> per_file(files.size());

  unsigned jobs = options.jobs ? options.jobs : std::max(1u, std::thread::hardware_concurrency());
  jobs = static_cast<unsigned>(std::min<std::size_t>(jobs, std::max<std::size_t>(files.size(), 1)));
  std::atomic<std::size_t> next{0};
  std::size_t done = 0;
  std::mutex mu;
  auto worker = [&] {
    for (;;) {
      const std::size_t i = next.fetch_add(1);
      if (i >= files.size()) return;
      per_file[i] = evaluateRecording(files[i], cfg, options);
      if (options.progress) {
        std::lock_guard<std::mutex> lock(mu);
        options.progress(++done, files.size(), files[i]);
      }
    }
  };
  if (jobs <= 1) {
    worker();
  } else {
    std::vector<std::thread> pool;
    for (unsigned k = 0; k < jobs; ++k) pool.emplace_back(worker);
    for (auto& t : pool) t.join();
  }
  for (auto& rows : per_file) {
    bool failed = false;
    for (auto& r : rows) {
      failed |= !r.error.empty();
      out.rows.push_back(std::move(r));
    }
    out.failed_recordings += failed ? 1 : 0;
  }
  return out;
}

namespace {

std::string csvField(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) {
    if (c == '"') q += '"';
    q += c;
  }
  return q + "\"";
}

struct Column {
  const char* name;
  std::function<double(const Metrics&)> get;
};

const std::vector<Column>& metricColumns() {
  static const std::vector<Column> c{
      {"d_path_m", [](const Metrics& m) { return m.d_path_m; }},
      {"d_path_gt_m", [](const Metrics& m) { return m.d_path_gt_m; }},
      {"terminal_error_m", [](const Metrics& m) { return m.terminal_error_m; }},
      {"loop_error_m", [](const Metrics& m) { return m.loop_error_m; }},
      {"ate_rmse_m", [](const Metrics& m) { return m.ate_rmse_m; }},
      {"ate_mean_m", [](const Metrics& m) { return m.ate_mean_m; }},
      {"ate_median_m", [](const Metrics& m) { return m.ate_median_m; }},
      {"ate_max_m", [](const Metrics& m) { return m.ate_max_m; }},
      {"ate_std_m", [](const Metrics& m) { return m.ate_std_m; }},
      {"rpe_1m_m", [](const Metrics& m) { return m.rpe_1m_m; }},
      {"rpe_5m_m", [](const Metrics& m) { return m.rpe_5m_m; }},
      {"n_rpe_1m", [](const Metrics& m) { return double(m.n_rpe_1m); }},
      {"n_rpe_5m", [](const Metrics& m) { return double(m.n_rpe_5m); }},
      {"heading_drift_deg", [](const Metrics& m) { return m.heading_drift_deg; }},
  };
  return c;
}

double degrees(double rad) {
  return rad * 180.0 / kPi;
}

}  // namespace

std::string batchCsv(const BatchResult& r) {
  std::string s = "recording,variant,ground_truth";
  for (const auto& c : metricColumns()) s += std::string(",") + c.name;
  s += ",heading_drift_method,n_matched,n_gt,n_outliers,n_estimates,alignment,align_x_m,align_y_m,"
       "align_theta_deg,error,not_applicable\n";
  const std::string al = alignmentText(r.alignment, r.align_first_s);
  for (const auto& row : r.rows) {
    const Metrics& m = row.metrics;
    s += csvField(row.recording) + "," + csvField(row.variant) + "," + row.ground_truth;
    if (!row.not_applicable.empty()) {
      for (std::size_t i = 0; i < metricColumns().size(); ++i) s += ",n/a";
      s += fmt::format(",n/a,0,0,0,0,{},n/a,n/a,n/a,,{}\n", al, csvField(row.not_applicable));
      continue;
    }
    for (const auto& c : metricColumns()) s += "," + num(c.get(m));
    s += fmt::format(",{},{},{},{},{},{},{},{},{},{},\n", toString(m.heading_drift_method),
                     m.n_matched, m.n_gt, m.n_outliers, row.n_estimates, al, num(m.alignment.x),
                     num(m.alignment.y), num(degrees(m.alignment.theta)), csvField(row.error));
  }
  return s;
}

void writeBatchCsv(const std::string& path, const BatchResult& r,
                   const config::WheelchairConfig& cfg) {
  util::writeFileAtomically(path, batchCsv(r));
  try {
    util::writeFileAtomically(
        path + ".config.ini",
        "# Configuration used for " + path + " (wheelchair evaluate)\n# origin: " + cfg.origin() +
            "\n# alignment: " + alignmentText(r.alignment, r.align_first_s) + "\n" + cfg.text());
  } catch (...) {
    std::remove(path.c_str());  // both files or neither
    throw;
  }
}

std::string batchJson(const BatchResult& r, const config::WheelchairConfig& cfg) {
  using nlohmann::json;
  auto jnum = [](double v) -> json { return std::isfinite(v) ? json(v) : json(nullptr); };
  json j;
  j["alignment"] = alignmentText(r.alignment, r.align_first_s);
  j["config_origin"] = cfg.origin();
  j["config"] = cfg.text();
  j["recordings"] = r.recordings;
  j["failed_recordings"] = r.failed_recordings;
  json rows = json::array();
  for (const auto& row : r.rows) {
    json o;
    o["recording"] = row.recording;
    o["variant"] = row.variant;
    o["ground_truth"] = row.ground_truth;
    for (const auto& c : metricColumns()) o[c.name] = jnum(c.get(row.metrics));
    o["heading_drift_method"] = toString(row.metrics.heading_drift_method);
    o["n_matched"] = row.metrics.n_matched;
    o["n_gt"] = row.metrics.n_gt;
    o["n_outliers"] = row.metrics.n_outliers;
    o["n_estimates"] = row.n_estimates;
    o["alignment_transform"] = {{"x_m", jnum(row.metrics.alignment.x)},
                                {"y_m", jnum(row.metrics.alignment.y)},
                                {"theta_deg", jnum(degrees(row.metrics.alignment.theta))}};
    o["alignment_spread_m"] = jnum(row.metrics.alignment_spread_m);
    o["error"] = row.error;
    o["not_applicable"] = row.not_applicable;
    rows.push_back(std::move(o));
  }
  j["rows"] = std::move(rows);
  return j.dump(2) + "\n";
}

void writeBatchJson(const std::string& path, const BatchResult& r,
                    const config::WheelchairConfig& cfg) {
  util::writeFileAtomically(path, batchJson(r, cfg));
}

std::string batchMarkdown(const BatchResult& r, const config::WheelchairConfig& cfg,
                          bool include_config) {
  auto f = [](double v, int prec) {
    return std::isfinite(v) ? fmt::format("{:.{}f}", v, prec) : std::string("–");
  };
  std::string s = fmt::format(
      "Alignment: `{}`. Ground truth per row (`pozyx` = UWB tag, lever arm "
      "from [pozyx]; `ground_truth` = motion-capture poses).\n\n",
      alignmentText(r.alignment, r.align_first_s));
  s += "| recording | variant | GT | d_path (m) | terminal err (m) | loop err (m) | ATE RMSE (m) | "
       "ATE max (m) | RPE 1 m (m) | heading drift (deg) | matched | error |\n";
  s += "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|\n";
  for (const auto& row : r.rows) {
    const Metrics& m = row.metrics;
    const bool na = !row.not_applicable.empty();  // every metric cell "n/a"
    auto g = [&](double v, int prec) { return na ? std::string("n/a") : f(v, prec); };
    std::string err = na ? "n/a: " + row.not_applicable : row.error;
    for (char& c : err)
      if (c == '|') c = '/';
    s += fmt::format("| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
                     row.recording, row.variant.empty() ? "–" : row.variant, row.ground_truth,
                     g(m.d_path_m, 2), g(m.terminal_error_m, 3), g(m.loop_error_m, 3),
                     g(m.ate_rmse_m, 3), g(m.ate_max_m, 3), g(m.rpe_1m_m, 3),
                     g(m.heading_drift_deg, 2), na ? "n/a" : std::to_string(m.n_matched), err);
  }
  if (include_config)
    s += "\n## Configuration used (`" + cfg.origin() + "`)\n\n```ini\n" + cfg.text() + "\n```\n";
  return s;
}

std::string batchTable(const BatchResult& r) {
  auto f = [](double v, int prec) {
    return std::isfinite(v) ? fmt::format("{:.{}f}", v, prec) : std::string("-");
  };
  std::size_t w = 9;  // width of the recording column
  for (const auto& row : r.rows) w = std::max(w, row.recording.size());
  std::string s = fmt::format("{:<{}}  {:<13} {:<12} {:>10} {:>12} {:>12} {:>11} {:>10} {:>13}\n",
                              "recording", w, "variant", "truth", "path (m)", "end err (m)",
                              "ATE RMSE (m)", "ATE max (m)", "RPE 1m (m)", "heading (deg)");
  for (const auto& row : r.rows) {
    const Metrics& m = row.metrics;
    s += fmt::format("{:<{}}  {:<13} {:<12} ", row.recording, w,
                     row.variant.empty() ? "-" : row.variant, row.ground_truth);
    if (!row.not_applicable.empty()) {
      s += "n/a: " + row.not_applicable + "\n";
    } else if (!row.error.empty()) {
      s += "FAILED: " + row.error + "\n";
    } else {
      s += fmt::format("{:>10} {:>12} {:>12} {:>11} {:>10} {:>13}\n", f(m.d_path_m, 2),
                       f(m.terminal_error_m, 3), f(m.ate_rmse_m, 3), f(m.ate_max_m, 3),
                       f(m.rpe_1m_m, 3), f(m.heading_drift_deg, 2));
    }
  }
  s += fmt::format(
      "(alignment {}; truth: pozyx = UWB tag positions, ground_truth = motion capture, none = "
      "no metrics against truth; '-' = not available)\n",
      alignmentText(r.alignment, r.align_first_s));
  const auto any = [&r](const char* truth) {
    return std::any_of(r.rows.begin(), r.rows.end(),
                       [truth](const BatchRow& row) { return row.ground_truth == truth; });
  };
  if (any("simulator")) s += "(simulator = the simulator's truth, evaluate --truth)\n";
  if (any("pozyx_fused"))
    s += "(pozyx_fused = the Pozyx the filter fused (use_pozyx = 1): NOT an independent truth)\n";
  return s;
}

void writeBatchMarkdown(const std::string& path, const BatchResult& r,
                        const config::WheelchairConfig& cfg) {
  util::writeFileAtomically(path, "# Trajectory metrics\n\n" + batchMarkdown(r, cfg, true));
}

}  // namespace wheelchair::evaluation
