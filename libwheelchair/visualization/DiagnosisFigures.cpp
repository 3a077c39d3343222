#include "libwheelchair/visualization/DiagnosisFigures.h"

#include "libwheelchair/util/AtomicFile.h"
#include "libwheelchair/util/OutputDir.h"

#include "libwheelchair/estimation/DeadReckoning.h"
#include "libwheelchair/estimation/ModelExtensions.h"
#include "libwheelchair/evaluation/Association.h"
#include "libwheelchair/evaluation/Metrics.h"
#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/model/DriveDynamics.h"
#include "libwheelchair/sensors/Encoders.h"
#include "libwheelchair/sensors/Filtering.h"
#include "libwheelchair/signals/DriveSignals.h"
#include "libwheelchair/visualization/DriveData.h"
#include "libwheelchair/visualization/Plot.h"
#include "libwheelchair/visualization/Scene3D.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <stdexcept>

namespace wheelchair::visualization {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr double kDeg = 180.0 / M_PI;

// Colours of the two models in the time plots: the nominal one wide and light underneath, the
// corrected one thin and dark on top, so both stay visible where they coincide.
constexpr Color kBefore{240, 140, 0};
constexpr Color kAfter{30, 80, 220};

Color lighter(Color c, double a) {  // c over white with opacity a
  auto f = [&](uint8_t v) { return static_cast<uint8_t>(std::lround(255 + a * (v - 255.0))); };
  return Color{f(c.r), f(c.g), f(c.b)};
}

/// A JSON value for a Markdown cell.
std::string cell(const json& v) {
  if (v.is_null()) return "–";
  if (v.is_boolean()) return v.get<bool>() ? "yes" : "no";
  if (v.is_number_integer()) return std::to_string(v.get<long long>());
  if (v.is_number()) {
    const double d = v.get<double>();
    if (!std::isfinite(d)) return "–";
    if (d != 0 && (std::fabs(d) < 1e-3 || std::fabs(d) >= 1e5)) return fmt::format("{:.4g}", d);
    return fmt::format("{:.4f}", d);
  }
  if (v.is_string()) return v.get<std::string>();
  if (v.is_array()) {
    std::string s;
    for (const auto& e : v) s += (s.empty() ? "" : ", ") + cell(e);
    return s;
  }
  return v.dump();
}

std::string num(double v, int p = 3) {
  return std::isfinite(v) ? fmt::format("{:.{}f}", v, p) : "–";
}

struct Stats {
  double mean = NAN, rms = NAN;
  std::size_t n = 0;
};

Stats statsIn(const ResidualSeries& s, double a, double b) {
  Stats st;
  double sum = 0, sq = 0;
  for (std::size_t i = 0; i < s.t_s.size(); ++i)
    if (s.t_s[i] >= a && s.t_s[i] <= b && std::isfinite(s.r[i]))
      sum += s.r[i], sq += s.r[i] * s.r[i], ++st.n;
  if (st.n) st.mean = sum / st.n, st.rms = std::sqrt(sq / st.n);
  return st;
}

/// Strictly increasing copy (later duplicates dropped) of parallel columns, by time.
template <class S, class F>
std::vector<S> sortedUnique(std::vector<S> v, F time) {
  std::stable_sort(v.begin(), v.end(), [&](const S& a, const S& b) { return time(a) < time(b); });
  std::vector<S> out;
  for (const auto& s : v)
    if (out.empty() || time(s) > time(out.back())) out.push_back(s);
  return out;
}

/// The effects that have no inverse on a recording but change the drive model (registry:
/// correctionPhase() none and a different drive train after actOnTruth, e.g. ground_slope).
std::vector<effects::EffectSpec> modelOnlyEffects(const std::vector<effects::EffectSpec>& all) {
  std::vector<effects::EffectSpec> out;
  for (const auto& e : all) {
    const effects::Effect* eff = effects::findEffect(e.id);
    if (!eff || eff->correctionPhase() != effects::CorrectionPhase::none) continue;
    effects::TruthModel a, b;
    eff->actOnTruth(e, b);
    if (b.drive.slope_rad != a.drive.slope_rad ||
        b.drive.downhill_heading_rad != a.drive.downhill_heading_rad)
      out.push_back(e);
  }
  return out;
}

/// Whether an effect acts on the power module's response to the commands (actuator_lag).
bool actsOnCommands(const effects::EffectSpec& e) {
  const effects::Effect* eff = effects::findEffect(e.id);
  if (!eff) return false;
  effects::TruthModel a, b;
  eff->actOnTruth(e, b);
  return a.actuator_delay_s != b.actuator_delay_s ||
         a.actuator_time_constant_s != b.actuator_time_constant_s;
}

/// The command-response stage(s) of a diagnosis JSON (objects with "stage": "command_response").
void findStages(const json& j, std::vector<const json*>& out) {
  if (j.is_object()) {
    if (j.value("stage", std::string()) == "command_response") {
      out.push_back(&j);
      return;
    }
    for (const auto& [k, v] : j.items()) findStages(v, out);
  } else if (j.is_array()) {
    for (const auto& v : j) findStages(v, out);
  }
}

/// Y range with room at the top for the legend (`top` = fraction of the data span added).
std::pair<double, double> paddedRange(const std::vector<const ResidualSeries*>& ss, double top) {
  double lo = 1e300, hi = -1e300;
  for (const auto* s : ss)
    for (double v : s->r)
      if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
  if (lo > hi) return {-1, 1};
  lo = std::min(lo, 0.0), hi = std::max(hi, 0.0);
  double span = hi - lo;
  if (span <= 0) span = 1e-3;
  return {lo - 0.06 * span, hi + top * span};
}

struct TimeFigure {
  std::string title, ylabel, unit;
  const ResidualSeries* before = nullptr;
  const ResidualSeries* after = nullptr;
  double t0 = 0;                       ///< subtracted from the times
  double val0 = -1e300, val1 = 1e300;  ///< validation window (recording clock)
  std::optional<double> fit_end;       ///< shaded fit part [t0, fit_end]
  std::string before_label = "nominal model", after_label = "corrected model";
  std::string xnote;  ///< appended to the x label
};

void drawTimeFigure(const TimeFigure& f, const std::string& png, int w, int h) {
  Plot p;
  p.title = f.title;
  std::string notes = f.fit_end ? "shaded: fitted on, not validation" : "";
  if (!f.xnote.empty()) notes += (notes.empty() ? "" : "; ") + f.xnote;
  p.xlabel = "time since start (s)" + (notes.empty() ? "" : "      (" + notes + ")");
  p.ylabel = f.ylabel;
  p.legend = LegendPosition::TopRight;
  if (f.fit_end) p.spans.push_back({0.0, *f.fit_end - f.t0, "", Color{228, 228, 238}});
  auto series = [&](const ResidualSeries& s, const std::string& label, Color c, double width) {
    const Stats st = statsIn(s, f.val0, f.val1);
    Series out;
    out.label =
        fmt::format("{}: validation mean {:+.3g}, RMS {:.3g} {}", label, st.mean, st.rms, f.unit);
    out.color = c;
    out.width_px = width;
    for (std::size_t i = 0; i < s.t_s.size(); ++i)
      out.x.push_back(s.t_s[i] - f.t0), out.y.push_back(s.r[i]);
    return out;
  };
  double x0 = 1e300, x1 = -1e300;
  for (const auto* s : {f.before, f.after})
    if (s && !s->t_s.empty())
      x0 = std::min(x0, s->t_s.front() - f.t0), x1 = std::max(x1, s->t_s.back() - f.t0);
  if (x0 < x1) {
    Series zero{"", {x0, x1}, {0.0, 0.0}, colors::black, LineStyle::Dotted, 1.0};
    p.series.push_back(zero);
  }
  if (f.before) p.series.push_back(series(*f.before, f.before_label, kBefore, 3.4));
  if (f.after) p.series.push_back(series(*f.after, f.after_label, kAfter, 1.4));
  std::vector<const ResidualSeries*> ss;
  for (const auto* s : {f.before, f.after})
    if (s) ss.push_back(s);
  p.y_range = paddedRange(ss, 0.45);
  p.save(png, w, h);
}

Series trajSeries(const evaluation::Trajectory& t, const std::string& variant, bool after) {
  Series s;
  s.label = variantLabel(variant) + (after ? ", corrected model" : ", nominal model");
  const Color c = variant == "ekf" ? Color{20, 20, 20} : variantColor(variant);
  s.color = after ? c : lighter(c, 0.55);
  s.line = after ? LineStyle::Solid : LineStyle::Dashed;
  // Widths decrease in drawing order (encoders, encoders + gyro, EKF) so that curves lying on
  // top of each other (the usual case after a good correction) all stay visible as bands.
  const double w = variant == "encoders" ? 4.2 : (variant == "encoders_gyro" ? 2.7 : 1.3);
  s.width_px = after ? w : w + 0.6;
  for (const auto& p : t) s.x.push_back(p.x_m), s.y.push_back(p.y_m);
  return s;
}

struct TrajRow {
  std::string variant;
  evaluation::Metrics before, after;
};

struct RecordingFigures {
  std::string path, suffix;
  bool drawn = false;
  std::string why_not;
  std::vector<std::pair<std::string, std::string>> figures;  // file, caption
  std::vector<TrajRow> traj;
  std::string gt_note;
  std::map<std::string, std::pair<Stats, Stats>> residual_stats;  // channel -> before, after
};

/// Ground truth in the start frame for the trajectory figure and metrics (see the header).
std::vector<evaluation::Position2DStamped> groundTruthInStartFrame(const DriveData& after,
                                                                   const DiagnosisFigureOptions& o,
                                                                   Eigen::Vector2d& lever,
                                                                   std::string& note) {
  std::vector<evaluation::Position2DStamped> out;
  lever = after.gt.lever_arm_m;
  if (after.truth && !after.truth->t_s.empty()) {
    for (std::size_t i = 0; i < after.truth->t_s.size(); ++i)
      out.push_back(
          {after.truth->t_s[i], after.truth->x_m[i], after.truth->y_m[i], after.truth->phi_rad[i]});
    lever = Eigen::Vector2d::Zero();
    note = "the simulator's true path";
    return out;
  }
  if (after.gt.samples.empty()) return out;
  const evaluation::Trajectory* ref = nullptr;
  for (const char* v : {"ekf", "encoders_gyro", "encoders"})
    if (after.trajectories.count(v) && !after.trajectories.at(v).empty()) {
      ref = &after.trajectories.at(v);
      note = std::string("recording's ") + evaluation::toString(after.gt.source) +
             " mapped into the start frame by the SE(2) alignment of the corrected " +
             variantLabel(v) + fmt::format(" over the first {:.0f} s", o.align_first_s);
      break;
    }
  if (!ref) return out;
  evaluation::MetricOptions mo;
  mo.alignment = evaluation::Alignment::SE2FirstSeconds;
  mo.align_first_s = o.align_first_s;
  mo.lever_arm_m = lever;
  const auto m = evaluation::computeMetrics(*ref, after.gt.samples, mo);
  if (m.n_matched == 0) return out;
  const evaluation::SE2 T_inv = m.alignment.inverse();
  for (const auto& s : after.gt.samples) {
    const Eigen::Vector2d p = T_inv.apply({s.x_m, s.y_m});
    out.push_back(
        {s.t_s, p.x(), p.y(), s.hasHeading() ? T_inv.applyHeading(s.phi_rad) : s.phi_rad});
  }
  return out;
}

void trajectoryFigure(const DriveData& before, const DriveData& after,
                      const std::vector<evaluation::Position2DStamped>& gt, bool gt_is_truth,
                      const std::string& png, int w, int h) {
  Plot p;
  p.title = "Trajectories with the nominal (dashed) and the corrected (solid) model";
  p.xlabel = "x (m), start frame";
  p.ylabel = "y (m)";
  p.equal_aspect = true;
  p.legend = LegendPosition::Outside;
  if (!gt.empty()) {
    Series s;
    if (gt_is_truth) {
      s.label = "true path (simulation)";
      s.line = LineStyle::Solid;
      s.width_px = 7.0;
      s.color = Color{245, 185, 185};
    } else {
      s.label = "ground truth (tag positions)";
      s.line = LineStyle::None;
      s.marker = Marker::Dot;
      s.marker_size_px = 2.5;
      s.color = Color{240, 120, 120};
    }
    for (const auto& g : gt) s.x.push_back(g.x_m), s.y.push_back(g.y_m);
    p.series.push_back(s);
  }
  // Nominal curves first (wide, light, dashed), corrected ones on top (narrower, solid), so a
  // corrected curve that coincides with its nominal one leaves the nominal visible around it.
  for (const bool is_after : {false, true})
    for (const std::string v : {"encoders", "encoders_gyro", "ekf"}) {
      const DriveData& d = is_after ? after : before;
      if (d.trajectories.count(v))
        p.series.push_back(trajSeries(d.trajectories.at(v), v, is_after));
    }
  for (const std::string v : {"encoders", "encoders_gyro", "ekf"})
    for (const DriveData* d : {&before, &after}) {
      auto it = d->trajectories.find(v);
      if (it == d->trajectories.end() || it->second.empty()) continue;
      const Color c = v == "ekf" ? Color{20, 20, 20} : variantColor(v);
      p.series.push_back({"",
                          {it->second.back().x_m},
                          {it->second.back().y_m},
                          d == &after ? c : lighter(c, 0.55),
                          LineStyle::None,
                          2,
                          Marker::Circle,
                          8});
    }
  p.series.push_back(
      {"start", {0.0}, {0.0}, Color{230, 0, 0}, LineStyle::None, 2, Marker::Square, 11});
  p.series.push_back(
      {"end of each trajectory", {}, {}, colors::gray, LineStyle::None, 2, Marker::Circle, 8});
  p.save(png, w + 300, h + 60);
}

/// Position error against the ground truth over time, per variant, nominal and corrected.
/// Noisy tag positions are smoothed (centred 1 s mean); curves far above the corrected ones
/// leave the plot at the top (their maximum is in the legend).
void trajectoryErrorFigure(const DriveData& before, const DriveData& after,
                           const std::vector<evaluation::Position2DStamped>& gt, bool gt_is_truth,
                           const Eigen::Vector2d& lever, double t0, const std::string& png, int w,
                           int h) {
  Plot p;
  p.title = "Position error: nominal (dashed) vs corrected model (solid)";
  p.xlabel = gt_is_truth ? "time since start (s)"
                         : "time since start (s)      (error to the tag positions, 1 s mean)";
  p.ylabel = "position error (m)";
  p.legend = LegendPosition::Outside;
  struct Curve {
    Series s;
    double max = 0;
    bool after = false;
  };
  std::vector<Curve> curves;
  for (const bool is_after : {false, true})
    for (const std::string v : {"encoders", "encoders_gyro", "ekf"}) {
      const DriveData& d = is_after ? after : before;
      if (!d.trajectories.count(v)) continue;
      const auto a = evaluation::associate(d.trajectories.at(v), gt, 0.5, lever);
      if (a.t.empty()) continue;
      std::vector<double> e(a.t.size());
      for (std::size_t i = 0; i < e.size(); ++i) e[i] = (a.est[i] - a.gt[i]).norm();
      if (!gt_is_truth) {  // centred moving mean over 1 s
        std::vector<double> m(e.size());
        std::size_t lo = 0, hi = 0;
        double sum = 0;
        for (std::size_t i = 0; i < e.size(); ++i) {
          while (hi < e.size() && a.t[hi] <= a.t[i] + 0.5) sum += e[hi++];
          while (a.t[lo] < a.t[i] - 0.5) sum -= e[lo++];
          m[i] = sum / (hi - lo);
        }
        e = m;
      }
      Curve c;
      c.s = trajSeries({}, v, is_after);
      c.after = is_after;
      for (std::size_t i = 0; i < e.size(); ++i) {
        c.s.x.push_back(a.t[i] - t0), c.s.y.push_back(e[i]);
        c.max = std::max(c.max, e[i]);
      }
      curves.push_back(c);
    }
  if (curves.empty()) return;
  // Scale: drop the largest error from the range while it is more than 4 x the next one (an
  // odometry that runs away would flatten everything else).
  std::vector<double> maxima;
  for (const auto& c : curves) maxima.push_back(c.max);
  std::sort(maxima.rbegin(), maxima.rend());
  std::size_t top = 0;
  while (top + 1 < maxima.size() && maxima[top] > 4 * maxima[top + 1]) ++top;
  const double ytop = std::max(1e-3, maxima[top] * 1.08);
  p.y_range = std::make_pair(0.0, ytop);
  for (auto& c : curves) {
    if (c.max > ytop) c.s.label += fmt::format(" (leaves the plot, up to {:.2f} m)", c.max);
    p.series.push_back(c.s);
  }
  p.save(png, w + 420, h);
}

evaluation::Metrics trajMetrics(const evaluation::Trajectory& t,
                                const std::vector<evaluation::Position2DStamped>& gt,
                                const Eigen::Vector2d& lever) {
  evaluation::MetricOptions mo;
  mo.alignment = evaluation::Alignment::None;  // gt is already in the start frame
  mo.lever_arm_m = lever;
  return evaluation::computeMetrics(t, gt, mo);
}

/// The trajectory figures of one recording (and the metrics against its ground truth).
void trajectoryFigures(const DriveData& before, const DriveData& after, double t0,
                       const std::string& name, const std::string& suffix,
                       const DiagnosisFigureOptions& o, RecordingFigures& rf) {
  auto file = [&](const std::string& stem) { return stem + suffix + ".png"; };
  auto out = [&](const std::string& f) { return (fs::path(o.out_dir) / f).string(); };
  Eigen::Vector2d lever;
  const auto gt = groundTruthInStartFrame(after, o, lever, rf.gt_note);
  const bool gt_truth = after.truth && !after.truth->t_s.empty();
  trajectoryFigure(before, after, gt, gt_truth, out(file("trajectories")), o.width, o.height);
  rf.figures.push_back(
      {file("trajectories"),
       "Trajectories of " + name +
           ": encoder odometry (blue), encoder v + gyro omega (green) and the EKF (black), each "
           "with the nominal model (dashed, light) and the corrected one (solid); " +
           (gt.empty() ? std::string("no ground truth in this recording")
                       : "ground truth: " + rf.gt_note) +
           "."});
  if (!gt.empty()) {
    for (const std::string v : {"encoders", "encoders_gyro", "ekf"})
      if (before.trajectories.count(v) && after.trajectories.count(v))
        rf.traj.push_back({v, trajMetrics(before.trajectories.at(v), gt, lever),
                           trajMetrics(after.trajectories.at(v), gt, lever)});
    trajectoryErrorFigure(before, after, gt, gt_truth, lever, t0, out(file("trajectory_error")),
                          o.width, o.height);
    rf.figures.push_back(
        {file("trajectory_error"),
         "Position error of each trajectory of " + name +
             " against the ground truth over time (same colours and dashes as the trajectory "
             "figure); " +
             (gt_truth ? std::string("exact errors to the simulator's true path")
                       : "errors to the noisy tag positions, centred 1 s mean") +
             ". Curves far above the corrected ones leave the plot at the top (their maximum "
             "is in the legend)."});
  }
}

RecordingFigures recordingFigures(const std::string& path, const std::string& suffix,
                                  const config::WheelchairConfig& input_cfg,
                                  const config::WheelchairConfig& corrected_cfg, bool heldout,
                                  const DiagnosisFigureOptions& o) {
  RecordingFigures rf;
  rf.path = path;
  rf.suffix = suffix;
  const io::Recording raw = io::readRawlog(path);
  if (raw.encoders.size() < 3 || raw.motors.size() < 3) {
    rf.why_not =
        "no encoder and motor-current streams (a command-driven recording): the "
        "residual and trajectory figures are made for the currents-driven form only";
    return rf;
  }
  rf.drawn = true;
  io::Recording corrected;
  config::WheelchairConfig corrected_adj;
  applyCorrection(raw, corrected_cfg, corrected, corrected_adj);
  // Effects without an inverse on the data act on the corrected model instead (ground_slope).
  const auto in_model =
      modelOnlyEffects(estimation::ModelExtensions::fromConfig(corrected_cfg.ini()).effects);
  std::string in_model_words;
  for (const auto& e : in_model) in_model_words += ", " + e.id + " in the model";

  evaluation::MetricOptions mo;
  mo.alignment = evaluation::Alignment::SE2FirstSeconds;
  mo.align_first_s = o.align_first_s;
  // One read of the rawlog serves the residuals and both trajectory sets.
  const DriveData before = loadDrive(raw, path, input_cfg, mo);
  const DriveData after = loadDrive(raw, path, corrected_cfg, mo);
  const double t0 = before.t0_s;
  const double tb = raw.startTime(), te = raw.endTime();
  TimeFigure base;
  base.t0 = t0;
  if (heldout) {
    base.fit_end = tb + o.diagnosis_options.fit_fraction * (te - tb);
    base.val0 = *base.fit_end;
  }
  const std::string name = fs::path(path).filename().string();
  const std::string val_words =
      heldout ? fmt::format("held-out last {:.0f}% of {} (the shaded part was used for fitting)",
                            100 * (1 - o.diagnosis_options.fit_fraction), name)
              : "validation recording " + name + " (not used for fitting)";
  auto file = [&](const std::string& stem) { return stem + suffix + ".png"; };
  auto out = [&](const std::string& f) { return (fs::path(o.out_dir) / f).string(); };

  // Gyro vs encoders.
  if (raw.imu.size() >= 3) {
    const auto rb = gyroEncoderResidual(raw, input_cfg, o.diagnosis_options.window_s,
                                        o.diagnosis_options.max_gap_s);
    const auto ra = gyroEncoderResidual(corrected, corrected_adj, o.diagnosis_options.window_s,
                                        o.diagnosis_options.max_gap_s);
    TimeFigure f = base;
    f.title = "Residual gyro omega - encoder omega, nominal vs corrected model";
    f.ylabel = "omega_gyro - omega_encoders (rad/s)";
    f.unit = "rad/s";
    f.before = &rb;
    f.after = &ra;
    drawTimeFigure(f, out(file("residual_gyro_omega")), o.width, o.height);
    rf.figures.push_back(
        {file("residual_gyro_omega"),
         fmt::format("Angular velocity from the gyro minus that from the encoders, each the mean "
                     "over windows of {:.2f} s (the kinematic channel of the diagnosis), with the "
                     "nominal model (orange) and the corrected one (blue, sensor effects of "
                     "[model_extensions] undone); {}.",
                     o.diagnosis_options.window_s, val_words)});
    rf.residual_stats["gyro_vs_encoders (rad/s)"] = {statsIn(rb, f.val0, f.val1),
                                                     statsIn(ra, f.val0, f.val1)};
  }
  // Motor currents.
  {
    const auto cb = currentResiduals(raw, input_cfg, o);
    const auto ca = currentResiduals(corrected, corrected_adj, o, in_model);
    for (int s = 0; s < 2; ++s) {
      const std::string side = s == 0 ? "right" : "left";
      TimeFigure f = base;
      f.title = fmt::format(
          "Residual {} motor current (measured - model (6)), nominal vs corrected", side);
      f.ylabel = fmt::format("i_{} - model current (A)", s == 0 ? "R" : "L");
      f.unit = "A";
      f.before = &cb[s];
      f.after = &ca[s];
      f.xnote =
          fmt::format("both currents zero-phase low-pass {:.1f} Hz", o.diagnosis_options.cutoff_hz);
      const std::string stem = "residual_current_" + side;
      drawTimeFigure(f, out(file(stem)), o.width, o.height);
      rf.figures.push_back(
          {file(stem),
           fmt::format("{} motor: measured current minus the current the drive model needs for "
                       "the motion the encoders saw (zero-phase filtered at {:.1f} Hz), with the "
                       "nominal model (orange) and the corrected one (blue: drive-train extension "
                       "currents removed{}); {}.",
                       s == 0 ? "Right" : "Left", o.diagnosis_options.cutoff_hz, in_model_words,
                       val_words)});
      rf.residual_stats["current_" + side + " (A)"] = {statsIn(cb[s], f.val0, f.val1),
                                                       statsIn(ca[s], f.val0, f.val1)};
    }
  }
  trajectoryFigures(before, after, t0, name, suffix, o, rf);
  return rf;
}

/// Drift of the command-response model (MRCLAM form), from the JSON.
bool driftFigure(const json& stage, const std::string& png, int w, int h) {
  if (!stage.contains("fit_before") || !stage.contains("fit_after")) return false;
  const json& b = stage["fit_before"];
  const json& a = stage["fit_after"];
  Plot p;
  p.title = "Open-loop drift of the command-response model on the validation recordings";
  p.xlabel = "open-loop horizon (s)";
  p.ylabel = "median position drift (m)";
  p.legend = LegendPosition::TopLeft;
  bool any = false;
  auto series = [&](const json& j, const std::string& label, Color c, double wpx) {
    Series s{label, {}, {}, c, LineStyle::Solid, wpx, Marker::Circle, 10};
    for (auto [horizon, key, hkey] : {std::tuple{10.0, "drift_10s_m", "heading_drift_10s_deg"},
                                      std::tuple{60.0, "drift_60s_m", "heading_drift_60s_deg"}}) {
      if (!j.contains(key) || !j[key].is_number()) continue;
      const double v = j[key].get<double>();
      if (!std::isfinite(v)) continue;
      s.x.push_back(horizon), s.y.push_back(v);
      any = true;
      p.annotations.push_back(
          {horizon + 1.0, v, fmt::format("{:.3f} m, {:.2f} deg", v, j.value(hkey, NAN)), c, 0.75});
    }
    p.series.push_back(s);
  };
  series(b, "nominal model (velocities = commands)", kBefore, 3.4);
  series(a, "corrected model (selected terms)", kAfter, 1.8);
  if (!any) return false;
  for (auto [horizon, key] : {std::pair{10, "drift_10s_m"}, std::pair{60, "drift_60s_m"}})
    if (!b.contains(key) || !b[key].is_number() || !std::isfinite(b[key].get<double>()))
      p.xlabel +=
          fmt::format("      (no {} s window: the recordings are too short or broken up)", horizon);
  double ymax = 0;
  for (const auto& s : p.series)
    for (double v : s.y) ymax = std::max(ymax, v);
  p.x_range = std::make_pair(0.0, 80.0);
  p.y_range = std::make_pair(0.0, std::max(0.1, ymax * 1.4));
  p.save(png, w, h);
  return true;
}

std::string findingsMarkdown(const json& report) {
  std::string md;
  const json findings = report.value("findings", json::array());
  if (findings.empty()) {
    md +=
        "No finding: the nominal model explains the recording(s) within the tests' "
        "thresholds.\n\n";
    return md;
  }
  int k = 0;
  for (const auto& f : findings) {
    md += fmt::format("### {}. `{}`{}\n\n", ++k, f.value("effect", std::string("?")),
                      f.value("fault", false) ? " (sensor fault)" : "");
    md += f.value("description", std::string()) + "\n\n";
    if (f.contains("channels") && !f["channels"].empty())
      md += "* channels: " + cell(f["channels"]) + "\n";
    if (f.contains("segments") && !f["segments"].empty()) {
      std::string s;
      std::size_t shown = 0;
      for (const auto& seg : f["segments"])
        if (seg.is_array() && seg.size() == 2 && ++shown <= 6)
          s += fmt::format("{}[{:.1f}, {:.1f}]", s.empty() ? "" : ", ", seg[0].get<double>(),
                           seg[1].get<double>());
      if (shown > 6) s += fmt::format(" and {} more", shown - 6);
      md += "* segments where it acts most (s, recording clock): " + s + "\n";
    }
    if (f.contains("evidence") && f["evidence"].is_object() && !f["evidence"].empty()) {
      std::string s;
      for (const auto& [key, v] : f["evidence"].items())
        s += (s.empty() ? "" : "; ") + key + " = " + cell(v);
      md += "* evidence: " + s + "\n";
    }
    md += "\n| parameter | value | 1 sigma |\n|---|---:|---:|\n";
    const json unc = f.value("uncertainty", json::object());
    const json params = f.value("parameters", json::object());
    for (const auto& [key, v] : params.items())
      md += "| " + key + " | " + cell(v) + " | " + (unc.contains(key) ? cell(unc[key]) : "–") +
            " |\n";
    const json fb = f.value("fit_before", json::object()),
               fa = f.value("fit_after", json::object());
    if (!fb.empty() || !fa.empty()) {
      md += "\n| fit metric | before | after |\n|---|---:|---:|\n";
      std::vector<std::string> keys;
      for (const auto& [key, v] : fb.items()) keys.push_back(key);
      for (const auto& [key, v] : fa.items())
        if (!fb.contains(key)) keys.push_back(key);
      for (const auto& key : keys)
        md += "| " + key + " | " + (fb.contains(key) ? cell(fb[key]) : "–") + " | " +
              (fa.contains(key) ? cell(fa[key]) : "–") + " |\n";
    }
    md += "\n";
  }
  return md;
}

std::string channelsMarkdown(const json& report) {
  const json ch = report.value("channels", json::object());
  if (ch.empty()) return "";
  std::string md =
      "## Residuals per channel on the validation data (diagnosis JSON)\n\n"
      "| channel | unit | n | mean before | mean after | RMS before | RMS after | mean NIS before "
      "| "
      "mean NIS after | NIS 95% band | Ljung-Box p before | after |\n"
      "|---|---|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|\n";
  for (const auto& [name, c] : ch.items()) {
    const json b = c.value("before", json::object()), a = c.value("after", json::object());
    auto g = [](const json& j, const char* k) { return j.contains(k) ? cell(j[k]) : "–"; };
    md += "| " + name + " | " + c.value("unit", std::string()) + " | " + g(b, "n") + " | " +
          g(b, "mean") + " | " + g(a, "mean") + " | " + g(b, "rms") + " | " + g(a, "rms") + " | " +
          g(b, "mean_nis") + " | " + g(a, "mean_nis") + " | " + g(b, "nis_band95") + " | " +
          g(b, "ljung_box_p") + " | " + g(a, "ljung_box_p") + " |\n";
  }
  if (ch.contains("current_right") || ch.contains("current_left"))
    md +=
        "\nIn the diagnosis JSON the current channels' *before* already has the kinematic (sensor) "
        "corrections of stage 1 applied; the figures' *before* is the fully nominal model.\n";
  return md + "\n";
}

std::string validationMarkdown(const json& report) {
  const json v = report.value("validation", json::object());
  std::string md;
  for (const char* key : {"trajectory_heldout", "trajectory_full_recordings"}) {
    if (!v.contains(key)) continue;
    const json& t = v[key];
    if (!t.contains("before") || !t.contains("after")) continue;
    md += fmt::format(
        "**{}** (diagnosis JSON, dead reckoning against the ground-truth stream):\n\n"
        "| # | odometry ATE (m) before | after | odometry terminal (m) before | after | "
        "encoder+gyro ATE (m) before | after | encoder+gyro terminal (m) before | after |\n"
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
        key);
    for (std::size_t k = 0; k < t["before"].size() && k < t["after"].size(); ++k) {
      const json &b = t["before"][k], &a = t["after"][k];
      auto g = [](const json& j, const char* key) { return cell(j.value(key, json())); };
      md += fmt::format("| {} | {} | {} | {} | {} | {} | {} | {} | {} |\n", k,
                        g(b, "odometry_ate_m"), g(a, "odometry_ate_m"), g(b, "odometry_terminal_m"),
                        g(a, "odometry_terminal_m"), g(b, "encoder_gyro_ate_m"),
                        g(a, "encoder_gyro_ate_m"), g(b, "encoder_gyro_terminal_m"),
                        g(a, "encoder_gyro_terminal_m"));
    }
    md += "\n";
  }
  if (v.contains("corrections")) {
    md += "Sensor corrections applied by the diagnosis: ";
    std::string s;
    for (const auto& [key, val] : v["corrections"].items())
      s += (s.empty() ? "" : ", ") + key + " = " + cell(val);
    md += s + "\n\n";
  }
  return md;
}

std::string commandResponseMarkdown(const json& stage, bool with_findings = true) {
  std::string md = "## Command response (command-driven form)\n\n";
  const json findings = with_findings ? stage.value("findings", json::array()) : json::array();
  if (with_findings && findings.empty()) md += "No command-response term was selected.\n\n";
  if (!findings.empty()) {
    md +=
        "| effect | channel | kind / term | parameters | delta BIC | validated |\n"
        "|---|---|---|---|---:|---|\n";
    for (const auto& f : findings) {
      std::string params;
      const json fp = f.value("parameters", json::object());
      for (const auto& [k, v] : fp.items())
        params += (params.empty() ? "" : ", ") + k + " = " + cell(v);
      const json ev = f.value("evidence", json::object());
      const json val = f.value("validation", json::object());
      md += "| " + f.value("effect", std::string()) + " | " + f.value("channel", std::string()) +
            " | " + f.value("kind", f.value("term", std::string())) + " | " + params + " | " +
            (ev.contains("delta_bic") ? cell(ev["delta_bic"]) : "–") + " | " +
            (val.contains("validated") ? cell(val["validated"]) : "–") + " |\n";
    }
    md += "\n";
  }
  if (stage.contains("fit_before") && stage.contains("fit_after")) {
    md += "| open-loop drift (validation) | before | after |\n|---|---:|---:|\n";
    for (const char* k :
         {"drift_10s_m", "drift_60s_m", "heading_drift_10s_deg", "heading_drift_60s_deg"})
      md += fmt::format("| {} | {} | {} |\n", k,
                        stage["fit_before"].contains(k) ? cell(stage["fit_before"][k]) : "–",
                        stage["fit_after"].contains(k) ? cell(stage["fit_after"][k]) : "–");
    md += "\n";
  }
  if (stage.contains("validation_residual_rms")) {
    const json& r = stage["validation_residual_rms"];
    md += "| window-mean velocity residual RMS (validation) | before | after |\n|---|---:|---:|\n";
    for (const char* k : {"v_m_s", "omega_rad_s"})
      if (r.contains(k))
        md += fmt::format("| {} | {} | {} |\n", k, cell(r[k].value("before", json())),
                          cell(r[k].value("after", json())));
    md += "\n";
  }
  return md;
}

}  // namespace

// ---------------------------------------------------------------------------------------------

void applyCorrection(const io::Recording& rec, const config::WheelchairConfig& corrected_cfg,
                     io::Recording& rec_out, config::WheelchairConfig& cfg_out) {
  const auto ext = estimation::ModelExtensions::fromConfig(corrected_cfg.ini());
  cfg_out = ext.adjustConfig(corrected_cfg);
  rec_out = ext.empty() ? rec : ext.apply(rec, cfg_out);
}

ResidualSeries gyroEncoderResidual(const io::Recording& rec, const config::WheelchairConfig& cfg,
                                   double window_s, double max_gap_s) {
  ResidualSeries out;
  const auto dr =
      estimation::deadReckoningEncoders(rec.encoders, cfg.encoders.params, cfg.vehicle.geom);
  const auto imu = sortedUnique(rec.imu, [](const io::ImuSample& s) { return s.t_s; });
  if (dr.size() < 3 || imu.size() < 3) return out;
  // Cumulative gyro integral (trapezoid) at the gyro times.
  std::vector<double> tg(imu.size()), G(imu.size(), 0.0);
  for (std::size_t i = 0; i < imu.size(); ++i) {
    tg[i] = imu[i].t_s;
    if (i)
      G[i] = G[i - 1] + 0.5 * (imu[i].gyro_z_rad_s + imu[i - 1].gyro_z_rad_s) * (tg[i] - tg[i - 1]);
  }
  const double max_gap = max_gap_s;
  std::size_t a = 0;
  while (a + 1 < dr.size()) {
    std::size_t b = a + 1;
    bool gap = false;
    while (b < dr.size() && dr[b].t_s - dr[a].t_s < window_s) {
      if (dr[b].t_s - dr[b - 1].t_s > max_gap) gap = true;
      ++b;
    }
    if (b >= dr.size()) break;
    if (dr[b].t_s - dr[b - 1].t_s > max_gap) gap = true;
    const double t0 = dr[a].t_s, t1 = dr[b].t_s;
    if (!gap && t0 >= tg.front() && t1 <= tg.back()) {
      const auto Gi = sensors::resampleLinear(tg, G, {t0, t1});
      const double T = t1 - t0;
      out.t_s.push_back(0.5 * (t0 + t1));
      out.r.push_back(((Gi[1] - Gi[0]) - (dr[b].phi_rad - dr[a].phi_rad)) / T);
    }
    a = b;
  }
  return out;
}

std::array<ResidualSeries, 2> currentResiduals(const io::Recording& rec,
                                               const config::WheelchairConfig& cfg,
                                               const DiagnosisFigureOptions& o,
                                               const std::vector<effects::EffectSpec>& in_model) {
  std::array<ResidualSeries, 2> out;
  effects::TruthModel m;
  m.drive = model::DriveTrain::symmetric(cfg.vehicle);
  effects::actOnTruth(modelOnlyEffects(in_model), m);
  const model::DriveTrain& dt = m.drive;
  const double lw = cfg.vehicle.geom.track_width_m;
  const auto& d = o.diagnosis_options;
  signals::DriveSignalOptions so;
  so.grid_rate_hz = d.grid_rate_hz, so.cutoff_hz = d.cutoff_hz, so.max_gap_s = d.max_gap_s;
  so.edge_trim_s = d.edge_trim_s;
  // The diagnosis' own conditioning (signals::prepare), so the figure shows its residual.
  for (const signals::DriveSegment& seg : signals::prepare(rec, cfg, so)) {
    const auto &p = seg.p, &u = seg.u_f, &a = seg.a_f;
    for (int i = seg.i0; i < seg.i1; ++i) {
      const model::MotionState st{0.5 * (u[0][i] + u[1][i]), (u[0][i] - u[1][i]) / lw,
                                  (p[0][i] - p[1][i]) / lw};
      const Eigen::Vector2d ip =
          dt.currents(st, 0.5 * (a[0][i] + a[1][i]), (a[0][i] - a[1][i]) / lw);
      for (int side = 0; side < 2; ++side)
        out[side].t_s.push_back(seg.t[i]), out[side].r.push_back(seg.i_f[side][i] - ip(side));
    }
    // Break the line between segments.
    for (auto& s : out)
      if (!s.t_s.empty()) s.t_s.push_back(s.t_s.back()), s.r.push_back(NAN);
  }
  return out;
}

namespace {

/// "Residuals and trajectories in the figures": the statistics of each recording's figures.
std::string figureStatsMarkdown(const std::vector<RecordingFigures>& recs, bool heldout) {
  std::string md;
  bool any_traj = false;
  for (const auto& r : recs) any_traj |= !r.traj.empty() || !r.residual_stats.empty();
  if (any_traj) {
    md += "## Residuals and trajectories in the figures\n\n";
    for (const auto& r : recs) {
      if (!r.drawn) continue;
      md += "**" + fs::path(r.path).filename().string() + "**" +
            (heldout ? " (statistics over the held-out part)" : "") + "\n\n";
      if (!r.residual_stats.empty()) {
        md +=
            "| residual | mean before | mean after | RMS before | RMS after |\n"
            "|---|---:|---:|---:|---:|\n";
        for (const auto& [ch, st] : r.residual_stats)
          md += fmt::format("| {} | {} | {} | {} | {} |\n", ch, num(st.first.mean, 4),
                            num(st.second.mean, 4), num(st.first.rms, 4), num(st.second.rms, 4));
        md += "\n";
      }
      if (!r.traj.empty()) {
        md += "Against the ground truth (" + r.gt_note +
              "), whole recording:\n\n"
              "| variant | ATE RMSE (m) before | after | terminal error (m) before | after |\n"
              "|---|---:|---:|---:|---:|\n";
        for (const auto& t : r.traj)
          md += fmt::format("| {} | {} | {} | {} | {} |\n", t.variant, num(t.before.ate_rmse_m),
                            num(t.after.ate_rmse_m), num(t.before.terminal_error_m),
                            num(t.after.terminal_error_m));
        md += "\n";
      }
    }
  }
  return md;
}

// index.md's head: what was fitted and validated, the verdict, the configurations, what could
// and could not be tested.
std::string indexHeaderMarkdown(const json& report, const config::WheelchairConfig& input_cfg,
                                const estimation::ModelExtensions& ext,
                                const std::vector<std::string>& fit_paths,
                                const std::vector<std::string>& validate_paths, bool heldout,
                                double fit_fraction) {
  std::string md = "# Diagnosis report\n\n";
  auto list = [](const std::vector<std::string>& v) {
    std::string s;
    for (const auto& p : v) s += (s.empty() ? "`" : ", `") + p + "`";
    return s.empty() ? std::string("–") : s;
  };
  md += "* fitted on: " + list(fit_paths) + "\n";
  md += "* validation: " +
        (heldout ? fmt::format("held-out last {:.0f}% of each fitted recording",
                               100 * (1 - fit_fraction))
                 : list(validate_paths)) +
        "\n";
  md += std::string("* mismatch: **") + (report.value("mismatch", false) ? "yes" : "no") + "**\n";
  md += "* input configuration: `" + input_cfg.origin() + "`\n";
  if (report.contains("config_written") && report["config_written"].is_string() &&
      !report["config_written"].get<std::string>().empty())
    md += "* corrected configuration written to: `" + report["config_written"].get<std::string>() +
          "`\n";
  if (!ext.empty()) md += "* model extensions applied in the figures: " + ext.summary() + "\n";
  if (report.contains("info") && report["info"].contains("comparisons")) {
    // what could and could not be tested (diagnosis/Comparisons.h), one line each
    std::string tested;
    for (const auto& c : report["info"]["comparisons"])
      if (c.value("tested", false))
        tested += (tested.empty() ? "" : "; ") + c.value("comparison", std::string());
    md += "* tested: " + (tested.empty() ? std::string("nothing") : tested) + "\n";
    for (const auto& c : report["info"]["comparisons"])
      if (!c.value("tested", false))
        md += "* not tested: " + c.value("comparison", std::string()) + ": " +
              cell(c.value("why", nlohmann::json(""))) + "\n";
  } else if (report.contains("info") && report["info"].contains("skipped"))
    for (const auto& [k, v] : report["info"]["skipped"].items())
      md += "* skipped " + k + ": " + cell(v) + "\n";
  if (report.contains("info") && report["info"].contains("insufficient_data"))
    for (const auto& why : report["info"]["insufficient_data"])
      md += "* insufficient data: " + cell(why) + "\n";
  return md;
}

}  // namespace

DiagnosisFigureResult writeDiagnosisFigures(const json& report,
                                            const config::WheelchairConfig& input_cfg,
                                            const config::WheelchairConfig& corrected_cfg,
                                            const std::vector<std::string>& fit_paths,
                                            const std::vector<std::string>& validate_paths,
                                            const DiagnosisFigureOptions& o) {
  if (o.out_dir.empty()) throw std::invalid_argument("diagnosis report: no output directory");
  util::OutputDir dir(o.out_dir);  // a failed run leaves no half directory
  DiagnosisFigureResult res;
  auto out = [&](const std::string& f) { return dir.file(f); };
  util::writeFileAtomically(out("diagnosis.json"), report.dump(2) + "\n");
  if (!o.summary_text.empty()) util::writeFileAtomically(out("summary.txt"), o.summary_text);

  const bool heldout = validate_paths.empty();
  const auto& vpaths = heldout ? fit_paths : validate_paths;
  std::vector<RecordingFigures> recs;
  for (std::size_t k = 0; k < vpaths.size(); ++k) {
    if (k >= o.max_recordings) {
      res.notes.push_back(fmt::format("figures drawn for the first {} validation recordings only",
                                      o.max_recordings));
      break;
    }
    const std::string suffix = vpaths.size() > 1 ? fmt::format("_{}", k + 1) : "";
    try {
      recs.push_back(recordingFigures(vpaths[k], suffix, input_cfg, corrected_cfg, heldout, o));
    } catch (const std::exception& e) {  // a figure must not lose the diagnosis
      RecordingFigures failed;
      failed.path = vpaths[k];
      failed.why_not = std::string("figures failed: ") + e.what();
      recs.push_back(failed);
    }
    if (!recs.back().drawn) res.notes.push_back(vpaths[k] + ": " + recs.back().why_not);
    for (const auto& f : recs.back().figures) res.figures.push_back(out(f.first));
  }
  const auto ext = estimation::ModelExtensions::fromConfig(corrected_cfg.ini());
  for (const auto& e : ext.effects)
    if (actsOnCommands(e))
      res.notes.push_back(e.id +
                          " is not applied to the recordings in these figures (it "
                          "needs the command history)");

  std::vector<const json*> stages;
  findStages(report, stages);
  // Without a command-response stage object, the report's own top-level drift (if any).
  const bool top_drift = stages.empty() && report.contains("fit_before") &&
                         report["fit_before"].is_object() &&
                         report["fit_before"].contains("drift_10s_m");
  if (top_drift) stages.push_back(&report);
  std::vector<std::pair<std::string, std::string>> stage_figs;
  for (std::size_t k = 0; k < stages.size(); ++k) {
    const std::string f = stages.size() > 1 ? fmt::format("drift_{}.png", k + 1) : "drift.png";
    if (driftFigure(*stages[k], out(f), o.width, o.height)) {
      res.figures.push_back(out(f));
      stage_figs.push_back(
          {f,
           "Median open-loop position drift of the command-response model (velocities from "
           "the commands alone, started at the true pose every few seconds) over 10 s and "
           "60 s on the validation recordings, nominal vs corrected; labels: position and "
           "heading drift."});
    }
  }

  // index.md
  std::string md = indexHeaderMarkdown(report, input_cfg, ext, fit_paths, validate_paths, heldout,
                                       o.diagnosis_options.fit_fraction);
  md += "\n## Findings\n\n" + findingsMarkdown(report);
  md += channelsMarkdown(report);
  const std::string val = validationMarkdown(report);
  if (!val.empty()) md += "## Validation\n\n" + val;
  for (const auto* s : stages) md += commandResponseMarkdown(*s, !top_drift);

  md += figureStatsMarkdown(recs, heldout);
  md += "## Figures\n\n";
  for (const auto& r : recs)
    for (const auto& [f, caption] : r.figures)
      md += "![" + f + "](" + f + ")\n\n" + caption + "\n\n";
  for (const auto& [f, caption] : stage_figs)
    md += "![" + f + "](" + f + ")\n\n" + caption + "\n\n";
  if (res.figures.empty()) md += "No figure: the recordings have no data the figures need.\n\n";
  for (const auto& n : res.notes) md += "* note: " + n + "\n";
  if (!o.summary_text.empty())
    md += "\n## Summary (summary.txt)\n\n```\n" + o.summary_text + "```\n";
  md +=
      "\n## Corrected configuration\n\nThe input configuration with the `[model_extensions]` "
      "found (what `--write-config` writes):\n\n```ini\n" +
      corrected_cfg.text() + "\n```\n";
  res.index_path = out("index.md");
  util::writeFileAtomically(res.index_path, md);
  dir.commit();
  return res;
}

}  // namespace wheelchair::visualization
