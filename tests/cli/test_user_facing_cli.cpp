// What the user sees through the `wheelchair` CLI (issue 13, "Trustworthy on real recordings"):
// one verdict per sensor from `filter`, the metrics table and "n/a" variants of `evaluate`,
// "insufficient data" from `diagnose` on short data, units on every printed number, plain
// column names in `info`, and a working example at the end of every command's --help.
// Runs on the bundled recordings (datasets/), imported once per suite.
#include "../common/TestUtil.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

namespace wheelchair::test {
namespace {

class UserFacingCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir();
    for (const char* name : {"three_task_faulty", "three_task_clean"}) {
      const auto r = cli("import " + sourcePath(std::string("datasets/") + name) + " -o " +
                         (*dir_ / (std::string(name) + ".rawlog")));
      ASSERT_EQ(r.exit_code, 0) << r.out;
    }
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static std::string rawlog(const std::string& name) { return *dir_ / (name + ".rawlog"); }
  static std::string tmp(const std::string& name) { return *dir_ / name; }
  static TempDir* dir_;
};
TempDir* UserFacingCli::dir_ = nullptr;

std::vector<std::string> linesStartingWith(const std::string& text, const std::string& prefix) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);)
    if (line.rfind(prefix, 0) == 0) out.push_back(line);
  return out;
}

// filter: the faulty drive rejects about half the encoder updates; the verdict says so in
// words and points to diagnose; the gyro's verdict does not call it faulty; the clean drive
// has no "inconsistent" sensor.
TEST_F(UserFacingCli, FilterPrintsOneVerdictPerSensor) {
  const auto r = cli("filter " + rawlog("three_task_faulty") + " --no-progress");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto verdicts = linesStartingWith(r.out, "verdict: ");
  ASSERT_EQ(verdicts.size(), 4u) << r.out;  // encoders, gyro, sonar, pozyx
  EXPECT_NE(verdicts[0].find("verdict: encoders: 5"), std::string::npos) << verdicts[0];
  EXPECT_NE(verdicts[0].find("% of updates rejected"), std::string::npos) << verdicts[0];
  EXPECT_NE(verdicts[0].find("inconsistent"), std::string::npos) << verdicts[0];
  EXPECT_NE(verdicts[0].find("diagnose"), std::string::npos) << verdicts[0];
  EXPECT_EQ(verdicts[1].find("inconsistent"), std::string::npos) << verdicts[1];
  EXPECT_NE(verdicts[3].find("pozyx: not used"), std::string::npos) << verdicts[3];

  const auto c = cli("filter " + rawlog("three_task_clean") + " --no-progress");
  ASSERT_EQ(c.exit_code, 0) << c.out;
  const auto clean = linesStartingWith(c.out, "verdict: ");
  ASSERT_EQ(clean.size(), 4u) << c.out;
  for (const auto& v : clean) EXPECT_EQ(v.find("inconsistent"), std::string::npos) << v;
}

}  // namespace
}  // namespace wheelchair::test

namespace wheelchair::test {
namespace {

// evaluate prints the metrics table (with units) on the console, not just a count.
TEST_F(UserFacingCli, EvaluatePrintsTheMetricsTable) {
  const auto r = cli("evaluate " + rawlog("three_task_faulty") + " -q --no-baseline");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("ATE RMSE (m)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("heading (deg)"), std::string::npos) << r.out;
  for (const char* v : {" ekf ", " encoders ", " encoders_gyro "}) {
    const auto rows = linesStartingWith(r.out, rawlog("three_task_faulty"));
    bool found = false;
    for (const auto& row : rows) found |= row.find(v) != std::string::npos;
    EXPECT_TRUE(found) << v << "\n" << r.out;
  }
  // `--csv -`: the CSV on stdout instead.
  const auto c = cli("evaluate " + rawlog("three_task_faulty") + " -q --no-baseline --csv -");
  ASSERT_EQ(c.exit_code, 0) << c.out;
  EXPECT_EQ(c.out.rfind("recording,variant,ground_truth,", 0), 0u) << c.out;
}

// A recording whose imu.csv has only its header: import warns naming the file; evaluate lists
// encoders_gyro as n/a (console, CSV, JSON, Markdown) instead of an ATE computed without a
// gyro, and that is not a failure.
TEST_F(UserFacingCli, EvaluateListsVariantsWithoutTheirSensorAsNotApplicable) {
  const std::string dir = tmp("nogyro");
  std::filesystem::create_directories(dir);
  for (const auto& e :
       std::filesystem::directory_iterator(sourcePath("datasets/three_task_faulty")))
    std::filesystem::copy_file(e.path(), dir + "/" + e.path().filename().string(),
                               std::filesystem::copy_options::overwrite_existing);
  const std::string imu = readFile(dir + "/imu.csv");
  writeFile(dir + "/imu.csv", imu.substr(0, imu.find('\n') + 1));
  const auto imp = cli("import " + dir + " -o " + tmp("nogyro.rawlog"));
  ASSERT_EQ(imp.exit_code, 0) << imp.out;
  EXPECT_NE(imp.out.find("warning: " + dir + "/imu.csv: header only"), std::string::npos)
      << imp.out;

  const auto r = cli("evaluate " + tmp("nogyro.rawlog") + " --no-baseline --csv " + tmp("ng.csv") +
                     " --json " + tmp("ng.json") + " --markdown " + tmp("ng.md"));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  bool console = false;
  for (const auto& row : linesStartingWith(r.out, tmp("nogyro.rawlog")))
    if (row.find("encoders_gyro") != std::string::npos) {
      console = true;
      EXPECT_NE(row.find("n/a: no gyro"), std::string::npos) << row;
    }
  EXPECT_TRUE(console) << r.out;
  EXPECT_NE(r.out.find("0 failed, 1 variant(s) not applicable"), std::string::npos) << r.out;

  const std::string csv = readFile(tmp("ng.csv"));
  EXPECT_NE(csv.find(",encoders_gyro,pozyx,n/a,n/a,"), std::string::npos) << csv;
  EXPECT_NE(csv.find(",no gyro (imu) readings\n"), std::string::npos) << csv;
  const auto j = nlohmann::json::parse(readFile(tmp("ng.json")));
  int na = 0;
  for (const auto& row : j["rows"]) {
    if (row["variant"] == "encoders_gyro") {
      ++na;
      EXPECT_EQ(row["not_applicable"], "no gyro (imu) readings");
      EXPECT_TRUE(row["ate_rmse_m"].is_null());
      EXPECT_EQ(row["error"], "");
    } else {
      EXPECT_EQ(row["not_applicable"], "");
      EXPECT_TRUE(row["ate_rmse_m"].is_number());
    }
  }
  EXPECT_EQ(na, 1);
  EXPECT_NE(readFile(tmp("ng.md")).find("| encoders_gyro | pozyx | n/a | n/a |"),
            std::string::npos);
}

}  // namespace
}  // namespace wheelchair::test

namespace wheelchair::test {
namespace {

// A cut [t0, t1] s of a bundled recording directory, imported.
std::string importCut(const std::string& dataset, double t0, double t1, const std::string& out) {
  const std::string dir = out + ".d";
  std::filesystem::create_directories(dir);
  for (const auto& e : std::filesystem::directory_iterator(sourcePath("datasets/" + dataset))) {
    const std::string name = e.path().filename().string();
    std::istringstream in(readFile(e.path().string()));
    std::string text, line;
    bool header = true;
    while (std::getline(in, line)) {
      if (header || name == "meta.ini") {
        text += line + "\n";
        header = name == "meta.ini";
        continue;
      }
      const double t = std::stod(line.substr(0, line.find(',')));
      if (t >= t0 && t <= t1) text += line + "\n";
    }
    writeFile(dir + "/" + name, text);
  }
  const auto r = cli("import " + dir + " -o " + out);
  EXPECT_EQ(r.exit_code, 0) << r.out;
  return out;
}

// diagnose on 2 s of the faulty drive (the left encoder is 5 % short) must not name an
// encoder: the first 2 s (standing) cannot show an encoder fault at all, 2 s of steady driving
// cannot tell a short left from a long right encoder; both say "insufficient data" and what to
// drive. The full drive still names the left encoder.
TEST_F(UserFacingCli, DiagnoseSaysInsufficientDataOnShortDrives) {
  const auto first = cli("diagnose " + importCut("three_task_faulty", 0, 2, tmp("first2.rawlog")) +
                         " --json " + tmp("first2.json"));
  ASSERT_EQ(first.exit_code, 0) << first.out;
  EXPECT_EQ(first.out.find("- encoder_scale"), std::string::npos) << first.out;
  EXPECT_NE(first.out.find("insufficient data: whether an encoder is off"), std::string::npos)
      << first.out;
  EXPECT_NE(first.out.find("drive about"), std::string::npos) << first.out;
  EXPECT_EQ(first.out.find("mismatch: no\n"), std::string::npos) << first.out;

  for (const double t0 : {4.0, 10.0}) {
    const auto r = cli("diagnose " +
                       importCut("three_task_faulty", t0, t0 + 2,
                                 tmp("cut" + std::to_string(int(t0)) + ".rawlog")) +
                       " --json " + tmp("cut.json"));
    ASSERT_EQ(r.exit_code, 0) << r.out;
    EXPECT_EQ(r.out.find("- encoder_scale"), std::string::npos) << t0 << ":\n" << r.out;
    EXPECT_NE(r.out.find("insufficient data: which encoder is off"), std::string::npos)
        << t0 << ":\n"
        << r.out;
    EXPECT_NE(r.out.find("turn in both directions"), std::string::npos) << r.out;
    const auto j = nlohmann::json::parse(readFile(tmp("cut.json")));
    EXPECT_EQ(j["info"]["insufficient_data"].size(), 1u) << j["info"].dump();
  }

  const auto full = cli("diagnose " + rawlog("three_task_faulty") + " --json " + tmp("full.json"));
  ASSERT_EQ(full.exit_code, 0) << full.out;
  EXPECT_NE(full.out.find("- encoder_scale: the left encoder reports 0.95"), std::string::npos)
      << full.out;
  EXPECT_EQ(full.out.find("insufficient data"), std::string::npos) << full.out;
}

}  // namespace
}  // namespace wheelchair::test

namespace wheelchair::test {
namespace {

double numberAfter(const std::string& text, const std::string& key) {
  const auto p = text.find(key);
  if (p == std::string::npos) return std::nan("");
  return std::stod(text.substr(p + key.size()));
}

// Every validation RMS diagnose prints has its unit and is the quantity the report's figures
// show (index.md "Residuals and trajectories in the figures": nominal model before, corrected
// after, gyro channel in rad/s). Agreement within 5 %: the figures apply the corrected
// configuration through the model extensions, the printed "after" is the regression's.
TEST_F(UserFacingCli, DiagnosePrintedRmsHasUnitsAndMatchesTheFigures) {
  const auto imp =
      cli("import " + sourcePath("datasets/three_task_faulty_b") + " -o " + tmp("faulty_b.rawlog"));
  ASSERT_EQ(imp.exit_code, 0) << imp.out;
  const auto r =
      cli("diagnose " + rawlog("three_task_faulty") + " --validate " + tmp("faulty_b.rawlog") +
          " --json " + tmp("d.json") + " --report " + tmp("rep"));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto lines = linesStartingWith(r.out, "  ");
  int rms_lines = 0;
  for (const auto& l : lines) {
    if (l.find("RMS") == std::string::npos && l.find("rms") == std::string::npos) continue;
    ++rms_lines;
    // A number followed by its unit (not merely a word starting with "A").
    EXPECT_TRUE(std::regex_search(l, std::regex(R"([0-9] (A|rad/s|m/s)\b)"))) << "no unit: " << l;
  }
  EXPECT_EQ(rms_lines, 3) << r.out;
  const std::string md = readFile(tmp("rep/index.md"));
  const auto figure = [&](const std::string& row) {
    const auto p = md.find("| " + row + " |");
    EXPECT_NE(p, std::string::npos) << row << "\n" << md;
    std::vector<double> v;
    std::istringstream in(md.substr(p + row.size() + 4, md.find('\n', p) - p - row.size() - 4));
    for (std::string cell; std::getline(in, cell, '|');) v.push_back(std::stod(cell));
    return v;  // mean before, mean after, RMS before, RMS after
  };
  const auto near = [](double printed, double fig, const std::string& what) {
    EXPECT_NEAR(printed, fig, 0.05 * std::abs(fig) + 1e-4) << what;
  };
  const auto gyro = figure("gyro_vs_encoders (rad/s)");
  near(numberAfter(r.out, "validation RMS: before "), gyro[2], "gyro before");
  near(numberAfter(r.out, "rad/s, after "), gyro[3], "gyro after");
  for (const std::string ch : {"current_right", "current_left"}) {
    const auto fig = figure(ch + " (A)");
    const std::string line = linesStartingWith(r.out, "  " + ch)[0];
    near(numberAfter(line, "nominal model "), fig[2], ch + " before");
    near(numberAfter(line, "A, corrected "), fig[3], ch + " after");
  }
}

}  // namespace
}  // namespace wheelchair::test

namespace wheelchair::test {
namespace {

// diagnose shows progress like filter when stderr is a terminal (a pseudo-terminal from
// script(1) here): the reading bar and the stage with elapsed seconds; --no-progress and a
// non-terminal stderr show none.
TEST_F(UserFacingCli, DiagnoseShowsProgressOnATerminal) {
  if (run("command -v script").exit_code != 0) GTEST_SKIP() << "script(1) not installed";
  // A bare chroot without devpts has no pseudo-terminals (as the capture pty tests find).
  if (run("script -qec true /dev/null").exit_code != 0)
    GTEST_SKIP() << "no pseudo-terminal on this machine (script(1) cannot create one)";
  const std::string cmd = std::string(WHEELCHAIR_CLI) + " diagnose " + rawlog("three_task_faulty") +
                          " --json " + tmp("p.json");
  const auto tty = run("script -qec '" + cmd + "' /dev/null");
  ASSERT_EQ(tty.exit_code, 0) << tty.out;
  EXPECT_NE(tty.out.find("reading      ["), std::string::npos) << tty.out;
  EXPECT_NE(tty.out.find("diagnosing   ..."), std::string::npos) << tty.out;
  EXPECT_NE(tty.out.find("mismatch: yes"), std::string::npos) << tty.out;
  const auto quiet = run("script -qec '" + cmd + " --no-progress' /dev/null");
  ASSERT_EQ(quiet.exit_code, 0) << quiet.out;
  EXPECT_EQ(quiet.out.find("diagnosing"), std::string::npos) << quiet.out;
  const auto pipe = cli("diagnose " + rawlog("three_task_faulty") + " --json " + tmp("p.json"));
  EXPECT_EQ(pipe.out.find("diagnosing"), std::string::npos) << pipe.out;
}

}  // namespace
}  // namespace wheelchair::test

namespace wheelchair::test {
namespace {

// Every subcommand's --help ends with a working example (run from the repository root on the
// bundled recordings) and shows option defaults; the examples that need no hardware or display
// are run as written, in a scratch directory that links datasets/ and config/.
TEST(CliHelp, EveryCommandEndsWithAWorkingExample) {
  const auto top = cli("--help");
  ASSERT_EQ(top.exit_code, 0) << top.out;
  std::vector<std::string> commands;
  bool in_list = false;
  std::istringstream in(top.out);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("Subcommands:", 0) == 0)
      in_list = true;
    else if (in_list && line.rfind("  ", 0) == 0)
      commands.push_back(line.substr(2, line.find(' ', 2) - 2));
  }
  ASSERT_GE(commands.size(), 12u) << top.out;

  TempDir dir;
  std::filesystem::create_directories(dir / "bin");
  std::filesystem::create_symlink(WHEELCHAIR_CLI, dir / "bin/wheelchair");
  std::filesystem::create_directory_symlink(sourcePath("datasets"), dir / "datasets");
  std::filesystem::create_directory_symlink(sourcePath("config"), dir / "config");
  const std::vector<std::string> runnable{"import", "info",     "filter",   "evaluate", "diagnose",
                                          "export", "identify", "simulate", "report"};
  int ran = 0;
  for (const auto& c : commands) {
    const auto h = cli(c + " --help");
    ASSERT_EQ(h.exit_code, 0) << c << ": " << h.out;
    const auto at = h.out.find("\nExample (from the repository root):\n  wheelchair ");
    ASSERT_NE(at, std::string::npos) << c << " --help has no example:\n" << h.out;
    std::string example = h.out.substr(at + 1);
    example = example.substr(example.find('\n') + 3);
    example = example.substr(0, example.find('\n'));
    EXPECT_EQ(h.out.find('\n', h.out.find(example) + example.size()) + 1, h.out.size())
        << c << ": the example is not the end of --help";
    if (std::find(runnable.begin(), runnable.end(), c) == runnable.end()) continue;
    example = example.substr(0, example.find("   ("));  // a trailing note
    const auto r = run("cd " + dir.path().string() + " && export PATH=" + (dir / "bin") +
                       ":$PATH && " + example);
    EXPECT_EQ(r.exit_code, 0) << c << " example failed: " << example << "\n" << r.out;
    ++ran;
  }
  EXPECT_EQ(ran, static_cast<int>(runnable.size()));
  // Defaults are shown (CLI11 "=value"), e.g. evaluate's alignment and report's.
  EXPECT_NE(cli("evaluate --help").out.find("--alignment TEXT=se2"), std::string::npos);
  EXPECT_NE(cli("view --help").out.find("--width INT=1200"), std::string::npos);
}

// info names its timestamp-health columns in words, with units on every numeric column.
TEST_F(UserFacingCli, InfoColumnsHavePlainNamesAndUnits) {
  const auto r = cli("info " + rawlog("three_task_faulty"));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  for (const char* col :
       {"rate (Hz)", "span (s)", "largest gap (s)", "out of order", "same timestamp"})
    EXPECT_NE(r.out.find(col), std::string::npos) << col << "\n" << r.out;
  EXPECT_EQ(r.out.find(" dups"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("  order "), std::string::npos) << r.out;
}

}  // namespace
}  // namespace wheelchair::test
