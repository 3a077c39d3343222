#include "libwheelchair/io/MrclamImport.h"

#include "libwheelchair/util/Text.h"

#include "libwheelchair/io/TextFormat.h"

#include <fmt/format.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

namespace fs = std::filesystem;

namespace wheelchair::io {

namespace {

// Reads whitespace-separated numeric rows with `ncols` columns, skipping '#' comments.
template <class F>
void readRows(const std::string& path, std::size_t ncols, F&& onRow) {
  std::ifstream in(path);
  if (!in) throw FormatError(fmt::format("{}: cannot open file", path));
  std::string line;
  std::size_t line_no = 0;
  std::vector<double> v;
  while (util::getBoundedLine(in, line, util::kMaxLineBytes, path, line_no + 1)) {
    ++line_no;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream ss(line);
    v.clear();
    std::string tok;
    while (ss >> tok) {
      char* end = nullptr;
      const double x = std::strtod(tok.c_str(), &end);
      if (*end != '\0' || !std::isfinite(x))
        throw FormatError(fmt::format("{}:{}: '{}' is not a finite number", path, line_no,
                                      util::quoteInput(tok)));
      v.push_back(x);
    }
    if (v.size() != ncols)
      throw FormatError(
          fmt::format("{}:{}: {} columns, expected {}", path, line_no, v.size(), ncols));
    onRow(v, line_no);
  }
}

}  // namespace

std::string MrclamImportReport::summary() const {
  return fmt::format(
      "{} commands ({:.1f} s .. {:.1f} s; {} duplicated timestamps, {} with conflicting "
      "values; {} isolated (0,0) lines; largest gap {:.2f} s at t = {:.1f}), {} ground-truth "
      "poses ({:.1f} s .. {:.1f} s; largest gap {:.2f} s), {} sightings ({} of mapped "
      "landmarks, {} unknown barcodes)",
      commands, commands_start_s, commands_end_s, duplicate_command_times,
      conflicting_duplicate_commands, isolated_zero_commands, largest_command_gap_s,
      largest_command_gap_at_s, ground_truth, ground_truth_start_s, ground_truth_end_s,
      largest_ground_truth_gap_s, sightings, landmark_sightings, unknown_barcodes);
}

Recording importMrclam(const std::string& dir, int robot, MrclamImportReport* report) {
  if (robot < 1 || robot > 5) throw std::invalid_argument("--robot must be 1..5");
  if (!fs::is_directory(dir)) throw FormatError(fmt::format("{}: not a directory", dir));
  const auto file = [&](const std::string& name) { return (fs::path(dir) / name).string(); };
  Recording rec;
  MrclamImportReport rep;

  std::map<int, int> subject_of_barcode;
  readRows(file("Barcodes.dat"), 2, [&](const std::vector<double>& v, std::size_t) {
    subject_of_barcode[static_cast<int>(v[1])] = static_cast<int>(v[0]);
  });
  std::map<int, LandmarkPosition> landmarks;
  readRows(file("Landmark_Groundtruth.dat"), 5, [&](const std::vector<double>& v, std::size_t) {
    const int id = static_cast<int>(v[0]);
    landmarks[id] = {id, v[1], v[2], v[3], v[4]};
    rec.meta[fmt::format("landmark.{:02d}", id)] =
        fmt::format("{} {} {} {}", v[1], v[2], v[3], v[4]);
  });

  readRows(file(fmt::format("Robot{}_Odometry.dat", robot)), 3,
           [&](const std::vector<double>& v, std::size_t) {
             if (!rec.joystick.empty()) {
               const auto& prev = rec.joystick.back();
               if (v[0] == prev.t_s) {
                 ++rep.duplicate_command_times;
                 if (v[1] != prev.v_cmd_m_s || v[2] != prev.omega_cmd_rad_s)
                   ++rep.conflicting_duplicate_commands;
               }
               if (v[0] < prev.t_s)
                 throw FormatError(fmt::format("Robot{}_Odometry.dat: time goes backwards", robot));
               const double gap = v[0] - prev.t_s;
               if (gap > rep.largest_command_gap_s) {
                 rep.largest_command_gap_s = gap;
                 rep.largest_command_gap_at_s = prev.t_s;
               }
             }
             rec.joystick.push_back({v[0], v[1], v[2]});
           });
  for (std::size_t i = 1; i + 1 < rec.joystick.size(); ++i) {
    const auto &a = rec.joystick[i - 1], &b = rec.joystick[i], &c = rec.joystick[i + 1];
    const bool zero = b.v_cmd_m_s == 0 && b.omega_cmd_rad_s == 0;
    const bool moving_around = (a.v_cmd_m_s != 0 || a.omega_cmd_rad_s != 0) &&
                               (c.v_cmd_m_s != 0 || c.omega_cmd_rad_s != 0);
    rep.isolated_zero_commands += zero && moving_around;
  }

  readRows(file(fmt::format("Robot{}_Groundtruth.dat", robot)), 4,
           [&](const std::vector<double>& v, std::size_t) {
             if (!rec.ground_truth.empty())
               rep.largest_ground_truth_gap_s =
                   std::max(rep.largest_ground_truth_gap_s, v[0] - rec.ground_truth.back().t_s);
             rec.ground_truth.push_back({v[0], v[1], v[2], v[3]});
           });

  readRows(file(fmt::format("Robot{}_Measurement.dat", robot)), 4,
           [&](const std::vector<double>& v, std::size_t) {
             const int barcode = static_cast<int>(v[1]);
             const auto it = subject_of_barcode.find(barcode);
             ++rep.sightings;
             if (it == subject_of_barcode.end()) {
               ++rep.unknown_barcodes;
               return;  // not a subject of this dataset: counted, not stored
             }
             rep.landmark_sightings += landmarks.count(it->second);
             rec.landmarks.push_back({v[0], it->second, v[2], v[3]});
           });

  rep.commands = rec.joystick.size();
  rep.ground_truth = rec.ground_truth.size();
  if (!rec.joystick.empty()) {
    rep.commands_start_s = rec.joystick.front().t_s;
    rep.commands_end_s = rec.joystick.back().t_s;
  }
  if (!rec.ground_truth.empty()) {
    rep.ground_truth_start_s = rec.ground_truth.front().t_s;
    rep.ground_truth_end_s = rec.ground_truth.back().t_s;
  }
  rec.meta["source"] = fmt::format("UTIAS MRCLAM {} robot {}", fs::path(dir).filename().string(), robot);
  rec.meta["citation"] =
      "K. Y. K. Leung, Y. Halpern, T. D. Barfoot, H. H. T. Liu, The UTIAS Multi-Robot "
      "Cooperative Localization and Mapping Dataset, IJRR 30(8), 2011";
  rec.meta["robot"] = std::to_string(robot);
  if (report) *report = rep;
  return rec;
}

std::vector<LandmarkPosition> landmarkMap(const Recording& rec) {
  std::vector<LandmarkPosition> out;
  for (const auto& [k, v] : rec.meta) {
    if (k.rfind("landmark.", 0) != 0) continue;
    LandmarkPosition p;
    p.id = std::stoi(k.substr(9));
    std::istringstream ss(v);
    if (ss >> p.x_m >> p.y_m >> p.sx_m >> p.sy_m) out.push_back(p);
  }
  return out;
}

}  // namespace wheelchair::io
