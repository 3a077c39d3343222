// Damaged and empty rawlogs through every command that reads rawlogs: without --salvage a
// damaged file is refused with one line naming the record index, byte offset and reason (a
// damaged header as header damage); with --salvage every complete record is used and a
// warning says where and why the file broke. A 0-byte file is refused by every command.
#include "../common/GzipUtil.h"
#include "../common/TestUtil.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <memory>
#include <regex>

namespace fs = std::filesystem;
using wheelchair::test::cli;
using wheelchair::test::gunzip;
using wheelchair::test::gzipTo;
using wheelchair::test::readFile;
using wheelchair::test::run;
using wheelchair::test::TempDir;
using wheelchair::test::writeFile;

namespace {

struct Files {
  TempDir tmp;
  std::string good, cut, header, middle, empty;
};

/// The bundled drive three_task_clean as a rawlog, and damaged copies of it.
const Files& files() {
  static const std::unique_ptr<Files> f = [] {
    auto p = std::make_unique<Files>();
    p->good = p->tmp / "drive.rawlog";
    const auto r = cli("import " + wheelchair::test::sourcePath("datasets/three_task_clean") +
                       " -o " + p->good);
    EXPECT_EQ(r.exit_code, 0) << r.out;
    const std::string bytes = readFile(p->good);
    p->cut = p->tmp / "cut.rawlog";  // a copy interrupted at two thirds
    writeFile(p->cut, bytes.substr(0, bytes.size() * 2 / 3));
    p->middle = p->tmp / "middle.rawlog";  // one compressed byte flipped in the middle
    std::string mid = bytes;
    mid[mid.size() / 2] ^= 0x10;
    writeFile(p->middle, mid);
    p->header = p->tmp / "header.rawlog";  // one byte of the header's text flipped
    std::string raw = gunzip(p->good);
    const auto at = raw.find("[recording]");
    EXPECT_NE(at, std::string::npos);
    raw[at + 40] ^= 0x01;
    gzipTo(p->header, raw);
    p->empty = p->tmp / "empty.rawlog";
    writeFile(p->empty, "");
    return p;
  }();
  return *f;
}

/// The reading commands (FILE and OUT are replaced).
const std::vector<std::string> kReaders = {
    "info FILE",
    "filter FILE --trajectory OUT/t.tum",
    "export FILE -o OUT/x",
    "evaluate -q FILE --json OUT/e.json",
    "report FILE -o OUT/r --no-3d",
    "diagnose FILE --json OUT/d.json",
    "identify FILE --json OUT/i.json",
};

std::string subst(std::string s, const std::string& key, const std::string& v) {
  for (auto p = s.find(key); p != std::string::npos; p = s.find(key, p + v.size()))
    s.replace(p, key.size(), v);
  return s;
}

struct Outcome {
  int code = -1;
  std::string err;  ///< stderr only
};

Outcome runReader(const std::string& pattern, const std::string& file, const std::string& out) {
  const std::string args = subst(subst(pattern, "FILE", file), "OUT", out);
  const auto r = run("(" + std::string(WHEELCHAIR_CLI) + " " + args + " >/dev/null)");
  return {r.exit_code, r.out};
}

/// Every reader refuses `file` with one line matching `what`.
void expectRefusedByAll(const std::string& file, const std::regex& what) {
  for (const auto& cmd : kReaders) {
    TempDir out;
    const Outcome o = runReader(cmd, file, out.path().string());
    SCOPED_TRACE(cmd + ": " + o.err);
    EXPECT_EQ(o.code, 1);
    ASSERT_FALSE(o.err.empty());
    EXPECT_EQ(o.err.find('\n'), o.err.size() - 1) << "not one line";
    EXPECT_TRUE(std::regex_search(o.err, what));
    EXPECT_NE(o.err.find(file), std::string::npos) << "does not name the file";
    EXPECT_EQ(o.err.find("MRPT exception"), std::string::npos);
  }
}

}  // namespace

TEST(CliDamaged, EmptyFileIsRefusedByEveryCommand) {
  expectRefusedByAll(files().empty, std::regex("empty file \\(0 bytes\\), not a rawlog"));
}

TEST(CliDamaged, TruncatedFileIsRefusedWithRecordAndOffset) {
  expectRefusedByAll(
      files().cut, std::regex("record [1-9][0-9]* \\(uncompressed byte [0-9]+\\): file cut short"));
}

TEST(CliDamaged, ByteFlipInTheMiddleIsRefusedWithRecordAndOffset) {
  expectRefusedByAll(files().middle,
                     std::regex("record [1-9][0-9]* \\(uncompressed byte [1-9][0-9]*\\): [a-z]"));
}

TEST(CliDamaged, ByteFlipInTheHeaderIsReportedAsHeaderDamage) {
  expectRefusedByAll(files().header,
                     std::regex("record 0 \\(uncompressed byte 0\\): header record \\(META\\) "
                                "damaged: checksum mismatch"));
}

TEST(CliDamaged, SalvageUsesTheCompleteRecordsAndSaysWhereItBroke) {
  for (const std::string cmd : {"filter", "export", "evaluate", "report", "diagnose", "identify"}) {
    const auto it = std::find_if(kReaders.begin(), kReaders.end(),
                                 [&](const std::string& c) { return c.rfind(cmd, 0) == 0; });
    ASSERT_NE(it, kReaders.end());
    TempDir out;
    const Outcome o = runReader(*it + " --salvage", files().cut, out.path().string());
    SCOPED_TRACE(cmd + ": " + o.err);
    EXPECT_EQ(o.code, 0);
    EXPECT_TRUE(std::regex_search(
        o.err, std::regex("warning: .*cut\\.rawlog: record ([1-9][0-9]*) \\(uncompressed byte "
                          "[0-9]+\\): file cut short.*; salvaged the \\1 complete records")));
    EXPECT_FALSE(fs::is_empty(out.path())) << "no output";
  }
  // The salvaged export holds exactly the records before the break (minus the header).
  TempDir out;
  ASSERT_EQ(runReader("export FILE -o OUT/x --salvage", files().cut, out.path().string()).code, 0);
  const auto info = cli("info " + files().cut);
  std::smatch m;
  ASSERT_TRUE(std::regex_search(info.out, m, std::regex("record ([0-9]+) ")));
  std::size_t rows = 0;
  for (const auto& e : fs::directory_iterator(out.path() / "x"))
    if (e.path().extension() == ".csv") {
      const std::string t = readFile(e.path().string());
      rows += static_cast<std::size_t>(std::count(t.begin(), t.end(), '\n')) - 1;  // header row
    }
  EXPECT_EQ(rows + 1, std::stoul(m[1]));
}

TEST(CliDamaged, SalvageRefusesAFileWithNothingBeforeTheBreak) {
  TempDir out;
  const Outcome o =
      runReader("export FILE -o OUT/x --salvage", files().header, out.path().string());
  EXPECT_EQ(o.code, 1) << o.err;
  EXPECT_NE(o.err.find("no complete data record before it"), std::string::npos) << o.err;
  EXPECT_FALSE(fs::exists(out.path() / "x"));
}
