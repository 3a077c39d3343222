// AtomicFile: complete or absent, on success, on a write failure at any point, and for
// targets that are not regular files. SpilledColumns (the temporary file diagnose sets streams
// aside on): read back bit for bit; a write failure (a full disk) is a one-line error that
// loses nothing and leaves no file.
#include "libwheelchair/util/AtomicFile.h"
#include "libwheelchair/util/SpilledColumns.h"

#include "../common/TestUtil.h"

#include <gtest/gtest.h>
#include <algorithm>

#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <vector>

namespace fs = std::filesystem;
using wheelchair::util::AtomicFile;

namespace {

std::size_t entries(const fs::path& d) {
  return static_cast<std::size_t>(
      std::distance(fs::directory_iterator(d), fs::directory_iterator()));
}

/// Limits the size of files this process may write (a full disk at `bytes`, as far as write(2)
/// is concerned: it fails with EFBIG once the limit is reached) until destruction.
struct FileSizeLimit {
  rlimit old{};
  explicit FileSizeLimit(rlim_t bytes) {
    std::signal(SIGXFSZ, SIG_IGN);
    ::getrlimit(RLIMIT_FSIZE, &old);
    rlimit r = old;
    r.rlim_cur = bytes;
    ::setrlimit(RLIMIT_FSIZE, &r);
  }
  ~FileSizeLimit() { ::setrlimit(RLIMIT_FSIZE, &old); }
};

}  // namespace

TEST(AtomicFile, CommitsCompleteContentAndLeavesNoTemporary) {
  const wheelchair::test::TempDir tmp;
  const fs::path& d = tmp.path();
  const std::string target = (d / "out.txt").string();
  {
    AtomicFile f(target);
    EXPECT_FALSE(fs::exists(target));
    for (int i = 0; i < 100000; ++i) f.stream() << i << '\n';
    f.commit();
  }
  EXPECT_EQ(entries(d), 1u);
  const std::string s = wheelchair::test::readFile(target);
  EXPECT_EQ(s.substr(0, 4), "0\n1\n");
  EXPECT_EQ(s.substr(s.size() - 6), "99999\n");
}

TEST(AtomicFile, ReplacesAnExistingRegularFileOnlyOnCommit) {
  const wheelchair::test::TempDir tmp;
  const fs::path& d = tmp.path();
  const std::string target = (d / "out.txt").string();
  { std::ofstream(target) << "old\n"; }
  {
    AtomicFile f(target);
    f.stream() << "new\n";
    EXPECT_EQ(wheelchair::test::readFile(target), "old\n");  // untouched until commit
  }  // not committed: the old file stays, the temporary goes
  EXPECT_EQ(wheelchair::test::readFile(target), "old\n");
  EXPECT_EQ(entries(d), 1u);
  wheelchair::util::writeFileAtomically(target, [](std::ostream& os) { os << "new\n"; });
  EXPECT_EQ(wheelchair::test::readFile(target), "new\n");
}

TEST(AtomicFile, FullDiskThrowsOneLineAndLeavesNothing) {
  const wheelchair::test::TempDir tmp;
  const fs::path& d = tmp.path();
  const std::string target = (d / "big.txt").string();
  std::string what;
  {
    FileSizeLimit limit(200000);  // the file needs ~590 kB
    try {
      AtomicFile f(target);
      for (int i = 0; i < 100000; ++i) f.stream() << i << '\n';
      f.commit();
    } catch (const std::runtime_error& e) {
      what = e.what();
    }
  }
  EXPECT_NE(what.find(target), std::string::npos) << what;
  EXPECT_NE(what.find("cannot write"), std::string::npos) << what;
  EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  EXPECT_FALSE(fs::exists(target));
  EXPECT_EQ(entries(d), 0u);
}

TEST(AtomicFile, FailureOnlyAtTheFinalFlushIsStillAFailure) {
  // Small enough to sit in the stream's buffer until commit(): the write fails only there.
  const wheelchair::test::TempDir tmp;
  const fs::path& d = tmp.path();
  const std::string target = (d / "small.txt").string();
  FileSizeLimit limit(10);
  AtomicFile f(target);
  f.stream() << std::string(1000, 'x');
  EXPECT_NO_THROW(f.check());
  EXPECT_THROW(f.commit(), std::runtime_error);
  EXPECT_FALSE(fs::exists(target));
  EXPECT_EQ(entries(d), 0u);
}

TEST(AtomicFile, CheckStopsALongWriterEarly) {
  const wheelchair::test::TempDir tmp;
  const fs::path& d = tmp.path();
  const std::string target = (d / "long.txt").string();
  FileSizeLimit limit(100000);
  AtomicFile f(target);
  int written = 0;
  bool threw = false;
  try {
    for (; written < 10000000; ++written) {
      f.stream() << "0123456789\n";
      if (written % 1000 == 0) f.check();
    }
  } catch (const std::runtime_error&) {
    threw = true;
  }
  EXPECT_TRUE(threw);
  EXPECT_LT(written, 20000);
  EXPECT_EQ(entries(d), 0u);
}

TEST(AtomicFile, RefusesTargetsThatAreNotRegularFiles) {
  const wheelchair::test::TempDir tmp;
  const fs::path& d = tmp.path();
  const fs::path real = d / "real.txt";
  { std::ofstream(real) << "keep\n"; }
  const fs::path link = d / "link.txt";
  fs::create_symlink(real, link);
  const fs::path fifo = d / "fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0644), 0);
  for (const std::string& p :
       {link.string(), fifo.string(), std::string("/dev/null"), d.string()}) {
    try {
      AtomicFile f(p);
      ADD_FAILURE() << p << " accepted";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("refusing"), std::string::npos) << e.what();
    }
  }
  EXPECT_TRUE(fs::is_symlink(link));
  EXPECT_EQ(wheelchair::test::readFile(real), "keep\n");
  EXPECT_EQ(entries(d), 3u);
}

TEST(AtomicFile, ByNameWritersCommitWhatTheyWrote) {
  const wheelchair::test::TempDir tmp;
  const fs::path& d = tmp.path();
  const std::string target = (d / "lib.bin").string();
  AtomicFile f(target);
  { std::ofstream(f.tempPath(), std::ios::binary) << "written by a library"; }
  f.commit();
  EXPECT_EQ(wheelchair::test::readFile(target), "written by a library");
  EXPECT_EQ(entries(d), 1u);
}

TEST(AtomicFile, MissingDirectoryIsAOneLineError) {
  try {
    AtomicFile f("/nonexistent_dir_wc/x.txt");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent_dir_wc/x.txt"), std::string::npos);
  }
}

namespace {

/// The files this process holds open in `dir` (from /proc/self/fd; an unlinked one reads
/// "DIR/#123 (deleted)" or "DIR/name (deleted)").
std::vector<std::string> openFilesIn(const std::string& dir) {
  std::vector<std::string> v;
  for (const auto& e : fs::directory_iterator("/proc/self/fd")) {
    std::error_code ec;
    const std::string t = fs::read_symlink(e.path(), ec).string();
    if (!ec && t.rfind(dir + "/", 0) == 0) v.push_back(t);
  }
  return v;
}

}  // namespace

TEST(SpilledColumns, ColumnsComeBackBitForBitAndTheFileLeavesNoName) {
  struct Pose {
    double t_s;
    float x_m;
    int id;
  };
  std::vector<double> a(100000);
  for (std::size_t i = 0; i < a.size(); ++i) a[i] = std::sin(0.001 * double(i)) / 3.0;
  a[7] = std::numeric_limits<double>::quiet_NaN(), a[8] = -0.0;
  std::vector<Pose> b = {{0.5, 1.25f, 3}, {1.0, -2.5f, 4}};
  const std::vector<double> a0 = a;
  const std::vector<Pose> b0 = b;
  const auto before = openFilesIn("/tmp");
  {
    wheelchair::util::SpilledColumns sp("test: the columns");
    sp.spill(a), sp.spill(b);
    EXPECT_TRUE(a.empty() && b.empty());
    EXPECT_EQ(a.capacity(), 0u) << "the memory is released";
    EXPECT_EQ(sp.spilled(), 2u);
    // The file is open in /tmp (std::tmpfile, TMPDIR not consulted) without a name.
    const auto open = openFilesIn("/tmp");
    ASSERT_EQ(open.size(), before.size() + 1);
    // (only the new one: files the test runner holds open under /tmp, e.g. ctest's log when
    // the build tree is there, are inherited and named)
    for (const auto& f : open) {
      if (std::find(before.begin(), before.end(), f) == before.end()) {
        EXPECT_NE(f.find("(deleted)"), std::string::npos) << f;
      }
    }
    sp.restore();
    EXPECT_EQ(sp.spilled(), 0u);
    EXPECT_EQ(openFilesIn("/tmp").size(), before.size()) << "closed once restored";
  }
  ASSERT_EQ(a.size(), a0.size());
  EXPECT_EQ(std::memcmp(a.data(), a0.data(), a.size() * sizeof(double)), 0);
  ASSERT_EQ(b.size(), b0.size());
  EXPECT_EQ(std::memcmp(b.data(), b0.data(), b.size() * sizeof(Pose)), 0);
}

TEST(SpilledColumns, FullDiskIsAOneLineErrorThatLosesNothingAndLeavesNoFile) {
  std::vector<double> small(100, 1.5), big(100000, 2.5);  // 800 B and 800 kB
  const auto before = openFilesIn("/tmp");
  std::string err;
  {
    wheelchair::util::SpilledColumns sp("test: the streams");
    {
      const FileSizeLimit full(64 * 1024);  // the temporary file cannot grow past 64 kB
      sp.spill(small);
      EXPECT_TRUE(small.empty());
      try {
        sp.spill(big);
        ADD_FAILURE() << "a write past the limit was not reported";
      } catch (const std::runtime_error& e) {
        err = e.what();
      }
    }
    EXPECT_EQ(big.size(), 100000u) << "the column whose write failed stays in memory";
    EXPECT_EQ(big.front(), 2.5);
    EXPECT_EQ(big.back(), 2.5);
    sp.restore();  // what was written before the failure is still read back
    EXPECT_EQ(small, std::vector<double>(100, 1.5));
  }
  EXPECT_NE(err.find("test: the streams: temporary file (/tmp): cannot write: "), std::string::npos)
      << err;
  EXPECT_NE(err.find(std::strerror(EFBIG)), std::string::npos) << err;
  EXPECT_EQ(err.find('\n'), std::string::npos) << "one line: " << err;
  EXPECT_EQ(openFilesIn("/tmp").size(), before.size()) << "the temporary file is closed";
}
