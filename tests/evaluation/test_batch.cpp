// Batch evaluation (libwheelchair/evaluation/Batch.h, `wheelchair evaluate`): parallel runs equal
// serial ones byte for byte, a corrupt or missing recording is reported in its row without
// stopping the batch, outputs record the configuration.
#include "../common/TestUtil.h"

#include "libwheelchair/evaluation/Batch.h"

#include <fmt/core.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <memory>
#include <sstream>

namespace wheelchair::evaluation {
namespace {

using test::cli;
using test::readFile;

// Two short simulated drives (generated once for the suite) plus a corrupt and a missing file.
class BatchTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::make_unique<test::TempDir>();
    for (int seed : {1, 2}) {
      const std::string f = *dir_ / ("drive" + std::to_string(seed) + ".rawlog");
      const auto r =
          cli(fmt::format("simulate --scenario three_task --seed {} --duration 8 -o {}", seed, f));
      ASSERT_EQ(r.exit_code, 0) << r.out;
      files_.push_back(f);
    }
    // A corrupt recording: the first one's bytes, truncated and scrambled.
    std::string bytes = readFile(files_[0]);
    bytes = bytes.substr(0, bytes.size() / 3);
    for (std::size_t i = 40; i < bytes.size(); i += 7)
      bytes[i] = static_cast<char>(bytes[i] ^ 0x5a);
    corrupt_ = *dir_ / "corrupt.rawlog";
    test::writeFile(corrupt_, bytes);
    missing_ = *dir_ / "missing.rawlog";
  }
  static void TearDownTestSuite() { dir_.reset(); }

  static std::unique_ptr<test::TempDir> dir_;
  static std::vector<std::string> files_;
  static std::string corrupt_, missing_;
};
std::unique_ptr<test::TempDir> BatchTest::dir_;
std::vector<std::string> BatchTest::files_;
std::string BatchTest::corrupt_, BatchTest::missing_;

TEST(BatchAlignment, ParsesTheCliForms) {
  MetricOptions o;
  parseAlignment("none", o);
  EXPECT_EQ(o.alignment, Alignment::None);
  parseAlignment("origin", o);
  EXPECT_EQ(o.alignment, Alignment::Origin);
  parseAlignment("se2-first:7.5", o);
  EXPECT_EQ(o.alignment, Alignment::SE2FirstSeconds);
  EXPECT_DOUBLE_EQ(o.align_first_s, 7.5);
  EXPECT_EQ(alignmentText(o.alignment, o.align_first_s), "se2-first:7.5");
  EXPECT_THROW(parseAlignment("se2-first:", o), std::invalid_argument);
  EXPECT_THROW(parseAlignment("se2-first:-1", o), std::invalid_argument);
  EXPECT_THROW(parseAlignment("sim3", o), std::invalid_argument);
}

TEST_F(BatchTest, ParallelEqualsSerialByteForByte) {
  const std::string in = files_[0] + " " + files_[1] + " " + files_[0];
  const auto a = cli("evaluate " + in + " -j 1 -q --csv " + (*dir_ / "j1.csv"));
  const auto b = cli("evaluate " + in + " -j 2 -q --csv " + (*dir_ / "j2.csv"));
  ASSERT_EQ(a.exit_code, 0) << a.out;
  ASSERT_EQ(b.exit_code, 0) << b.out;
  const std::string j1 = readFile(*dir_ / "j1.csv"), j2 = readFile(*dir_ / "j2.csv");
  EXPECT_FALSE(j1.empty());
  EXPECT_EQ(j1, j2);
  // Header + 3 recordings x 4 variants, in input order then variant order.
  std::istringstream ss(j1);
  std::string line;
  std::vector<std::string> lines;
  while (std::getline(ss, line)) lines.push_back(line);
  ASSERT_EQ(lines.size(), 13u);
  EXPECT_EQ(lines[0].rfind(
                "recording,variant,ground_truth,d_path_m,d_path_gt_m,terminal_error_m,loop_error_m,"
                "ate_rmse_m,ate_mean_m,ate_median_m,ate_max_m,",
                0),
            0u)
      << lines[0];
  for (const auto& col : {"rpe_1m_m", "heading_drift_deg", "n_matched", "error"})
    EXPECT_NE(lines[0].find(col), std::string::npos) << col;
  const std::vector<std::string> variants{"ekf", "encoders", "encoders_gyro", "baseline"};
  for (std::size_t i = 1; i < lines.size(); ++i) {
    const std::string& f = files_[((i - 1) / 4) == 1 ? 1 : 0];
    EXPECT_EQ(lines[i].rfind(f + "," + variants[(i - 1) % 4] + ",pozyx,", 0), 0u) << lines[i];
  }
  // The sidecar records the configuration.
  const std::string ini = readFile(*dir_ / "j1.csv.config.ini");
  EXPECT_NE(ini.find("[vehicle]"), std::string::npos);
  EXPECT_NE(ini.find("wheel_radius_m"), std::string::npos);
}

TEST_F(BatchTest, LibraryRunIsIdenticalForAnyJobCount) {
  const config::WheelchairConfig cfg;
  BatchOptions o;
  o.baseline = false;
  o.jobs = 1;
  const auto serial = runBatch({files_[1], files_[0]}, cfg, o);
  o.jobs = 2;
  const auto parallel = runBatch({files_[1], files_[0]}, cfg, o);
  EXPECT_EQ(batchCsv(serial), batchCsv(parallel));
  ASSERT_EQ(serial.rows.size(), 6u);
  EXPECT_EQ(serial.rows[0].recording, files_[1]);
  EXPECT_EQ(serial.rows[0].variant, "ekf");
  EXPECT_FALSE(serial.anyFailed());
  for (const auto& r : serial.rows) {
    EXPECT_TRUE(r.error.empty()) << r.error;
    EXPECT_GT(r.metrics.n_matched, 10u);
    EXPECT_TRUE(std::isfinite(r.metrics.ate_rmse_m));
    EXPECT_GT(r.metrics.d_path_m, 0.5);
  }
}

TEST_F(BatchTest, AFailingRecordingIsReportedInItsRowAndDoesNotStopTheBatch) {
  const std::string in = files_[0] + " " + corrupt_ + " " + missing_ + " " + files_[1];
  const std::string csv = *dir_ / "fail.csv", json = *dir_ / "fail.json", md = *dir_ / "fail.md";
  const auto r = cli("evaluate " + in + " -j 2 -q --no-baseline --csv " + csv + " --json " + json +
                     " --markdown " + md + " --alignment se2-first:5");
  EXPECT_EQ(r.exit_code, 1) << r.out;
  const auto j = nlohmann::json::parse(readFile(json));
  EXPECT_EQ(j.at("failed_recordings").get<int>(), 2);
  EXPECT_EQ(j.at("recordings").get<int>(), 4);
  EXPECT_EQ(j.at("alignment").get<std::string>(), "se2-first:5");
  EXPECT_NE(j.at("config").get<std::string>().find("[sonar]"), std::string::npos);
  const auto& rows = j.at("rows");
  ASSERT_EQ(rows.size(), 3u + 1u + 1u + 3u);
  // Good recordings first and last, each with its three variants and no error.
  for (int i : {0, 1, 2, 5, 6, 7}) {
    EXPECT_EQ(rows[i].at("error").get<std::string>(), "") << rows[i].dump();
    EXPECT_TRUE(rows[i].at("ate_rmse_m").is_number());
  }
  EXPECT_EQ(rows[3].at("recording").get<std::string>(), corrupt_);
  EXPECT_EQ(rows[3].at("variant").get<std::string>(), "");
  EXPECT_FALSE(rows[3].at("error").get<std::string>().empty());
  EXPECT_TRUE(rows[3].at("ate_rmse_m").is_null());
  EXPECT_EQ(rows[4].at("recording").get<std::string>(), missing_);
  EXPECT_FALSE(rows[4].at("error").get<std::string>().empty());
  // CSV and Markdown carry the same rows.
  const std::string c = readFile(csv);
  EXPECT_NE(c.find(corrupt_ + ",,none,nan"), std::string::npos) << c;
  EXPECT_NE(c.find(missing_ + ",,none,nan"), std::string::npos);
  const std::string m = readFile(md);
  EXPECT_NE(m.find("| " + missing_ + " | –"), std::string::npos) << m;
  EXPECT_NE(m.find("```ini"), std::string::npos);
}

TEST_F(BatchTest, UsageErrors) {
  EXPECT_EQ(cli("evaluate " + files_[0] + " --alignment bogus").exit_code, 2);
  EXPECT_EQ(cli("evaluate").exit_code, 2);
}

}  // namespace
}  // namespace wheelchair::evaluation
