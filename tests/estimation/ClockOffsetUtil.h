// Shared by the clock-offset tests: a bundled plain-text drive with every timestamp shifted by
// a constant (what a logger stamping UNIX time writes), imported through the CLI, and a small
// CSV reader for the files the CLI writes.
#pragma once

#include "../common/TestUtil.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

namespace wheelchair::test {

/// UNIX time of November 2023: the order of magnitude of every real logger's stamps.
constexpr double kUnixOffset_s = 1.7e9;

/// Copies recording directory `src` to `dst` with `offset_s` added to the time column of every
/// CSV file (printed at 1 us, the resolution of the bundled files); `edit(t_s)` may change a
/// shifted time further (e.g. a clock jump). Other files are copied as they are.
inline void shiftRecording(const std::string& src, const std::string& dst, double offset_s,
                           const std::function<double(double)>& edit = {}) {
  namespace fs = std::filesystem;
  fs::create_directories(dst);
  for (const auto& e : fs::directory_iterator(src)) {
    const std::string name = e.path().filename().string();
    if (e.path().extension() != ".csv") {
      fs::copy_file(e.path(), fs::path(dst) / name, fs::copy_options::overwrite_existing);
      continue;
    }
    std::ifstream in(e.path());
    std::ofstream out(fs::path(dst) / name);
    std::string line;
    bool header = true;
    while (std::getline(in, line)) {
      if (header || line.empty()) {
        out << line << "\n";
        header = false;
        continue;
      }
      const auto comma = line.find(',');
      double t = std::stod(line.substr(0, comma)) + offset_s;
      if (edit) t = edit(t);
      out << fmt::format("{:.6f}", t) << line.substr(comma) << "\n";
    }
  }
}

/// `wheelchair import` of bundled dataset `name` shifted by offset_s; returns the rawlog path.
inline std::string importShifted(const TempDir& tmp, const std::string& name, double offset_s) {
  const std::string dir = tmp / fmt::format("{}-{:.0f}", name, offset_s);
  shiftRecording(sourcePath("datasets/" + name), dir, offset_s);
  const std::string out = dir + ".rawlog";
  const auto r = cli("import " + dir + " -o " + out);
  EXPECT_EQ(r.exit_code, 0) << r.out;
  return out;
}

struct CsvTable {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  int col(const std::string& name) const {
    for (std::size_t i = 0; i < header.size(); ++i)
      if (header[i] == name) return static_cast<int>(i);
    ADD_FAILURE() << "no column " << name;
    return 0;
  }
};

/// A number of a CSV the CLI wrote (fails the test naming the text when it is not one).
inline double num(const std::string& s) {
  char* end = nullptr;
  const double x = std::strtod(s.c_str(), &end);  // (std::stod refuses subnormal values)
  if (!s.empty() && end == s.c_str() + s.size()) return x;
  ADD_FAILURE() << "not a number: '" << s << "'";
  return std::nan("");
}

inline CsvTable readCsv(const std::string& path) {
  CsvTable t;
  std::ifstream in(path);
  std::string line;
  auto split = [](const std::string& s) {
    std::vector<std::string> f;
    std::stringstream ss(s);
    std::string x;
    while (std::getline(ss, x, ',')) f.push_back(x);
    if (!s.empty() && s.back() == ',') f.emplace_back();
    return f;
  };
  if (std::getline(in, line)) t.header = split(line);
  while (std::getline(in, line))
    if (!line.empty()) t.rows.push_back(split(line));
  return t;
}

}  // namespace wheelchair::test
