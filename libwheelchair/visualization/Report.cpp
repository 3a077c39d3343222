#include "libwheelchair/visualization/Report.h"

#include "libwheelchair/util/AtomicFile.h"
#include "libwheelchair/util/OutputDir.h"

#include "libwheelchair/visualization/Plot.h"
#include "libwheelchair/visualization/Scene3D.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <stdexcept>

namespace wheelchair::visualization {
namespace {

using Pts = std::vector<std::pair<double, double>>;

Color mix(Color c, double a) {  // c over white with opacity a
  auto f = [&](uint8_t v) { return static_cast<uint8_t>(std::lround(255 + a * (v - 255.0))); };
  return Color{f(c.r), f(c.g), f(c.b)};
}

/// Phases of the drive (straight / turn) from the encoder dead reckoning, as shaded spans
/// like the three tasks marked in the paper's Fig. 6.
std::vector<XSpan> motionPhases(const DriveData& d, double t0) {
  std::vector<XSpan> out;
  const auto& dr = d.phase_speeds;
  if (dr.size() < 2) return out;
  struct Run {
    int kind;
    double a, b;
  };
  std::vector<Run> runs;
  for (const auto& s : dr) {
    const int kind = motionKind(s);
    if (runs.empty() || runs.back().kind != kind)
      runs.push_back({kind, s.t_s, s.t_s});
    else
      runs.back().b = s.t_s;
  }
  // Drop short runs (merge them into the previous one), then join equal neighbours.
  std::vector<Run> merged;
  for (const auto& r : runs) {
    if (!merged.empty() && (r.b - r.a < 1.0 || merged.back().kind == r.kind))
      merged.back().b = r.b;
    else
      merged.push_back(r);
  }
  int k = 0;
  for (const auto& r : merged) {
    if (r.kind == 0 || r.b - r.a < 1.0) continue;
    ++k;
    out.push_back({r.a - t0, r.b - t0, fmt::format("{}: {}", k, r.kind == 1 ? "straight" : "turn"),
                   k % 2 ? Color{232, 232, 240} : Color{240, 236, 226}});
  }
  return out;
}

// Appends the points of a path (Fig. 5) that are drawn (pathPointsToDraw, Plot.h) to `s`.
template <class X, class Y>
void appendPath(Series& s, std::size_t n, X x, Y y) {
  const auto keep = pathPointsToDraw(n, x, y);
  s.x.reserve(s.x.size() + keep.size());
  s.y.reserve(s.y.size() + keep.size());
  for (std::size_t i : keep) s.x.push_back(x(i)), s.y.push_back(y(i));
}

Series trajSeries(const evaluation::Trajectory& t, const std::string& variant) {
  Series s;
  s.label = variantLabel(variant);
  s.color = variantColor(variant);
  s.width_px = variant == "ekf" ? 2.6 : 2.0;
  if (variant == "baseline") s.line = LineStyle::Dashed;
  appendPath(
      s, t.size(), [&](std::size_t i) { return t[i].x_m; },
      [&](std::size_t i) { return t[i].y_m; });
  return s;
}

// A plot over the time since the start of the drive, the motion phases shaded.
Plot timePlot(const DriveData& d, const std::string& title, const std::string& ylabel) {
  Plot p;
  p.title = title;
  p.xlabel = "time since start (s)";
  p.ylabel = ylabel;
  p.spans = motionPhases(d, d.t0_s);
  p.legend = LegendPosition::BottomLeft;
  return p;
}

// `s` with the samples appended: x = t_s - t0 (s), y = value(sample).
template <class Samples, class Value>
Series overTime(Series s, const Samples& samples, double t0, Value value) {
  s.x.reserve(s.x.size() + samples.size());
  s.y.reserve(s.y.size() + samples.size());
  for (const auto& x : samples) s.x.push_back(x.t_s - t0), s.y.push_back(value(x));
  return s;
}

// The simulated truth's `values` over time (every second sample), in the truth's colour.
Series truthOverTime(const DriveData& d, const std::string& label,
                     const std::vector<double>& values, LineStyle line) {
  Series s{label, {}, {}, variantColor("truth"), line, 1.6};
  s.x.reserve(d.truth->t_s.size() / 2 + 1);
  s.y.reserve(d.truth->t_s.size() / 2 + 1);
  for (std::size_t i = 0; i < d.truth->t_s.size(); i += 2)
    s.x.push_back(d.truth->t_s[i] - d.t0_s), s.y.push_back(values[i]);
  return s;
}

// Points drawn as markers only (no points: a legend entry only).
Series markers(const std::string& label, Color c, Marker m, double size_px, std::vector<double> x,
               std::vector<double> y) {
  Series s;
  s.label = label;
  s.color = c;
  s.line = LineStyle::None;
  s.marker = m;
  s.marker_size_px = size_px;
  s.x = std::move(x);
  s.y = std::move(y);
  return s;
}

Pts rectPts(double x0, double y0, double x1, double y1) {
  return {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}, {x0, y0}};
}

std::string fmtNum(double v, int p) {
  return std::isfinite(v) ? fmt::format("{:.{}f}", v, p) : "–";
}

}  // namespace

void figureTrajectories(const DriveData& d, const std::string& png, int w, int h) {
  Plot p;
  p.title = "Fig. 5 - trajectories (view from above, start frame)";
  p.xlabel = "x (m)";
  p.ylabel = "y (m)";
  p.equal_aspect = true;
  p.legend = LegendPosition::Outside;
  if (d.truth && !d.truth->t_s.empty()) {
    Series s;
    s.label = variantLabel("truth");
    s.color = variantColor("truth");
    s.width_px = 1.6;
    s.line = LineStyle::Dashed;
    const auto& tr = *d.truth;
    appendPath(
        s, tr.x_m.size(), [&](std::size_t i) { return tr.x_m[i]; },
        [&](std::size_t i) { return tr.y_m[i]; });
    p.series.push_back(s);
  }
  if (!d.gt_start.empty()) {
    Series s;
    s.label = d.gt.source == evaluation::GroundTruthSource::Pozyx ? "Pozyx tag (ground truth)"
                                                                  : "ground truth";
    s.color = variantColor("gt");
    s.line = LineStyle::None;
    s.marker = Marker::Dot;
    s.marker_size_px = 3.0;
    for (const auto& g : d.gt_start) s.x.push_back(g.x_m), s.y.push_back(g.y_m);
    p.series.push_back(s);
  }
  for (const std::string v : {"encoders", "encoders_gyro", "baseline", "ekf"}) {
    auto it = d.trajectories.find(v);
    if (it == d.trajectories.end() || it->second.empty()) continue;
    p.series.push_back(trajSeries(it->second, v));
  }
  // End markers, then the (common) start and the legend entry of the end markers.
  for (const std::string v : {"encoders", "encoders_gyro", "baseline", "ekf"}) {
    auto it = d.trajectories.find(v);
    if (it == d.trajectories.end() || it->second.empty()) continue;
    p.series.push_back(markers("", variantColor(v), Marker::Circle, 9, {it->second.back().x_m},
                               {it->second.back().y_m}));
  }
  p.series.push_back(markers("start", Color{230, 0, 0}, Marker::Square, 11, {0.0}, {0.0}));
  p.series.push_back(markers("end of each trajectory", colors::white, Marker::Circle, 9, {}, {}));
  if (!d.gt_frame_note.empty()) p.xlabel += "      (ground truth " + d.gt_frame_note + ")";
  p.save(png, w + 260, h + 60);
}

void figureVelocity(const DriveData& d, const std::string& png, int w, int h) {
  const double t0 = d.t0_s;
  Plot p = timePlot(d, "Fig. 6a - linear velocity: encoders vs EKF", "v (m/s)");
  // The measurement is drawn wide underneath and the estimate thin on top, so both stay
  // visible where they agree (which is most of a good drive).
  p.series.push_back(overTime(
      Series{"v from the encoders", {}, {}, variantColor("encoders"), LineStyle::Solid, 3.4},
      d.encoder_speeds, t0, [](const auto& s) { return s.v_m_s; }));
  p.series.push_back(
      overTime(Series{"v estimated by the EKF", {}, {}, variantColor("ekf"), LineStyle::Solid, 1.3},
               d.ekf_trace, t0, [](const EkfTracePoint& e) { return e.v_m_s; }));
  if (d.truth && !d.truth->v_m_s.empty())
    p.series.push_back(truthOverTime(d, "true v (simulation)", d.truth->v_m_s, LineStyle::Dashed));
  p.save(png, w, h);
}

void figureAngularVelocity(const DriveData& d, const std::string& png, int w, int h) {
  const double t0 = d.t0_s;
  Plot p = timePlot(d, "Fig. 6b - angular velocity: gyro vs encoders", "omega (rad/s)");
  p.series.push_back(overTime(
      Series{"omega from the gyro", {}, {}, variantColor("encoders_gyro"), LineStyle::Solid, 1.4},
      d.gyro, t0, [](const auto& s) { return s.gyro_z_rad_s; }));
  p.series.push_back(overTime(
      Series{"omega from the encoders", {}, {}, variantColor("encoders"), LineStyle::Solid, 1.8},
      d.encoder_speeds, t0, [](const auto& s) { return s.omega_rad_s; }));
  p.series.push_back(overTime(
      Series{"omega estimated by the EKF", {}, {}, variantColor("ekf"), LineStyle::Dashed, 1.6},
      d.ekf_trace, t0, [](const EkfTracePoint& e) { return e.omega_rad_s; }));
  if (d.truth && !d.truth->omega_rad_s.empty())
    p.series.push_back(
        truthOverTime(d, "true omega (simulation)", d.truth->omega_rad_s, LineStyle::Dotted));
  p.save(png, w, h);
}

void figureCurrents(const DriveData& d, const std::string& png, int w, int h) {
  const double t0 = d.t0_s;
  Plot p = timePlot(d, "Fig. 6c - motor currents", "current (A)");
  p.series.push_back(
      overTime(Series{"right motor (i_1)", {}, {}, colors::red, LineStyle::Solid, 1.5}, d.currents,
               t0, [](const auto& s) { return s.current_right_A; }));
  p.series.push_back(
      overTime(Series{"left motor (i_2)", {}, {}, colors::blue, LineStyle::Solid, 1.5}, d.currents,
               t0, [](const auto& s) { return s.current_left_A; }));
  if (d.currents.empty())
    p.annotations.push_back({0, 0, "no motor currents in this recording", colors::red, 0.9});
  p.save(png, w, h);
}

void figureObstacle(const DriveData& d, double t, const std::string& png, int w, int h) {
  Plot p;
  p.title = fmt::format("Fig. 7 - obstacle in the base frame at t = {:.1f} s (view from above)",
                        t - d.t0_s);
  p.xlabel = "x_M (m), forward";
  p.ylabel = "y_M (m), left";
  p.equal_aspect = true;
  p.legend = LegendPosition::Outside;
  const auto& g = d.cfg.vehicle.geom;
  // Footprint and wheels.
  p.shapes.push_back({"chair footprint", rectPts(-0.30, -0.33, 0.60, 0.33), Color{120, 90, 40}, 1.8,
                      LineStyle::Solid, 0.18});
  for (double side : {-1.0, 1.0})
    p.shapes.push_back({"",
                        rectPts(-g.wheel_radius_m, side * g.track_width_m / 2 - 0.035,
                                g.wheel_radius_m, side * g.track_width_m / 2 + 0.035),
                        Color{40, 40, 40}, 1.0, LineStyle::Solid, 0.9});
  // Sonar cone at the maximum range and the current reading.
  const auto& so = d.cfg.sonar;
  const double yaw = so.yaw_deg * M_PI / 180, half = so.cone_half_angle_deg * M_PI / 180;
  auto fan = [&](double r) {
    Pts f{{so.x_m, so.y_m}};
    for (int i = 0; i <= 24; ++i) {
      const double a = yaw - half + 2 * half * i / 24;
      f.emplace_back(so.x_m + r * std::cos(a), so.y_m + r * std::sin(a));
    }
    f.emplace_back(so.x_m, so.y_m);
    return f;
  };
  p.shapes.push_back(
      {"sonar cone (max range)", fan(so.max_range_m), colors::gray, 1.0, LineStyle::Dotted, 0.0});
  double reading = -1;
  for (const auto& s : d.rec.sonar)
    if (s.t_s <= t) reading = s.range_m;
  if (reading > 0)
    p.shapes.push_back({fmt::format("sonar reading {:.2f} m", reading), fan(reading),
                        colors::orange, 1.5, LineStyle::Solid, 0.22});
  else if (reading == 0)
    p.annotations.push_back({so.x_m, -0.5, "sonar reading 0 (no echo)", colors::orange, 0.8});

  const auto* e = d.ekfAt(t);
  double xmax = so.max_range_m + so.x_m, ymax = 2.0;
  if (e && e->obstacle_initialised) {
    const double px = e->x(5), py = e->x(6);
    const Eigen::Matrix2d P = e->P.block<2, 2>(5, 5);
    p.shapes.push_back({"1-sigma covariance ellipse",
                        covarianceEllipse(px, py, P(0, 0), P(0, 1), P(1, 1), 1.0), colors::cyan,
                        2.4, LineStyle::Solid, 0.15});
    p.shapes.push_back({"2-sigma", covarianceEllipse(px, py, P(0, 0), P(0, 1), P(1, 1), 2.0),
                        colors::cyan, 1.4, LineStyle::Dashed, 0.0});
    // The numbers go in the legend (outside the axes), where they are never clipped.
    p.series.push_back(
        {fmt::format("estimated obstacle: d = {:.2f} +- {:.3f} m, theta = {:.1f} "
                     "+- {:.1f} deg",
                     e->obstacle_distance_m, e->obstacle_distance_sd_m,
                     e->obstacle_bearing_rad * 180 / M_PI, e->obstacle_bearing_sd_rad * 180 / M_PI),
         {px},
         {py},
         colors::green,
         LineStyle::None,
         2,
         Marker::Circle,
         12});
    xmax = std::max(xmax, px + 2 * std::sqrt(P(0, 0)) + 0.3);
    ymax = std::max(ymax, std::fabs(py) + 2 * std::sqrt(P(1, 1)) + 0.3);
  } else {
    p.annotations.push_back({0.0, 1.2, "no obstacle estimate at this time", colors::red, 0.9});
  }
  ymax = std::min(ymax, 6.0);
  xmax = std::min(xmax, 8.0);
  // True obstacles (simulation), mapped into the base frame with the true pose.
  double tx, ty, tphi;
  if (d.truth && d.truth->poseAt(t, tx, ty, tphi)) {
    Series tru{"true obstacle", {}, {}, colors::red, LineStyle::None, 2, Marker::Circle, 10};
    for (const auto& o : d.truth->obstacles) {
      const double dx = o.x_m - tx, dy = o.y_m - ty;
      const double bx = std::cos(tphi) * dx + std::sin(tphi) * dy,
                   by = -std::sin(tphi) * dx + std::cos(tphi) * dy;
      if (bx > -1.0 && bx < xmax && std::fabs(by) < ymax) tru.x.push_back(bx), tru.y.push_back(by);
    }
    if (!tru.x.empty()) p.series.push_back(tru);
  }
  Series axle{"axle midpoint (base frame origin)",
              {0.0},
              {0.0},
              colors::black,
              LineStyle::None,
              2,
              Marker::Cross,
              10};
  p.series.push_back(axle);
  double xmin = -1.0;
  if (e && e->obstacle_initialised)
    xmin = std::max(-8.0, std::min(xmin, e->x(5) - 2 * std::sqrt(e->P(5, 5)) - 0.3));
  p.x_range = std::make_pair(xmin, xmax);
  p.y_range = std::make_pair(-ymax, ymax);
  p.save(png, w + 260, h + 60);
}

void figureDistance(const DriveData& d, const std::string& png, int w, int h) {
  const double t0 = d.t0_s;
  Plot p;
  p.title = "Fig. 8 - reconstructed distance to the obstacle (+- sigma) over the raw sonar";
  p.xlabel = "time since start (s)";
  p.ylabel = "range from the sonar (m)";
  p.legend = LegendPosition::TopRight;
  Series raw{"raw sonar (0 = failed reading)",
             {},
             {},
             colors::blue,
             LineStyle::Solid,
             1.1,
             Marker::Dot,
             4};
  for (const auto& s : d.rec.sonar) raw.x.push_back(s.t_s - t0), raw.y.push_back(s.range_m);
  Series est{"estimate", {}, {}, colors::red, LineStyle::Solid, 2.2};
  Series lo{"estimate +- sigma", {}, {}, colors::red, LineStyle::Dotted, 1.6};
  Series hi{"", {}, {}, colors::red, LineStyle::Dotted, 1.6};
  Band band{"", {}, {}, {}, mix(colors::red, 0.15), 1.0};
  bool prev = false;
  for (const auto& e : d.ekf_trace) {
    const double r = e.range_m, sd = e.range_sd_m;
    const double x = e.t_s - t0;
    if (!e.obstacle) {
      if (prev) {  // break the lines
        est.x.push_back(x), est.y.push_back(NAN);
        lo.x.push_back(x), lo.y.push_back(NAN);
        hi.x.push_back(x), hi.y.push_back(NAN);
      }
      prev = false;
      continue;
    }
    prev = true;
    est.x.push_back(x), est.y.push_back(r);
    lo.x.push_back(x), lo.y.push_back(r - sd);
    hi.x.push_back(x), hi.y.push_back(r + sd);
    band.x.push_back(x), band.lo.push_back(r - sd), band.hi.push_back(r + sd);
  }
  p.bands.push_back(band);
  p.series.push_back(raw);
  p.series.push_back(lo);
  p.series.push_back(hi);
  p.series.push_back(est);
  // Like the paper's Fig. 8: the time window in which the sonar saw something (+ margins).
  double a = NAN, b = NAN, ymax = 0.5;
  for (const auto& s : d.rec.sonar)
    if (s.range_m > 0) {
      if (std::isnan(a)) a = s.t_s;
      b = s.t_s;
      ymax = std::max(ymax, s.range_m * 1.15);
    }
  if (!std::isnan(a))
    p.x_range = std::make_pair(std::max(0.0, a - t0 - 2.0), std::min(d.t1_s - t0, b - t0 + 4.0));
  p.y_range = std::make_pair(-0.15, std::min(ymax, d.cfg.sonar.max_range_m * 1.15));
  std::size_t zeros = 0;
  for (const auto& s : d.rec.sonar) zeros += s.range_m == 0;
  p.xlabel += fmt::format("      ({} of {} sonar readings are 0)", zeros, d.rec.sonar.size());
  p.save(png, w, h);
}

ReportResult writeReport(const std::string& rawlog, const config::WheelchairConfig& cfg,
                         const ReportOptions& o) {
  const DriveData d = loadDrive(rawlog, cfg, o.metrics, o.truth_path);
  return writeReport(d, o);
}

namespace {

// A figure of the report: its file name (in the report directory) and caption.
struct ReportFigure {
  std::string file, caption;
};

// index.md: what the recording holds, the metrics, the EKF's sensor statistics, the figures with
// their captions, the notes and the configuration used.
std::string indexMarkdown(const DriveData& d, const std::vector<ReportFigure>& figs,
                          const std::vector<std::string>& notes) {
  namespace fs = std::filesystem;
  std::string md = "# Report: " + fs::path(d.path).filename().string() + "\n\n";
  md += "* recording: `" + d.path + "`\n";
  md += fmt::format("* duration of the estimates: {:.2f} s (recording clock {:.3f} .. {:.3f} s)\n",
                    d.t1_s - d.t0_s, d.t0_s, d.t1_s);
  md += fmt::format(
      "* samples: encoders {}, imu {}, motors {}, sonar {}, pozyx {}, ground truth {}\n",
      d.counts.encoders, d.counts.imu, d.counts.motors, d.counts.sonar, d.counts.pozyx,
      d.counts.ground_truth);
  md += "* ground truth: " + std::string(evaluation::toString(d.gt.source)) +
        (d.gt_frame_note.empty() ? "" : " (figures: " + d.gt_frame_note + ")") + "\n";
  if (d.truth)
    md += "* simulated: scenario `" + d.truth->scenario +
          "`, effects: " + (d.truth->effects.empty() ? "none" : d.truth->effects) + "\n";
  md += "* configuration: `" + d.cfg.origin() + "` (full text below)\n\n";
  md += "## Metrics\n\n" + evaluation::batchMarkdown(d.metrics, d.cfg, false) + "\n";
  const auto& ekf = d.est.ekf;
  if (!d.ekf_trace.empty()) {
    md +=
        "## EKF sensor statistics\n\n| sensor | used | rejected | dropouts | mean NIS "
        "|\n|---|---:|---:|---:|---:|\n";
    for (int s = 0; s < estimation::kNumSensors; ++s) {
      const auto& st = ekf.sensors[s];
      if (s == int(estimation::Sensor::Landmarks)) continue;  // the command-driven EKF's
      md += fmt::format("| {} | {} | {} | {} | {} |\n",
                        estimation::sensorName(static_cast<estimation::Sensor>(s)), st.used,
                        st.rejected, st.dropouts, st.nis_count ? fmtNum(st.meanNis(), 2) : "–");
    }
    for (const auto& w : ekf.warnings) md += "\n* warning: " + w;
    md += "\n";
  }
  md += "\n## Figures\n\n";
  for (const auto& f : figs) md += "![" + f.file + "](" + f.file + ")\n\n" + f.caption + "\n\n";
  for (const auto& n : notes) md += "* note: " + n + "\n";
  md += "\n## Configuration used\n\n```ini\n" + d.cfg.text() + "\n```\n";
  return md;
}

}  // namespace

ReportResult writeReport(const DriveData& d, const ReportOptions& o) {
  if (o.out_dir.empty()) throw std::invalid_argument("report: no output directory");
  util::OutputDir dir(o.out_dir);  // a failed report leaves no half directory
  ReportResult r;
  const double t_at = std::isfinite(o.at_s) ? o.at_s : defaultObstacleTime(d);
  auto path = [&](const std::string& f) { return dir.file(f); };
  std::vector<ReportFigure> figs;
  auto add = [&](const std::string& file, const std::string& caption) {
    r.figures.push_back(path(file));
    figs.push_back({file, caption});
  };
  figureTrajectories(d, path("fig5_trajectories.png"), o.width, o.height);
  add("fig5_trajectories.png",
      "Fig. 5: trajectories of the variants (encoders only, encoder v + gyro omega, baseline, EKF) "
      "in "
      "the start frame, with the ground truth" +
          (d.gt_frame_note.empty() ? std::string() : " (" + d.gt_frame_note + ")") +
          "; red square = start, circles = end points.");
  figureVelocity(d, path("fig6a_velocity.png"), o.width, o.height);
  add("fig6a_velocity.png",
      "Fig. 6a: linear velocity from the encoders vs the EKF's estimate; shaded: phases of the "
      "drive.");
  figureAngularVelocity(d, path("fig6b_angular_velocity.png"), o.width, o.height);
  add("fig6b_angular_velocity.png",
      "Fig. 6b: angular velocity from the gyro vs the encoders (and the EKF).");
  figureCurrents(d, path("fig6c_motor_currents.png"), o.width, o.height);
  add("fig6c_motor_currents.png", "Fig. 6c: motor currents, right (index 0, paper's 1) and left.");
  figureObstacle(d, t_at, path("fig7_obstacle.png"), o.width, o.height);
  add("fig7_obstacle.png",
      fmt::format(
          "Fig. 7: obstacle estimate (green) with its 1- and 2-sigma covariance ellipses (cyan) in "
          "the base frame at t = {:.2f} s (recording clock {:.3f} s); red: true obstacles when "
          "simulated.",
          t_at - d.t0_s, t_at));
  figureDistance(d, path("fig8_distance.png"), o.width, o.height);
  add("fig8_distance.png",
      "Fig. 8: EKF range from the sonar to the obstacle estimate (red) +- 1 sigma (dotted, shaded) "
      "over the "
      "raw sonar (blue; zeros are failed readings); time window: where the sonar saw an obstacle.");
  if (o.scene3d) {
    DriveScene scene(d);
    scene.setTime(t_at);
    std::string why;
    if (renderSnapshot(scene, path("scene3d.png"), 1200, 800, &why))
      add("scene3d.png", "3-D view (as `wheelchair view`) at the same time as Fig. 7.");
    else
      r.notes.push_back("3-D snapshot skipped: " + why);
  }

  r.index_path = path("index.md");
  util::writeFileAtomically(r.index_path,
                            [&](std::ostream& out) { out << indexMarkdown(d, figs, r.notes); });
  dir.commit();
  return r;
}

}  // namespace wheelchair::visualization
