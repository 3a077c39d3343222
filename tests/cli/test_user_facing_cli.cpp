// What the user sees through the `wheelchair` CLI (issue 13, "Trustworthy on real recordings"):
// one verdict per sensor from `filter`, the metrics table and "n/a" variants of `evaluate`,
// "insufficient data" from `diagnose` on short data, units on every printed number, plain
// column names in `info`, and a working example at the end of every command's --help.
// Runs on the bundled recordings (datasets/), imported once per suite.
#include "../common/TestUtil.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

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
