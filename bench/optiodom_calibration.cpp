// Odometry calibration on the real OptiOdom runs (docs/discovery.md, "Real robot without a
// gyro: OptiOdom"): fit on one path kind, predict the other, against OptiTrack.
//
//   build/bench/optiodom_calibration [--data DIR] [--segment-s S]
//
// DIR (default ../shared/datasets/optiodom beside the source tree) holds square/<ID>/ and
// circular/<ID>/ experiment folders (io/OptiodomImport.h). For each direction (fit squares ->
// validate circles, fit circles -> validate squares) it prints the held-out dead-reckoning
// error (start aligned; mean over runs of the time-mean position error, of the end position
// error and of the end heading error; the same metric for every row: each held-out run is dead
// reckoned from its first OptiTrack pose with the row's geometry and compared with OptiTrack at
// every encoder sample, no re-alignment) of:
//   nominal    each run's own metadata geometry (what the robot drove with)
//   UMBmark    Borenstein & Feng from the fit squares' return errors, per experiment, the
//              corrected geometries averaged (squares only: n/a when fitting on circles)
//   LS         two-step linear least squares (segments of S s, default 1 s)
//   diagnose   the `wheelchair diagnose` kinematic-calibration stage
//              (diagnosis/KinematicCalibration.h), configuration = the first fit experiment's;
//              its geometry includes the travel angle it fitted (OdometryGeometry)
//   (LS + beta) the least-squares geometry with diagnose's travel angle: where the gain is from
// Exit 1 when the data directory is missing or unreadable.
#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/diagnosis/KinematicCalibration.h"
#include "libwheelchair/identification/OdometryCalibration.h"
#include "libwheelchair/io/OptiodomImport.h"

#include <fmt/core.h>

#include <algorithm>
#include <filesystem>
#include <iostream>
#include <map>
#include <string>

using namespace wheelchair;
namespace fs = std::filesystem;
namespace idf = wheelchair::identification;

namespace {

struct Run {
  io::Recording rec;
  idf::OdometryRun odo;
  idf::OdometryGeometry nominal;
  io::OptiodomImportReport rep;
};

std::vector<Run> loadKind(const fs::path& dir) {
  std::vector<Run> out;
  for (auto& [rec, rep] : io::importOptiodomFolder(dir.string())) {
    Run r;
    r.rec = std::move(rec);
    r.rep = rep;
    r.odo = idf::odometryRun(r.rec, fmt::format("{} run {}", rep.experiment, rep.run));
    config::WheelchairConfig cfg;
    io::applyOptiodomGeometry(rep.geometry, cfg);
    r.nominal = idf::odometryGeometry(cfg);
    out.push_back(std::move(r));
  }
  return out;
}

struct Row {
  std::string method;
  double mean_m = 0, end_m = 0, head_deg = 0;
  idf::OdometryGeometry g;
  bool per_run_nominal = false;
};

Row evaluate(const std::string& name, const std::vector<Run>& val, const idf::OdometryGeometry* g) {
  Row row;
  row.method = name;
  int n = 0;
  for (const auto& r : val) {
    const auto e = idf::odometryError(r.odo, g ? *g : r.nominal);
    row.mean_m += e.mean_position_m, row.end_m += e.end_position_m;
    row.head_deg += e.end_heading_rad * 180 / M_PI;
    ++n;
  }
  row.mean_m /= n, row.end_m /= n, row.head_deg /= n;
  if (g) row.g = *g;
  row.per_run_nominal = !g;
  return row;
}

void direction(const std::string& title, const std::vector<Run>& fit, const std::vector<Run>& val,
               double segment_s) {
  std::vector<Row> rows;
  rows.push_back(evaluate("nominal (each run's metadata)", val, nullptr));
  // UMBmark per square experiment, corrected absolute geometries averaged
  std::map<std::string, std::vector<const Run*>> byExp;
  for (const auto& r : fit)
    if (r.rep.square_side_m > 0) byExp[r.rep.experiment].push_back(&r);
  if (!byExp.empty()) {
    idf::OdometryGeometry avg;
    int n = 0;
    for (const auto& [id, runs] : byExp) {
      std::vector<idf::OdometryRun> sq;
      for (auto* r : runs) sq.push_back(r->odo);
      try {
        const auto u = idf::umbmark(sq, runs.front()->rep.square_side_m, runs.front()->nominal);
        avg.m_per_tick_right += u.corrected.m_per_tick_right;
        avg.m_per_tick_left += u.corrected.m_per_tick_left;
        avg.track_m += u.corrected.track_m;
        ++n;
        fmt::print(
            "  UMBmark {}: {} cw / {} ccw, x_cw {:+.4f} m, x_ccw {:+.4f} m, E_d {:.5f}, "
            "E_b {:.5f}\n",
            id, u.n_cw, u.n_ccw, u.x_cw_m, u.x_ccw_m, u.E_d, u.E_b);
      } catch (const std::exception& e) {
        fmt::print("  UMBmark {}: {}\n", id, e.what());
      }
    }
    if (n) {
      avg.m_per_tick_right /= n, avg.m_per_tick_left /= n, avg.track_m /= n;
      rows.push_back(evaluate("UMBmark (Borenstein & Feng 1996)", val, &avg));
    }
  }
  std::vector<idf::OdometryRun> fitRuns;
  for (const auto& r : fit) fitRuns.push_back(r.odo);
  const auto ls = idf::leastSquaresCalibration(fitRuns, segment_s);
  rows.push_back(
      evaluate(fmt::format("least squares (two-step, {} s segments)", segment_s), val, &ls));
  // diagnose's stage, with the first fit experiment's configuration
  config::WheelchairConfig cfg;
  io::applyOptiodomGeometry(fit.front().rep.geometry, cfg);
  diagnosis::DiagnosisOptions opt;
  std::vector<io::Recording> fr, vr;
  for (const auto& r : fit) fr.push_back(r.rec);
  for (const auto& r : val) vr.push_back(r.rec);
  const auto kc = diagnosis::calibrateKinematics(fr, vr, cfg, opt);
  const auto dg = kc.accepted ? kc.fitted : kc.nominal;
  rows.push_back(evaluate(fmt::format("diagnose ({}{})", kc.accepted ? kc.model : "no finding",
                                      kc.accepted ? "" : ": configured geometry"),
                          val, &dg));
  // where the gain comes from: the least-squares geometry with diagnose's travel angle
  idf::OdometryGeometry lsBeta = ls;
  lsBeta.travel_angle_rad = dg.travel_angle_rad;
  rows.push_back(evaluate(fmt::format("(least squares + diagnose's travel angle {:+.2f} deg)",
                                      dg.travel_angle_rad * 180 / M_PI),
                          val, &lsBeta));

  fmt::print("\n### {} ({} fit runs, {} held-out runs)\n\n", title, fit.size(), val.size());
  fmt::print(
      "| method | mean position error (m) | end position error (m) | end heading error "
      "(deg) | k_R (um/tick) | k_L (um/tick) | track (m) |\n|---|---:|---:|---:|---:|---:|---:|\n");
  const double base = rows.front().mean_m;
  for (const auto& r : rows) {
    if (r.per_run_nominal)
      fmt::print("| {} | {:.4f} | {:.4f} | {:.2f} | per run | per run | per run |\n", r.method,
                 r.mean_m, r.end_m, r.head_deg);
    else
      fmt::print("| {} | {:.4f} ({:+.0f} %) | {:.4f} | {:.2f} | {:.3f} | {:.3f} | {:.4f} |\n",
                 r.method, r.mean_m, 100 * (r.mean_m / base - 1), r.end_m, r.head_deg,
                 1e6 * r.g.m_per_tick_right, 1e6 * r.g.m_per_tick_left, r.g.track_m);
  }
  fmt::print("\ndiagnose candidates (k-fold CV mean position error on the fit runs):");
  for (const auto& c : kc.candidates)
    fmt::print(" {} {:.4f} m;", c["model"].get<std::string>(),
               c["cv_mean_position_error_m"].get<double>());
  fmt::print("\n");
  fmt::print(
      "specification check: whole-run {} vs increments {}: turn gain {:+.3f} % (+- {:.3f} %), "
      "z {:+.1f} (limit {}): {}\n",
      kc.whole_run_model, kc.increment_model, 100 * kc.gain_difference_rel,
      100 * kc.gain_difference_sd,
      kc.gain_difference_sd > 0 ? kc.gain_difference_rel / kc.gain_difference_sd : 0.0,
      diagnosis::kMaxGainDisagreementZ,
      kc.whole_run_misspecified ? "misspecified, increment-domain candidates only" : "consistent");
}

}  // namespace

int main(int argc, char** argv) {
  std::string data = std::string(WHEELCHAIR_SOURCE_DIR) + "/../shared/datasets/optiodom";
  double segment_s = 1.0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc || (a != "--data" && a != "--segment-s")) {
      std::cerr << "usage: optiodom_calibration [--data DIR] [--segment-s S]\n";
      return 2;
    }
    if (a == "--data") data = argv[++i];
    if (a == "--segment-s") segment_s = std::stod(argv[++i]);
  }
  try {
    if (!fs::is_directory(fs::path(data) / "square") ||
        !fs::is_directory(fs::path(data) / "circular"))
      throw std::runtime_error(data + ": no square/ and circular/ experiment folders");
    const auto squares = loadKind(fs::path(data) / "square");
    const auto circles = loadKind(fs::path(data) / "circular");
    fmt::print("OptiOdom: {} square runs, {} circular runs from {}\n", squares.size(),
               circles.size(), data);
    direction("fit on squares, validate on circles", squares, circles, segment_s);
    direction("fit on circles, validate on squares", circles, squares, segment_s);
  } catch (const std::exception& e) {
    std::cerr << "optiodom_calibration: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
