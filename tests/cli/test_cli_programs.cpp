// The two programs of the command line (apps/wheelchair/FullProgram.h): `wheelchair` runs the
// GUI/3-D/hardware commands in `wheelchair-full`; both know every command and every options
// table, and `wheelchair` does not load the libraries only those commands need.
#include "../common/TestUtil.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <regex>
#include <string>

namespace fs = std::filesystem;
using wheelchair::test::cli;
using wheelchair::test::run;
using wheelchair::test::TempDir;

namespace {

const std::string kCli = WHEELCHAIR_CLI;
const std::string kFull = (fs::path(WHEELCHAIR_CLI).parent_path() / "wheelchair-full").string();

// The programs' outputs with the program's own path (CLI11's "Usage: PATH ...") taken out.
std::string withoutProgramPath(std::string s, const std::string& path) {
  for (auto at = s.find(path); at != std::string::npos; at = s.find(path, at))
    s.replace(at, path.size(), "PROGRAM");
  return s;
}

const char* const kFullOnly[] = {"capture", "diagnose", "replay-serial", "report", "view"};

}  // namespace

TEST(CliPrograms, BothProgramsKnowEveryOptionsTable) {
  // The strict INI check treats a section no table registered as a typo: `wheelchair` must
  // register exactly the tables of the full program.
  const auto lean = cli("config --dump"), full = run(kFull + " config --dump");
  ASSERT_EQ(lean.exit_code, 0) << lean.out;
  ASSERT_EQ(full.exit_code, 0) << full.out;
  EXPECT_NE(lean.out.find("[diagnosis]"), std::string::npos) << lean.out;
  EXPECT_NE(lean.out.find("[estimator]"), std::string::npos) << lean.out;
  EXPECT_EQ(lean.out, full.out);
}

TEST(CliPrograms, HelpListsEveryCommandOfTheFullProgram) {
  const auto lean = cli("--help"), full = run(kFull + " --help");
  ASSERT_EQ(lean.exit_code, 0) << lean.out;
  EXPECT_EQ(withoutProgramPath(lean.out, kCli), withoutProgramPath(full.out, kFull));
  for (const char* c : kFullOnly) EXPECT_NE(lean.out.find(c), std::string::npos) << c;
}

TEST(CliPrograms, FullOnlyCommandsRunInTheFullProgramWithTheSameArguments) {
  for (const char* c : kFullOnly) {
    const auto lean = cli(std::string(c) + " --help"), full = run(kFull + " " + c + " --help");
    EXPECT_EQ(lean.exit_code, 0) << c << ": " << lean.out;
    EXPECT_EQ(withoutProgramPath(lean.out, kCli), withoutProgramPath(full.out, kFull)) << c;
    EXPECT_NE(lean.out.find("Example (from the repository root)"), std::string::npos) << c;
  }
  // Errors and exit codes are the full program's; the global option before the command counts.
  TempDir dir;
  const auto missing = cli("--lenient report " + dir / "none.rawlog" + " -o " + dir / "r");
  EXPECT_EQ(missing.exit_code, 1) << missing.out;
  EXPECT_NE(missing.out.find("wheelchair report: error:"), std::string::npos) << missing.out;
  EXPECT_NE(missing.out.find("none.rawlog"), std::string::npos) << missing.out;
  const auto usage = cli("view --no-such-option x.rawlog");
  EXPECT_EQ(usage.exit_code, 2) << usage.out;
}

TEST(CliPrograms, WheelchairDoesNotLoadTheGuiAndDriverLibraries) {
  const auto lean = run("ldd " + kCli), full = run("ldd " + kFull);
  ASSERT_EQ(lean.exit_code, 0) << lean.out;
  ASSERT_EQ(full.exit_code, 0) << full.out;
  for (const char* lib : {"libmrpt-gui", "libmrpt-hwdrivers", "libwx_"}) {
    EXPECT_EQ(lean.out.find(lib), std::string::npos) << lib;
    EXPECT_NE(full.out.find(lib), std::string::npos) << lib;
  }
}

TEST(CliPrograms, AMissingFullProgramIsOneLineAndExitOne) {
  TempDir dir;
  fs::copy_file(kCli, dir / "wheelchair");
  fs::permissions(dir / "wheelchair", fs::perms::owner_all);
  const auto r = run(dir / "wheelchair" + " view x.rawlog");
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_TRUE(std::regex_search(
      r.out, std::regex("^wheelchair view: error: cannot run .*wheelchair-full: No such file "
                        "or directory \\(view is in wheelchair-full, built with wheelchair\\)\n$")))
      << r.out;
  // The other commands still run in the program itself.
  EXPECT_EQ(run(dir / "wheelchair" + " config --dump").exit_code, 0);
}
