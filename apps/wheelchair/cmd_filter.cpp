// wheelchair filter FILE.rawlog : replays a recording through the estimator (the paper's
// continuous-discrete EKF integrated by CVODE, or the kinematic baseline) and writes the
// estimated trajectory, the per-time estimates with their standard deviations, and the
// Fig. 5 raw variants. Prints per-sensor usage, rejections and NIS statistics.
//
// Recordings with landmark sightings / a landmark map (`wheelchair import --format mrclam`)
// go through the command-driven EKF instead (estimation/CommandDrivenEkf.h): commands
// (JOYSTICK) + range-bearing sightings (LANDMARKS), map known; its estimates are in the MAP
// frame (MRCLAM: the Vicon frame), `--frame start` re-expresses them in the frame of the first
// estimated pose. `--filter command` forces that path. A recording lacking what the chosen
// filter needs exits 1 naming what is missing.
//
// Progress on stderr only when stderr is a terminal (and not --no-progress): a bar over the
// measurements processed (wheelchair filters) or the recording time (command-driven EKF).
#include "Command.h"
#include "HealthJson.h"
#include "Progress.h"

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/estimation/CommandDrivenEkf.h"
#include "libwheelchair/estimation/DeadReckoning.h"
#include "libwheelchair/estimation/EkfOptions.h"
#include "libwheelchair/estimation/EstimateWriters.h"
#include "libwheelchair/estimation/Estimator.h"
#include "libwheelchair/estimation/ModelExtensions.h"
#include "libwheelchair/estimation/SensorVerdict.h"
#include "libwheelchair/evaluation/Batch.h"
#include "libwheelchair/evaluation/Trajectory.h"
#include "libwheelchair/io/MrclamImport.h"
#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/RawlogStream.h"
#include "libwheelchair/util/AtomicFile.h"

#include <mrpt/config/CConfigFile.h>

#include <fmt/core.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <mutex>
#include <optional>
#include <thread>

#include <unistd.h>

namespace wheelchair::cli {
namespace {

struct FilterCliOptions {
  std::string input, config_path, trajectory, estimates, filter, obstacle_form, frame = "map";
  std::string health;  ///< model-health events (JSON lines)
  bool variants = false, pozyx = false, no_progress = false, salvage = false;
};

std::string nisVerdict(double mean, std::pair<double, double> band, long n) {
  if (n == 0) return "-";
  if (mean < band.first) return "low";
  if (mean > band.second) return "HIGH";
  return "yes";
}

std::string withSuffix(const std::string& path, const std::string& suffix) {
  const std::filesystem::path p(path);
  return (p.parent_path() / (p.stem().string() + suffix + p.extension().string())).string();
}

/// Why the wheelchair filters cannot run on `rec` ("" = they can).
std::string missingForWheelchairFilter(const io::Recording& rec,
                                       const estimation::EkfOptions& opt) {
  const bool enc = opt.use_encoders && rec.encoders.size() >= 2;
  const bool gyro = opt.use_gyro && !rec.imu.empty();
  const bool sonar = opt.use_sonar && !rec.sonar.empty();
  const bool pozyx = opt.use_pozyx && !rec.pozyx.empty();
  if (enc || gyro || sonar || pozyx) return "";
  std::string s =
      "the wheelchair filter needs encoder (ENCODERS), gyro (IMU), sonar (SONAR) or Pozyx "
      "(POZYX, with --pozyx) measurements; the recording has none that is enabled";
  const auto missing_cd = estimation::missingForCommandDrivenEkf(rec);
  if (estimation::isCommandDrivenRecording(rec) || !rec.joystick.empty()) {
    if (missing_cd.empty()) {
      s += " (it has what the command-driven EKF needs: use --filter command or omit --filter)";
    } else {
      s += "; the command-driven EKF would need ";
      for (std::size_t i = 0; i < missing_cd.size(); ++i) s += (i ? "; " : "") + missing_cd[i];
    }
  }
  return s;
}

// The command-driven EKF's options: the [mrclam_*] sections of --config, else the defaults;
// `note` says where they came from. Empty when the configuration file does not exist.
std::optional<estimation::CommandDrivenEkfOptions> commandDrivenOptions(const FilterCliOptions& o,
                                                                        std::string& note) {
  note = "built-in defaults (nominal response: velocities = commands)";
  if (o.config_path.empty()) return estimation::CommandDrivenEkfOptions{};
  if (!std::filesystem::exists(o.config_path)) return std::nullopt;
  const auto cfg = config::WheelchairConfig::load(o.config_path);  // strict key check
  const auto& ini = cfg.ini();
  note = o.config_path;
  if (!estimation::hasCommandDrivenSections(ini))
    note += " (no [mrclam_filter] / [mrclam_response] section: defaults, nominal response)";
  return estimation::loadCommandDrivenEkfOptions(ini);
}

// The command-driven run on the console: speed, frame, the sightings' NIS table (the common
// SensorStats of Sensor::Landmarks), the command input and the final pose.
void printCommandDrivenRun(const estimation::CommandDrivenEkfResult& res,
                           const estimation::CommandDrivenEkfOptions& opt, const io::Recording& rec,
                           std::size_t landmarks, const std::string& input,
                           const std::string& config_note, double wall_s) {
  const double duration_s = rec.endTime() - rec.startTime();
  const double filtered_s = res.trajectory.back().t_s - res.t_start_s;
  fmt::print(
      "{}: {:.1f} s of recording, command-driven EKF (commands + landmark range-bearing, {} "
      "mapped landmarks), {:.1f} s filtered in {:.3f} s ({:.0f}x real time)\n",
      input, duration_s, landmarks, filtered_s, wall_s, wall_s > 0 ? filtered_s / wall_s : 0.0);
  fmt::print("configuration: {}\n", config_note);
  fmt::print(
      "frame: map (landmark map = Vicon frame for MRCLAM); started at t = {:.3f} s "
      "({:.1f} s into the recording) from two landmark sightings\n",
      res.t_start_s, res.t_start_s - rec.startTime());
  const auto& st = res.landmarks();
  const auto band = st.meanNisBand95();
  fmt::print("{:<9} {:>7} {:>9} {:>9} {:>9} {:>10} {:>14} {:>8} {:>9}\n", "sensor", "used",
             "rejected", "unmapped", "pre-init", "mean NIS", "95% band", "mean ok", "in band");
  fmt::print("{:<9} {:>7} {:>9} {:>9} {:>9} {:>10.3f} {:>6.2f}..{:<6.2f} {:>8} {:>8.1f}%\n",
             "landmarks", st.used, st.rejected, res.unmapped, res.before_start, st.meanNis(),
             band.first, band.second, nisVerdict(st.meanNis(), band, st.nis_count),
             100 * st.fractionInside95());
  fmt::print("{:<9} {:>7} (input: {} (0,0) blips dropped{})\n", "commands", res.commands,
             res.dropped_zero_runs, opt.ignore_zero_runs ? "" : "; ignore_zero_runs off");
  fmt::print(
      "(NIS: range-bearing, 2 dof; mean over the accepted updates, {:.3f} over all {} attempts "
      "incl. gated out; gate chi2(2) at p = {}; 'pre-init': mapped sightings up to the "
      "initialisation; 'unmapped': sightings of other robots, skipped)\n",
      res.mean_nis_all, st.used + st.rejected, opt.gate_probability);
  if (!rec.ground_truth.empty())
    fmt::print(
        "ground truth ({} GROUND_TRUTH poses) not used: compare with `wheelchair evaluate`\n",
        rec.ground_truth.size());
  const auto& f = res.trajectory.back();
  fmt::print(
      "final pose x = {:.3f} +- {:.3f} m, y = {:.3f} +- {:.3f} m, phi = {:.1f} deg (map frame)\n",
      f.x_m, std::sqrt(f.var_x), f.y_m, std::sqrt(f.var_y), f.phi_rad * 180 / M_PI);
}

// The command-driven outputs (library writers): TUM trajectory (map frame, or --frame start),
// estimates CSV, the options used, and the open-loop commands variant.
void writeCommandDrivenOutputs(const FilterCliOptions& o, const io::Recording& rec,
                               const estimation::CommandDrivenEkfResult& res,
                               const estimation::CommandDrivenEkfOptions& opt,
                               const std::string& config_note) {
  const bool start_frame = o.frame == "start";
  const std::string frame_text =
      start_frame ? "frame: start (the first estimated pose, from the landmark initialisation)"
                  : "frame: map (landmark map; the Vicon frame for MRCLAM)";
  const auto framed = [&](const evaluation::Trajectory& t) {
    return start_frame ? evaluation::relativeTo(t, t.front()) : t;
  };
  if (!o.trajectory.empty()) {
    evaluation::writeTum(o.trajectory, framed(evaluation::toTrajectory(res.trajectory)),
                         {"wheelchair filter " + o.input + ": command-driven EKF", frame_text});
    fmt::print("trajectory (TUM, {}): {}\n", start_frame ? "start frame" : "map frame",
               o.trajectory);
  }
  if (!o.estimates.empty()) {
    estimation::writeCommandDrivenCsv(o.estimates, res.trajectory);
    fmt::print("estimates (CSV, map frame): {}\n", o.estimates);
  }
  if (!o.trajectory.empty() || !o.estimates.empty()) {
    const std::string cfg_path =
        (o.trajectory.empty() ? o.estimates : o.trajectory) + ".config.ini";
    util::writeFileAtomically(cfg_path, [&](std::ostream& os) {
      os << fmt::format("# command-driven EKF options used by wheelchair filter {} (from {})\n{}",
                        o.input, config_note, estimation::toIni(opt));
    });
    fmt::print("configuration used: {}\n", cfg_path);
  }
  if (o.variants) {
    const std::string base = o.trajectory.empty() ? "filter.tum" : o.trajectory;
    const auto dr = estimation::deadReckoningCommands(
        rec, opt, res.t_start_s, {res.start_pose_xy(0), res.start_pose_xy(1), res.start_phi_rad},
        res.start_velocity);
    const auto dr_traj = evaluation::toTrajectory(dr);
    const std::string path = withSuffix(base, "_commands");
    evaluation::writeTum(
        path, framed(dr_traj),
        {"wheelchair filter " + o.input +
             ": open-loop dead reckoning of the commands from the EKF's initial pose",
         frame_text});
    fmt::print("open-loop commands variant: {} (d_path {:.2f} m)\n", path,
               evaluation::pathLength(dr_traj));
  }
}

int runCommandDriven(const FilterCliOptions& o, const io::Recording& rec, Progress& progress) {
  const auto fail = [&](const std::string& why) {
    std::cerr << "wheelchair filter: " << o.input << ": " << why << "\n";
    return kExitBadInput;
  };
  std::string config_note;
  const auto opt = commandDrivenOptions(o, config_note);
  if (!opt) return fail("configuration " + o.config_path + ": no such file");
  if (o.pozyx || !o.obstacle_form.empty())
    fmt::print("note: --pozyx / --obstacle-form apply to the wheelchair filters only: ignored\n");
  const auto missing = estimation::missingForCommandDrivenEkf(rec);
  if (!missing.empty()) {
    std::string why =
        "the command-driven EKF (commands + landmark range-bearing, map known) needs ";
    for (std::size_t i = 0; i < missing.size(); ++i) why += (i ? "; " : "") + missing[i];
    why += "; the recording lacks it";
    if (rec.encoders.empty() && rec.imu.empty() && rec.sonar.empty())
      why += " (and it has no encoder/gyro/sonar measurements for the wheelchair filter)";
    return fail(why);
  }
  const auto map = io::landmarkMap(rec);
  const auto t0 = std::chrono::steady_clock::now();
  const auto res = estimation::runCommandDrivenEkf(
      rec, map, *opt, [&](double f) { progress.update(f, "filtering"); });
  progress.stop();
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!res.initialised)
    return fail(fmt::format(
        "the command-driven EKF could not initialise: no two sightings of mapped landmarks at "
        "least {} m apart within {} s ({} sightings of mapped landmarks, {} of unmapped "
        "subjects)",
        opt->init_min_separation_m, opt->init_window_s, rec.landmarks.size() - res.unmapped,
        res.unmapped));
  printCommandDrivenRun(res, *opt, rec, map.size(), o.input, config_note, wall_s);
  writeCommandDrivenOutputs(o, rec, res, *opt, config_note);
  return kExitOk;
}

// The run on the console: speed, the per-sensor NIS table and verdicts, CVODE statistics,
// warnings, the final sensor errors, the health events and the final pose.
void printRun(const estimation::EstimationResult& res, const estimation::EkfOptions& opt,
              const io::RecordingSummary& sum, const std::string& input, double wall_s) {
  const double duration_s = sum.end_s - sum.start_s;
  long measurements = 0;
  fmt::print("{}: {:.1f} s of recording, {} filter, processed in {:.3f} s ({:.0f}x real time)\n",
             input, duration_s, res.filter, wall_s, wall_s > 0 ? duration_s / wall_s : 0.0);
  fmt::print("{:<9} {:>7} {:>9} {:>9} {:>9} {:>10} {:>14} {:>8} {:>9}\n", "sensor", "used",
             "rejected", "dropouts", "skipped", "mean NIS", "95% band", "mean ok", "in band");
  for (int s = 0; s < estimation::kNumSensors; ++s) {
    const auto& st = res.sensors[s];
    measurements += st.used + st.rejected + st.dropouts;
    if (!st.used && !st.rejected && !st.dropouts && !st.skipped) continue;
    const auto band = st.meanNisBand95();
    fmt::print("{:<9} {:>7} {:>9} {:>9} {:>9} {:>10.3f} {:>6.2f}..{:<6.2f} {:>8} {:>8.1f}%\n",
               estimation::sensorName(static_cast<estimation::Sensor>(s)), st.used, st.rejected,
               st.dropouts, st.skipped, st.meanNis(), band.first, band.second,
               nisVerdict(st.meanNis(), band, st.nis_count), 100 * st.fractionInside95());
  }
  fmt::print(
      "(mean NIS over the accepted updates; 95% band of that mean for a consistent filter; "
      "'in band': share of single NIS values inside chi2(dof)'s two-sided 95% interval)\n");
  for (const auto& v : estimation::sensorVerdicts(res, opt.gate_probability))
    fmt::print("verdict: {}\n", v);
  if (const auto& p = res.stats(estimation::Sensor::Pozyx); p.inflated > 0)
    fmt::print(
        "pozyx: the filter had drifted {} times (after {} consecutive gated readings each): "
        "position covariance inflated until the reading fitted, then applied\n",
        p.inflated, opt.pozyx_inflate_after_rejections);
  if (res.cvode.intervals > 0) {
    const auto& c = res.cvode;
    fmt::print(
        "CVODE: {} intervals ({} restarts), {:.2f} steps, {:.2f} f-evaluations and {:.2f} "
        "error-test failures per interval\n",
        c.intervals, c.restarts, double(c.steps) / c.intervals, double(c.rhs_evals) / c.intervals,
        double(c.error_test_fails) / c.intervals);
  }
  for (const auto& w : res.warnings) fmt::print("warning: {}\n", w);
  if (const auto& e = res.sensor_errors; e.present)
    fmt::print(
        "sensor errors at the end: encoder scale right {:.4f} +- {:.4f}, left {:.4f} +- {:.4f} "
        "(reported / true), gyro bias {:.5f} +- {:.5f} rad/s\n",
        e.encoder_scale_right, e.encoder_scale_right_sd, e.encoder_scale_left,
        e.encoder_scale_left_sd, e.gyro_bias_rad_s, e.gyro_bias_sd_rad_s);
  for (const auto& e : res.health)
    fmt::print("health: t = {:.1f} s: {}\n", e.t_s - sum.start_s, e.text);
  if (res.n_estimates > 0) {
    const auto& f = res.final();
    fmt::print("final pose x = {:.3f} +- {:.3f} m, y = {:.3f} +- {:.3f} m, phi = {:.1f} deg\n",
               f.x(2), f.sd(2), f.x(3), f.sd(3), f.x(4) * 180 / M_PI);
  }
}

// The health events as JSON lines (one object per event), committed complete or not at all.
void writeHealth(util::AtomicFile& file, const std::string& path,
                 const estimation::EstimationResult& res) {
  for (const auto& e : res.health) file.stream() << healthJsonLine(e) << "\n";
  file.commit();
  fmt::print("health events (JSON lines): {} ({} events)\n", path, res.health.size());
}

// The paper's Fig. 5 variants (encoders only; encoder v + gyro omega) as TUM files next to
// the trajectory, one at a time, each pose written as it is produced.
void writeVariants(const FilterCliOptions& o, const io::RecordingSummary& sum,
                   const config::WheelchairConfig& cfg, const std::optional<io::Recording>& rec) {
  const std::string base = o.trajectory.empty() ? "filter.tum" : o.trajectory;
  // One variant at a time, each pose written as it is produced (streamed from the rawlog
  // unless the model extensions hold a corrected recording).
  const auto writeVariant = [&](const std::string& path, bool with_gyro) {
    evaluation::TumWriter tum(path);
    const auto add = [&](const estimation::DeadReckoningSample& p) {
      tum.add({p.t_s, p.x_m, p.y_m, p.phi_rad});
    };
    double d_path = 0;
    if (rec) {
      const auto& p = cfg.encoders.params;
      const auto dr =
          with_gyro
              ? estimation::deadReckoningEncoderGyro(rec->encoders, rec->imu, p, cfg.vehicle.geom)
              : estimation::deadReckoningEncoders(rec->encoders, p, cfg.vehicle.geom);
      for (const auto& x : dr) add(x);
      d_path = estimation::pathLength(dr);
    } else {
      d_path = estimation::deadReckonRawlog(o.input, sum, with_gyro, cfg.encoders.params,
                                            cfg.vehicle.geom, add)
                   .path_m;
    }
    tum.commit();
    return d_path;
  };
  const double d_enc = writeVariant(withSuffix(base, "_encoders"), false);
  const double d_encg = writeVariant(withSuffix(base, "_encoders_gyro"), true);
  fmt::print("Fig. 5 variants: {} (d_path {:.2f} m), {} (d_path {:.2f} m)\n",
             withSuffix(base, "_encoders"), d_enc, withSuffix(base, "_encoders_gyro"), d_encg);
}

// The wheelchair filters' configuration: --config and the flags; `notes` to print before the
// run's table.
struct FilterSetup {
  config::WheelchairConfig cfg;
  estimation::EkfOptions opt;
  std::vector<std::string> notes;
};

FilterSetup loadSetup(const FilterCliOptions& o) {
  FilterSetup s;
  auto& cfg = s.cfg;
  if (!o.config_path.empty()) cfg = config::WheelchairConfig::load(o.config_path);
  if (!o.filter.empty()) cfg.set("estimator", "filter", o.filter);
  if (!o.obstacle_form.empty()) cfg.set("estimator", "obstacle_form", o.obstacle_form);
  if (o.pozyx) cfg.set("estimator", "use_pozyx", "1");
  s.opt.loadFromConfig(cfg.ini());
  if (!o.health.empty() && !s.opt.estimate_encoder_scales) {
    // The monitor estimates the faults through the sensor-error states.
    cfg.set("estimator", "estimate_encoder_scales", "1");
    s.opt.estimate_encoder_scales = true;
    s.notes.push_back("--health switches estimate_encoder_scales on");
  }
  s.opt.resolveSensorDefaults(cfg);
  return s;
}

// Fused, the Pozyx is no longer an independent ground truth for these estimates.
const char* const kFusedNote =
    "Pozyx fused (use_pozyx = 1): not an independent ground truth for these estimates; "
    "evaluate against a GROUND_TRUTH stream or the simulator's truth (evaluate --truth)";

// The output files, streamed while the filter runs (memory flat in the drive's length); their
// temporaries are created first, so a bad path fails before the run. Destroyed without
// commit(), they leave nothing behind.
struct FilterOutputs {
  FilterOutputs(const FilterCliOptions& o, bool pozyx_fused) {
    if (!o.trajectory.empty())
      tum.emplace(o.trajectory,
                  pozyx_fused ? std::vector<std::string>{kFusedNote} : std::vector<std::string>{});
    if (!o.estimates.empty()) csv.emplace(o.estimates);
    if (!o.health.empty()) health.emplace(o.health);
    sinks.emplace(
        std::vector<estimation::EstimateSink*>{tum ? &*tum : nullptr, csv ? &*csv : nullptr});
  }
  std::optional<evaluation::TumEstimateSink> tum;
  std::optional<estimation::EstimatesCsvWriter> csv;
  std::optional<util::AtomicFile> health;
  std::optional<estimation::EstimateFanOut> sinks;  ///< both files
};

// After the run: the console report, then the files are completed.
int finishFilter(const FilterCliOptions& o, const FilterSetup& setup,
                 const estimation::EstimationResult& res, const io::RecordingSummary& sum,
                 const std::optional<io::Recording>& rec, bool pozyx_fused, FilterOutputs& out,
                 double wall_s) {
  printRun(res, setup.opt, sum, o.input, wall_s);
  if (pozyx_fused) fmt::print("note: {}\n", kFusedNote);
  if (out.health) writeHealth(*out.health, o.health, res);

  if (out.tum) {
    out.tum->commit();
    fmt::print("trajectory (TUM, start frame: the body at the first sample): {}\n", o.trajectory);
  }
  if (out.csv) {
    out.csv->commit();
    fmt::print("estimates (CSV): {}\n", o.estimates);
  }
  if (!o.trajectory.empty() || !o.estimates.empty()) {
    const std::string cfg_path =
        (o.trajectory.empty() ? o.estimates : o.trajectory) + ".config.ini";
    setup.cfg.save(cfg_path);
    fmt::print("configuration used: {}\n", cfg_path);
  }
  if (o.variants) writeVariants(o, sum, setup.cfg, rec);
  return kExitOk;
}

bool lacksFilterStreams(const io::RecordingSummary& sum, const estimation::EkfOptions& opt) {
  using io::StreamKind;
  return (!opt.use_encoders || sum.count(StreamKind::Encoders) < 2) &&
         (!opt.use_gyro || !sum.count(StreamKind::Imu)) &&
         (!opt.use_sonar || !sum.count(StreamKind::Sonar)) &&
         (!opt.use_pozyx || !sum.count(StreamKind::Pozyx));
}

// The common case read once (estimation::runEstimatorOnePass: no scan first, ~0.3 s less per
// recorded hour): a time-ordered file for the wheelchair filters, no model extensions.
// nullopt (nothing printed, no file written) whenever the result could differ from the
// general path below -- a file out of time order or without motor currents, one the command-
// driven EKF or nothing at all would take, a break without --salvage, any error: runFilter
// then does it all again the general way, which also gives the errors their usual words.
std::optional<int> runFilterOnePass(const FilterCliOptions& o, Progress& progress) {
  if (o.filter == "command") return std::nullopt;
  try {
    const FilterSetup setup = loadSetup(o);
    if (!estimation::ModelExtensions::fromConfig(setup.cfg.ini()).empty()) return std::nullopt;
    const bool pozyx_guess = setup.opt.use_pozyx;  // checked against the file below
    FilterOutputs out(o, pozyx_guess);
    io::RecordingSummary sum;
    const auto t0 = std::chrono::steady_clock::now();
    const auto bar = [&](double f) { progress.update(f, "filtering"); };
    const auto res =
        estimation::runEstimatorOnePass(o.input, setup.cfg, setup.opt, *out.sinks, sum, bar);
    progress.stop();
    const double wall_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (!res ||
        estimation::selectEstimator(sum, o.filter) == estimation::EstimatorFamily::CommandDriven ||
        lacksFilterStreams(sum, setup.opt) ||
        pozyx_guess != (setup.opt.use_pozyx && sum.count(io::StreamKind::Pozyx) > 0))
      return std::nullopt;
    if (sum.report.broken) {  // throws without --salvage: the general path says so
      const std::string w = io::salvageOrThrow(o.input, *sum.report.broken, sum.size(), o.salvage);
      std::cerr << "wheelchair filter: warning: " << w << "\n";
    }
    for (const auto& n : setup.notes) fmt::print("note: {}\n", n);
    return finishFilter(o, setup, *res, sum, std::nullopt, pozyx_guess, out, wall_s);
  } catch (const std::exception&) {
    progress.stop();
    return std::nullopt;
  }
}

int runFilter(const FilterCliOptions& o) {
  Progress progress(!o.no_progress && isatty(STDERR_FILENO));
  if (const auto done = runFilterOnePass(o, progress)) return *done;
  progress.tick("reading");
  // Pass 1 over the file: what it holds, where it breaks (the salvage rule applies here), how
  // far out of time order it is. The wheelchair filters then read it again as a stream
  // (memory flat in the drive's length, io/RawlogStream.h).
  std::string salvaged;
  const io::RecordingSummary sum = io::scanRawlogSalvaging(o.input, o.salvage, &salvaged);
  progress.stop();
  if (!salvaged.empty()) std::cerr << "wheelchair filter: warning: " << salvaged << "\n";
  // The whole recording, where a path needs it (damage already accepted above).
  const auto readAll = [&] { return io::readRawlogSalvaging(o.input, true, nullptr); };
  if (estimation::selectEstimator(sum, o.filter) == estimation::EstimatorFamily::CommandDriven)
    return runCommandDriven(o, readAll(), progress);

  FilterSetup setup = loadSetup(o);
  for (const auto& n : setup.notes) fmt::print("note: {}\n", n);
  auto& cfg = setup.cfg;
  const auto& opt = setup.opt;
  if (lacksFilterStreams(sum, opt)) {
    std::cerr << "wheelchair filter: " << o.input << ": "
              << missingForWheelchairFilter(readAll(), opt) << "\n";
    return kExitBadInput;
  }
  // A corrected configuration (`wheelchair diagnose --write-config`) calibrates the sensors
  // and the drive train before filtering (estimation/ModelExtensions.h): that path holds the
  // corrected recording in memory.
  std::optional<io::Recording> rec;
  const auto ext = estimation::ModelExtensions::fromConfig(cfg.ini());
  if (!ext.empty()) {
    cfg = ext.adjustConfig(cfg);
    rec = ext.apply(readAll(), cfg);
    fmt::print("model extensions applied: {}\n", ext.summary());
  }
  const bool pozyx_fused = opt.use_pozyx && sum.count(io::StreamKind::Pozyx) > 0;
  FilterOutputs out(o, pozyx_fused);
  const auto t0 = std::chrono::steady_clock::now();
  const estimation::EstimationResult res = [&] {
    try {  // name the file: runEstimator names the sample and time of a failure
      const auto bar = [&](double f) { progress.update(f, "filtering"); };
      return rec ? estimation::runEstimator(*rec, cfg, opt, *out.sinks, bar)
                 : estimation::runEstimator(o.input, sum, cfg, opt, *out.sinks, bar);
    } catch (const std::exception& e) {
      throw std::runtime_error(o.input + ": " + e.what());
    }
  }();
  progress.stop();
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return finishFilter(o, setup, res, sum, rec, pozyx_fused, out, wall_s);
}

const RegisterCommand reg{Command{
    "filter",
    "Replay a rawlog through the estimator (CVODE-integrated EKF or baseline; command-driven "
    "EKF for landmark recordings such as MRCLAM)",
    [](CLI::App& sub) -> std::function<int()> {
      auto o = std::make_shared<FilterCliOptions>();
      sub.add_option("input", o->input, "Input rawlog")->required();
      sub.add_option("--config", o->config_path, "Configuration INI (default: nominal)");
      sub.add_option("--trajectory", o->trajectory,
                     "Write the estimated body pose (TUM: t x y z qx qy qz qw, start frame)");
      sub.add_option("--estimates", o->estimates,
                     "Write v, omega, x, y, phi, obstacle x, y, distance and their sigmas (CSV)");
      sub.add_flag("--variants", o->variants,
                   "Also write the Fig. 5 raw variants: encoders only, encoder v + gyro omega");
      sub.add_option("--filter", o->filter,
                     "physics (default), baseline, or command (the command-driven EKF; default "
                     "for recordings with landmark sightings / a landmark map, e.g. MRCLAM)")
          ->check(CLI::IsMember({"physics", "baseline", "command"}));
      sub.add_option("--frame", o->frame,
                     "Command-driven EKF output frame: map (default; MRCLAM: Vicon frame) or "
                     "start (the first estimated pose)")
          ->check(CLI::IsMember({"map", "start"}));
      sub.add_flag("--no-progress", o->no_progress,
                   "No progress display on stderr (it is shown only when stderr is a terminal)");
      sub.add_option("--obstacle-form", o->obstacle_form, "cartesian (7) or polar (8)")
          ->check(CLI::IsMember({"cartesian", "polar"}));
      sub.add_flag("--pozyx", o->pozyx, "Also fuse Pozyx positions (off: they are ground truth)");
      sub.add_flag("--salvage", o->salvage, kSalvageHelp);
      sub.add_option("--health", o->health,
                     "Model-health events as JSON lines {t_s, sensor, kind, effect, side, "
                     "parameter, value, sd, since_s, text} (switches estimate_encoder_scales on)");
      return [o] { return runFilter(*o); };
    }}};

}  // namespace
}  // namespace wheelchair::cli
