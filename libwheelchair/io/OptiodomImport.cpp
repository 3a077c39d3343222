#include "libwheelchair/io/OptiodomImport.h"
#include "libwheelchair/util/Text.h"

#include "libwheelchair/io/TextFormat.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>

namespace fs = std::filesystem;

namespace wheelchair::io {

namespace {

constexpr double kCycle_s = 0.05;  // the robot's cycle stamp (counter x 50 ms)

std::vector<std::string> splitCsv(const std::string& line) {
  std::vector<std::string> out;
  std::size_t start = line.compare(0, 3, "\xEF\xBB\xBF") == 0 ? 3 : 0;  // UTF-8 byte-order mark
  while (true) {
    const auto c = line.find(',', start);
    out.push_back(
        util::trim(line.substr(start, c == std::string::npos ? std::string::npos : c - start)));
    if (c == std::string::npos) break;
    start = c + 1;
  }
  while (!out.empty() && out.back().empty()) out.pop_back();  // trailing empty cells
  return out;
}

bool parseNumber(const std::string& s, double& x) {
  if (s.empty()) return false;
  char* end = nullptr;
  x = std::strtod(s.c_str(), &end);
  return *end == '\0' && std::isfinite(x);
}

double number(const std::string& s, const std::string& where) {
  double x = 0;
  if (!parseNumber(s, x))
    throw FormatError(fmt::format("{}: '{}' is not a finite number", where, s));
  return x;
}

/// <ID>_metadata.csv: key -> cells.
std::map<std::string, std::vector<std::string>> readMetadata(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw FormatError(fmt::format("{}: cannot open file", path));
  std::map<std::string, std::vector<std::string>> m;
  std::string line;
  std::size_t line_no = 0;
  while (util::getBoundedLine(in, line, util::kMaxLineBytes, path, ++line_no)) {
    auto cells = splitCsv(line);
    if (cells.empty() || cells[0].empty()) continue;
    m[cells[0]] = std::vector<std::string>(cells.begin() + 1, cells.end());
  }
  return m;
}

struct CommandLog {
  std::vector<JoystickSample> cmds;  ///< t re-based to the run's first cycle; raw units
  double dL = 0, dR = 0, b = 0;      ///< dL0, dR0, b0 of the header (0 if absent)
  std::string method;
};

/// The commands of run `run` in the robot log <ID>.csv (t, v ticks/cycle, omega rad/cycle).
CommandLog readCommandLog(const std::string& path, int run) {
  std::ifstream in(path);
  if (!in) throw FormatError(fmt::format("{}: cannot open file", path));
  CommandLog log;
  std::string line;
  std::size_t line_no = 0;
  int current = 0;
  double t0 = 0;
  while (util::getBoundedLine(in, line, util::kMaxLineBytes, path, ++line_no)) {
    auto c = splitCsv(line);
    if (c.empty()) continue;
    const std::string where = fmt::format("{}:{}", path, line_no);
    if (c[0] == "Method:" && c.size() > 1) log.method = c[1];
    if (c[0] == "dL0(m):" && c.size() >= 6) {
      log.dL = number(c[1], where), log.dR = number(c[3], where), log.b = number(c[5], where);
      continue;
    }
    if (c[0] == "Run:") {
      if (c.size() < 2) throw FormatError(where + ": 'Run:' without a run number");
      current = static_cast<int>(number(c[1], where));
      continue;
    }
    double t = 0;
    if (current != run || !parseNumber(c[0], t)) continue;  // header lines, other runs
    if (c.size() < 8)
      throw FormatError(
          fmt::format("{}: {} columns, expected 9 (t, odoL, odoR, x, y, th, vlin, "
                      "omega, flag)",
                      where, c.size()));
    if (log.cmds.empty()) t0 = t;
    log.cmds.push_back({t - t0, number(c[6], where), number(c[7], where)});
  }
  return log;
}

}  // namespace

std::string OptiodomImportReport::summary() const {
  return fmt::format(
      "experiment {} ({} path{}, {}), {} cycles over {:.1f} s, {} commands; geometry D_R {} m, "
      "D_L {} m, track {} m, {} ticks per wheel turn",
      experiment, path_kind,
      square_side_m > 0 ? fmt::format(" {} m side", square_side_m) : std::string(), direction,
      cycles, duration_s, commands, geometry.wheel_diameter_right_m, geometry.wheel_diameter_left_m,
      geometry.track_m, geometry.ticksPerWheelRev());
}

Recording importOptiodom(const std::string& dir, int run, OptiodomImportReport* report) {
  if (!fs::is_directory(dir)) throw FormatError(fmt::format("{}: not a directory", dir));
  std::string id = fs::path(dir).filename().string();
  if (id.empty()) id = fs::path(dir).parent_path().filename().string();  // trailing slash
  const auto file = [&](const std::string& suffix) {
    return (fs::path(dir) / (id + suffix)).string();
  };
  OptiodomImportReport rep;
  rep.experiment = id;
  rep.run = run;

  // ---- metadata: geometry, number of runs, square side
  const std::string meta_path = file("_metadata.csv");
  const auto meta = readMetadata(meta_path);
  const auto need = [&](const std::string& key, std::size_t n) -> const std::vector<std::string>& {
    auto it = meta.find(key);
    if (it == meta.end() || it->second.size() < n)
      throw FormatError(
          fmt::format("{}: key '{}' missing or with fewer than {} values", meta_path, key, n));
    return it->second;
  };
  if (need("type", 1)[0] != "diff")
    throw FormatError(fmt::format("{}: type '{}' is not a differential drive ('diff')", meta_path,
                                  need("type", 1)[0]));
  auto& g = rep.geometry;
  g.gear_ratio = number(need("ngear", 1)[0], meta_path + ": ngear");
  const double enc = number(need("encRes", 1)[0], meta_path + ": encRes");
  g.counts_per_motor_rev = static_cast<int>(std::lround(enc));
  g.track_m = number(need("Li", 1)[0], meta_path + ": Li");
  const auto& di = need("Di", 2);
  const double d1 = number(di[0], meta_path + ": Di"), d2 = number(di[1], meta_path + ": Di");
  rep.runs_in_metadata = static_cast<int>(number(need("N", 1)[0], meta_path + ": N"));
  if (auto it = meta.find("L"); it != meta.end() && !it->second.empty() && !it->second[0].empty())
    rep.square_side_m = number(it->second[0], meta_path + ": L");
  if (!(g.gear_ratio > 0) || g.counts_per_motor_rev <= 0 ||
      std::abs(enc - g.counts_per_motor_rev) > 1e-9 || !(g.track_m > 0) || !(d1 > 0) || !(d2 > 0))
    throw FormatError(fmt::format(
        "{}: ngear, encRes (an integer), Li and Di must be positive (got {}, {}, {}, {} {})",
        meta_path, g.gear_ratio, enc, g.track_m, d1, d2));
  if (run < 1 || run > rep.runs_in_metadata)
    throw std::invalid_argument(
        fmt::format("--run {} is outside 1..{} (N in {})", run, rep.runs_in_metadata, meta_path));

  const std::string run_path = file(fmt::format("_run-{:02d}.csv", run));
  if (!fs::is_regular_file(run_path)) throw FormatError(fmt::format("{}: no such file", run_path));

  // ---- commands and the side order of the diameters (the log header names dL0 and dR0)
  CommandLog log = readCommandLog(file(".csv"), run);
  rep.method = log.method;
  g.wheel_diameter_left_m = d1, g.wheel_diameter_right_m = d2;  // metadata order: L, R
  if (log.dL > 0 && log.dR > 0) {
    g.wheel_diameter_left_m = log.dL, g.wheel_diameter_right_m = log.dR;
    if (std::abs(log.dL - d1) + std::abs(log.dR - d2) > 1e-9 &&
        std::abs(log.dL - d2) + std::abs(log.dR - d1) > 1e-9)
      throw FormatError(fmt::format("{}: dL0 {} / dR0 {} disagree with Di {} {} of {}",
                                    file(".csv"), log.dL, log.dR, d1, d2, meta_path));
  }
  if (log.cmds.empty())
    throw FormatError(fmt::format("{}: no rows for run {} ('Run:,{}')", file(".csv"), run, run));

  // ---- the synchronised run: ground truth and per-cycle ticks
  std::ifstream in(run_path);
  if (!in) throw FormatError(fmt::format("{}: cannot open file", run_path));
  Recording rec;
  std::string line;
  std::size_t line_no = 0;
  int64_t nR = 0, nL = 0;
  while (util::getBoundedLine(in, line, util::kMaxLineBytes, run_path, ++line_no)) {
    auto c = splitCsv(line);
    if (c.empty()) continue;
    const std::string where = fmt::format("{}:{}", run_path, line_no);
    if (c.size() != 6)
      throw FormatError(fmt::format("{}: {} columns, expected 6 (t, x_gt, y_gt, th_gt, odoR, odoL)",
                                    where, c.size()));
    double v[6];
    for (int k = 0; k < 6; ++k) v[k] = number(c[k], where);
    if (!rec.encoders.empty() && !(v[0] > rec.encoders.back().t_s))
      throw FormatError(fmt::format("{}: time {} does not increase", where, v[0]));
    if (v[4] != std::round(v[4]) || v[5] != std::round(v[5]))
      throw FormatError(fmt::format("{}: ticks {} {} are not whole counts", where, v[4], v[5]));
    nR += static_cast<int64_t>(v[4]), nL += static_cast<int64_t>(v[5]);
    if (std::abs(nR) > INT32_MAX || std::abs(nL) > INT32_MAX)
      throw FormatError(where + ": accumulated ticks exceed the 32-bit counter");
    rec.encoders.push_back({v[0], static_cast<int32_t>(nR), static_cast<int32_t>(nL)});
    rec.ground_truth.push_back({v[0], v[1], v[2], v[3]});
  }
  if (rec.encoders.size() < 2) throw FormatError(run_path + ": fewer than 2 rows");

  const double m_per_tick_mean =
      M_PI * 0.5 * (g.wheel_diameter_right_m + g.wheel_diameter_left_m) / g.ticksPerWheelRev();
  const double t_first = rec.encoders.front().t_s;
  for (auto& c : log.cmds)
    rec.joystick.push_back(
        {t_first + c.t_s, c.v_cmd_m_s * m_per_tick_mean / kCycle_s, c.omega_cmd_rad_s / kCycle_s});

  rep.cycles = rec.encoders.size();
  rep.commands = rec.joystick.size();
  rep.duration_s = rec.encoders.back().t_s - t_first;
  rep.path_kind = rep.square_side_m > 0 ? "square" : "other";
  // direction: the sign of the total turn, from the ticks (right ahead = turning left = ccw)
  rep.direction = (nR - nL) * g.wheel_diameter_right_m > 0 ? "ccw" : "cw";

  rec.meta["source"] = fmt::format("OptiOdom {} run {}", id, run);
  rec.meta["citation"] =
      "R. B. Sousa, M. R. Petry, P. G. Costa, A. P. Moreira, OptiOdom: a Generic Approach for "
      "Odometry Calibration of Wheeled Mobile Robots, J. Intell. Robot. Syst. 105, 39, 2022";
  rec.meta["experiment"] = id;
  rec.meta["run"] = std::to_string(run);
  rec.meta["path"] = rep.path_kind;
  rec.meta["direction"] = rep.direction;
  if (rep.square_side_m > 0) rec.meta["square_side_m"] = fmt::format("{}", rep.square_side_m);
  if (!rep.method.empty()) rec.meta["method"] = rep.method;
  if (report) *report = rep;
  return rec;
}

std::vector<OptiodomRun> importOptiodomFolder(const std::string& root) {
  std::vector<std::filesystem::path> experiments;
  for (const auto& e : std::filesystem::directory_iterator(root))
    if (e.is_directory()) experiments.push_back(e.path());
  std::sort(experiments.begin(), experiments.end());
  std::vector<OptiodomRun> runs;
  for (const auto& e : experiments) {
    int n = 1;  // N from run 1's metadata
    for (int k = 1; k <= n; ++k) {
      OptiodomRun r;
      r.rec = importOptiodom(e.string(), k, &r.report);
      n = r.report.runs_in_metadata;
      runs.push_back(std::move(r));
    }
  }
  return runs;
}

void applyOptiodomGeometry(const OptiodomGeometry& g, config::WheelchairConfig& cfg) {
  auto& geom = cfg.vehicle.geom;
  geom.wheel_radius_m = 0.25 * (g.wheel_diameter_right_m + g.wheel_diameter_left_m);
  geom.wheel_radius_right_m = 0.5 * g.wheel_diameter_right_m;
  geom.wheel_radius_left_m = 0.5 * g.wheel_diameter_left_m;
  geom.track_width_m = g.track_m;
  geom.gear_ratio = g.gear_ratio;
  // ticks per wheel turn = counts_per_rev * wheel_pulley / encoder_pulley = encRes * ngear:
  // ngear as the smallest power-of-ten fraction (43.7 = 437 / 10)
  int den = 1;
  while (den < 1000000 && std::abs(g.gear_ratio * den - std::round(g.gear_ratio * den)) > 1e-6)
    den *= 10;
  cfg.encoders.params.counts_per_rev = g.counts_per_motor_rev;
  cfg.encoders.params.wheel_pulley_teeth = static_cast<int>(std::lround(g.gear_ratio * den));
  cfg.encoders.params.encoder_pulley_teeth = den;
  cfg.encoders.rate_hz = 1.0 / kCycle_s;
  cfg.joystick.rate_hz = 1.0 / kCycle_s;
  cfg.syncToIni();
}

}  // namespace wheelchair::io
