// Errors that quote input: control bytes escaped, long text cut, and a huge line without a
// newline refused with its file and line without reading it all into memory.
#include "../common/TestUtil.h"

#include <gtest/gtest.h>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

namespace fs = std::filesystem;
using wheelchair::test::TempDir;

namespace {

struct ChildRun {
  int code = -1;
  long maxrss_kB = 0;
  std::string err;
};

/// Runs the CLI with `args` in a child process; its own peak RSS (wait4) and stderr.
ChildRun runMeasured(const std::string& args, const std::string& err_file) {
  ChildRun r;
  const std::string cmd = std::string(WHEELCHAIR_CLI) + " " + args + " >/dev/null 2>" + err_file;
  const pid_t pid = fork();
  if (pid == 0) {
    execl("/bin/sh", "sh", "-c", ("exec " + cmd).c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  int status = 0;
  rusage ru{};
  wait4(pid, &status, 0, &ru);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.maxrss_kB = ru.ru_maxrss;
  r.err = wheelchair::test::readFile(err_file);
  return r;
}

std::string copyDrive(const TempDir& tmp) {
  const std::string dir = tmp / "drive";
  fs::copy(wheelchair::test::sourcePath("datasets/three_task_clean"), dir);
  return dir;
}

}  // namespace

TEST(CliEcho, HugeLineWithoutNewlineIsRefusedInBoundedMemory) {
  TempDir tmp;
  const std::string dir = copyDrive(tmp);
  const auto base = runMeasured("import " + dir + " -o " + (tmp / "ok.rawlog"), tmp / "e0");
  ASSERT_EQ(base.code, 0) << base.err;
  {
    std::ofstream f(dir + "/imu.csv", std::ios::app | std::ios::binary);
    f << "1.0,";
    const std::string chunk(1 << 20, '7');
    for (int i = 0; i < 50; ++i) f << chunk;  // 50 MB, no newline
  }
  const auto big = runMeasured("import " + dir + " -o " + (tmp / "big.rawlog"), tmp / "e1");
  EXPECT_EQ(big.code, 1);
  EXPECT_EQ(big.err.find('\n'), big.err.size() - 1) << big.err.substr(0, 300);
  EXPECT_LT(big.err.size(), 300u);
  EXPECT_NE(big.err.find("imu.csv:"), std::string::npos) << big.err;
  EXPECT_NE(big.err.find("line longer than"), std::string::npos) << big.err;
  // Reading the whole line would cost at least 50 MB more than a normal import.
  EXPECT_LT(big.maxrss_kB - base.maxrss_kB, 30 * 1024) << big.maxrss_kB << " vs " << base.maxrss_kB;
  EXPECT_FALSE(fs::exists(tmp / "big.rawlog"));
}

TEST(CliEcho, ControlBytesAreEscapedAndLongFieldsCut) {
  TempDir tmp;
  const std::string dir = copyDrive(tmp);
  {
    std::ofstream f(dir + "/imu.csv", std::ios::app | std::ios::binary);
    f << "1.0,\x1b[2J\x07" << std::string(500, 'x') << "\r\n";
  }
  const auto r = runMeasured("import " + dir + " -o " + (tmp / "r.rawlog"), tmp / "e");
  EXPECT_EQ(r.code, 1);
  EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << r.err;
  EXPECT_EQ(r.err.find('\x1b'), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find('\x07'), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("\\x1b[2J\\x07xxx"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("x...'"), std::string::npos) << r.err;
  EXPECT_LT(r.err.size(), 300u) << r.err;
}

TEST(CliEcho, HugeConfigurationFileIsRefusedWithOneLine) {
  TempDir tmp;
  wheelchair::test::writeFile(tmp / "huge.ini", std::string(5u << 20, '#'));
  const auto r = runMeasured("import " + wheelchair::test::sourcePath("datasets/excite") +
                                 " --config " + (tmp / "huge.ini") + " -o " + (tmp / "r.rawlog"),
                             tmp / "e");
  EXPECT_EQ(r.code, 1);
  EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << r.err.substr(0, 300);
  EXPECT_NE(r.err.find("huge.ini: larger than"), std::string::npos) << r.err.substr(0, 300);
  EXPECT_FALSE(fs::exists(tmp / "r.rawlog"));
}
