// Every writer command on a full disk: a file-size limit on the child process (bash `ulimit -f`,
// 1024-byte blocks; the CLI ignores SIGXFSZ so write(2) fails with EFBIG) just below the size
// of its output, so only the final flush/close fails, and a limit of 0, so the first write
// fails. Each must exit 1 with one error line naming the target and leave neither the target
// nor a temporary in the output directory.
#include "../common/TestUtil.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <memory>

namespace fs = std::filesystem;
using wheelchair::test::cli;
using wheelchair::test::readFile;
using wheelchair::test::run;
using wheelchair::test::sourcePath;
using wheelchair::test::TempDir;

namespace {

struct Inputs {
  TempDir tmp;
  std::string rawlog, text_dir;
};

/// A short simulated drive (rawlog) and its text export, shared by the tests of this file.
const Inputs& inputs() {
  static const std::unique_ptr<Inputs> in = [] {
    auto p = std::make_unique<Inputs>();
    p->rawlog = p->tmp / "drive.rawlog";
    p->text_dir = p->tmp / "drive_text";
    const auto r = cli("simulate --scenario three_task --duration 8 -o " + p->rawlog);
    EXPECT_EQ(r.exit_code, 0) << r.out;
    const auto e = cli("export " + p->rawlog + " -o " + p->text_dir);
    EXPECT_EQ(e.exit_code, 0) << e.out;
    return p;
  }();
  return *in;
}

std::vector<std::string> entries(const fs::path& d) {
  std::vector<std::string> v;
  for (const auto& e : fs::recursive_directory_iterator(d)) v.push_back(e.path().string());
  return v;
}

uintmax_t largestFile(const fs::path& p) {
  if (fs::is_regular_file(p)) return fs::file_size(p);
  uintmax_t m = 0;
  for (const auto& e : fs::recursive_directory_iterator(p))
    if (e.is_regular_file()) m = std::max(m, e.file_size());
  return m;
}

/// Runs `args` with a file-size limit of `blocks` kB. Returns stderr (through a pipe: a file
/// would be limited too); sets `code`.
std::string runLimited(const std::string& args, long blocks, int& code) {
  const auto r = run("bash -c 'ulimit -f " + std::to_string(blocks) + "; exec " +
                     std::string(WHEELCHAIR_CLI) + " " + args + " >/dev/null'");
  code = r.exit_code;
  return r.out;
}

std::string replaceOut(std::string s, const std::string& out) {
  for (auto p = s.find("OUT"); p != std::string::npos; p = s.find("OUT", p + out.size()))
    s.replace(p, 3, out);
  return s;
}

/// `args` writes `late_target` (relative to OUT; a file or directory) among its outputs. The
/// error must name OUT, or `first_failure` when given (a larger file written before the
/// outputs, e.g. a temporary one, that a file-size limit stops first).
void checkWriter(const std::string& args, const std::string& late_target,
                 const std::string& first_failure = "") {
  TempDir tmp;
  const fs::path out = tmp.path() / "out";
  fs::create_directories(out);
  const std::string cmd = replaceOut(args, out.string());
  // Unlimited: succeeds; measure the output.
  const auto ok = cli(cmd);
  ASSERT_EQ(ok.exit_code, 0) << cmd << "\n" << ok.out;
  const uintmax_t size = largestFile(out / late_target);
  ASSERT_GT(size, 1024u) << late_target;
  // Late (only the final writes fail: the limit is just below the file's size) and early
  // (nothing can be written).
  for (const long blocks : {static_cast<long>((size - 1) / 1024), 0L}) {
    fs::remove_all(out);
    fs::create_directories(out);
    int code = -1;
    const std::string err = runLimited(cmd, blocks, code);
    SCOPED_TRACE(cmd + " with ulimit -f " + std::to_string(blocks) + ": " + err);
    EXPECT_EQ(code, 1);
    ASSERT_FALSE(err.empty());
    EXPECT_EQ(err.find('\n'), err.size() - 1) << "not one line";
    EXPECT_NE(err.find("error"), std::string::npos);
    EXPECT_NE(err.find(first_failure.empty() ? out.string() : first_failure), std::string::npos)
        << "does not name what failed";
    EXPECT_EQ(err.find("MRPT exception"), std::string::npos);
    EXPECT_TRUE(entries(out).empty()) << "left behind: " << entries(out).front();
  }
}

}  // namespace

TEST(CliFullDisk, Import) {
  checkWriter("import " + inputs().text_dir + " -o OUT/r.rawlog", "r.rawlog");
}

TEST(CliFullDisk, SimulateRawlog) {
  // The rawlog is written first: a disk that cannot hold it fails at its final flush.
  checkWriter("simulate --scenario three_task --duration 8 -o OUT/s.rawlog", "s.rawlog");
}

TEST(CliFullDisk, Export) {
  checkWriter("export " + inputs().rawlog + " -o OUT/x", "x");
}

TEST(CliFullDisk, EvaluateCsvJsonMarkdown) {
  checkWriter(
      "evaluate -q " + inputs().rawlog + " --csv OUT/e.csv --json OUT/e.json --markdown OUT/e.md",
      "e.json");
}

TEST(CliFullDisk, DiagnoseJsonAndConfig) {
  // Stage 2 first sets the streams it does not read aside on a temporary file in /tmp
  // (util::SpilledColumns, ~40 kB for this drive, more than d.json): under a file-size limit
  // that write fails first, and the error names it.
  checkWriter("diagnose " + inputs().rawlog + " --json OUT/d.json --write-config OUT/d.ini",
              "d.json",
              "diagnose: streams set aside during stage 2: temporary file (/tmp): "
              "cannot write: File too large");
}

TEST(CliFullDisk, DiagnoseJsonWithoutMotorCurrents) {
  // A recording without motor currents (the bundled MRCLAM slice: the command-response
  // analysis, no stage 2 and no temporary file): the late failure is d.json's own write.
  const TempDir t;
  const std::string rec = t / "r3.rawlog";
  const auto r =
      cli("import --format mrclam " + sourcePath("datasets/mrclam") + " --robot 3 -o " + rec);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  checkWriter(
      "diagnose " + rec + " --config " + sourcePath("config/mrclam.ini") + " --json OUT/d.json",
      "d.json");
}

TEST(CliFullDisk, Report) {
  checkWriter("report " + inputs().rawlog + " -o OUT/rep --no-3d", "rep");
}

TEST(CliFullDisk, IdentifyJson) {
  checkWriter("identify " + inputs().rawlog + " --json OUT/i.json", "i.json");
}

TEST(CliOutputTarget, SymlinkFifoAndDeviceAreRefused) {
  TempDir tmp;
  const std::string victim = tmp / "victim.txt", link = tmp / "link.rawlog",
                    fifo = tmp / "fifo.rawlog";
  wheelchair::test::writeFile(victim, "keep me\n");
  fs::create_symlink(victim, link);
  ASSERT_EQ(run("mkfifo " + fifo).exit_code, 0);
  for (const std::string& target : {link, fifo, std::string("/dev/null")}) {
    const auto r = cli("import " + inputs().text_dir + " -o " + target);
    EXPECT_EQ(r.exit_code, 1) << r.out;
    EXPECT_NE(r.out.find("refusing to replace"), std::string::npos) << r.out;
  }
  EXPECT_TRUE(fs::is_symlink(link));
  EXPECT_TRUE(fs::is_fifo(fifo));
  EXPECT_EQ(readFile(victim), "keep me\n");
  const auto r = cli("evaluate -q " + inputs().rawlog + " --json " + link);
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_TRUE(fs::is_symlink(link));
  EXPECT_EQ(readFile(victim), "keep me\n");
}
