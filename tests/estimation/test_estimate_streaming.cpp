// Estimates streamed to a sink (runEstimator(..., sink)) instead of stored, the streaming
// estimates CSV writer, and `wheelchair filter` writing its outputs that way (issue 13:
// memory flat in the drive's length, no SIGABRT on a failed write).
#include "StreamingUtil.h"
#include "SyntheticDrive.h"

#include "../common/TestUtil.h"
#include "libwheelchair/estimation/EstimateWriters.h"
#include "libwheelchair/estimation/Estimator.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <sstream>
#include <stdexcept>
#include <vector>

using namespace wheelchair;
using namespace wheelchair::estimation;
using namespace wheelchair::estimation::test;

namespace {

SynthRun drive() {
  SynthOptions so = curvyDrive(15.0);
  so.pozyx = true;
  return synthesize(nominal(), so, 11);
}

std::vector<std::string> linesOf(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream ss(text);
  for (std::string l; std::getline(ss, l);) out.push_back(l);
  return out;
}

std::size_t filesIn(const std::filesystem::path& dir) {
  std::size_t n = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir)) ++n;
  return n;
}

}  // namespace

TEST(EstimateStreaming, SinkReceivesBitIdenticalEstimatesAndTheResultKeepsNone) {
  const SynthRun sr = drive();
  for (const EkfOptions& opt : estimation::test::streamingOptionSets()) {
    const EstimationResult stored = runEstimator(sr.rec, nominal(), opt);
    Collect sink;
    const EstimationResult streamed = runEstimator(sr.rec, nominal(), opt, sink);
    ASSERT_GT(stored.estimates.size(), 100u);
    EXPECT_EQ(stored.n_estimates, stored.estimates.size());
    EXPECT_TRUE(streamed.estimates.empty());
    EXPECT_TRUE(streamed.nis.empty());
    EXPECT_FALSE(stored.nis.empty());
    ASSERT_EQ(sink.v.size(), stored.estimates.size());
    EXPECT_EQ(streamed.n_estimates, stored.estimates.size());
    for (std::size_t k = 0; k < sink.v.size(); ++k) {
      const auto &a = stored.estimates[k], &b = sink.v[k];
      ASSERT_EQ(a.t_s, b.t_s) << k;
      ASSERT_EQ(a.x, b.x) << k;
      ASSERT_EQ(a.sd, b.sd) << k;
      ASSERT_EQ(a.P, b.P) << k;
      ASSERT_EQ(a.obstacle_distance_m, b.obstacle_distance_m) << k;
    }
    EXPECT_EQ(streamed.final().t_s, stored.final().t_s);
    EXPECT_EQ(streamed.final().x, stored.final().x);
    for (int s = 0; s < kNumSensors; ++s) {
      EXPECT_EQ(streamed.sensors[s].used, stored.sensors[s].used);
      EXPECT_EQ(streamed.sensors[s].rejected, stored.sensors[s].rejected);
      EXPECT_EQ(streamed.sensors[s].nis_sum, stored.sensors[s].nis_sum);
    }
    EXPECT_EQ(streamed.rejected.size(), stored.rejected.size());
  }
}

TEST(EstimateStreaming, CsvWriterWritesOneRowPerEstimateThatReadsBackExactly) {
  const SynthRun sr = drive();
  wheelchair::test::TempDir dir;
  EkfOptions opt;
  EstimatesCsvWriter csv(dir / "est.csv");
  const EstimationResult res = runEstimator(sr.rec, nominal(), opt, csv);
  EXPECT_FALSE(std::filesystem::exists(dir / "est.csv"));  // nothing visible before commit
  csv.commit();
  const auto lines = linesOf(wheelchair::test::readFile(dir / "est.csv"));
  ASSERT_EQ(lines.size(), res.n_estimates + 1);
  EXPECT_EQ(lines[0].rfind("t_s,v_m_s,omega_rad_s,x_m,y_m,phi_rad,", 0), 0u);
  // Last row: 10 significant digits give the filter's doubles back to 5e-10 relative.
  std::vector<double> v;
  std::stringstream ss(lines.back());
  for (std::string f; std::getline(ss, f, ',');) v.push_back(std::stod(f));
  ASSERT_EQ(v.size(), 17u);
  const auto& f = res.final();
  EXPECT_NEAR(v[0], f.t_s, 5e-7);
  for (int i = 0; i < 7; ++i) {
    EXPECT_NEAR(v[1 + i], f.x(i), 5e-10 * std::fabs(f.x(i))) << i;
    EXPECT_NEAR(v[9 + i], f.sd(i), 5e-10 * f.sd(i)) << i;
  }
  EXPECT_EQ(filesIn(dir.path()), 1u);  // no temporary left
}

// Every row and column of a filter's CSV reads back to the filter's doubles (t to its 6
// decimals, the rest to 10 significant digits: the double nearest the exactly rounded decimal,
// within 5e-10 relative), also rows of extreme values (signed zero, subnormals, 1e300,
// exponent forms).
TEST(EstimateStreaming, EveryCsvRowReadsBackToTheSameDoubles) {
  const SynthRun sr = drive();
  wheelchair::test::TempDir dir;
  Collect keep;
  EstimatesCsvWriter csv(dir / "est.csv");
  EstimateFanOut both({&keep, &csv});
  runEstimator(sr.rec, nominal(), EkfOptions{}, both);
  // Extreme values after the filter's rows (the writer does not require increasing time).
  for (double v : {0.0, -0.0, 5e-324, -2.2250738585072014e-308, 1e-5, 9.999999999999999e15, 1e16,
                   -1.7976931348623157e308, 0.1, 1.0 / 3.0}) {
    EstimateSample e;
    e.t_s = 1e9 + 1.0 / 128;  // 1000000000.0078125: halfway at the 7th decimal
    e.x.setConstant(v);
    e.sd.setConstant(-v / 3);
    e.obstacle_distance_m = v * 7;
    e.obstacle_distance_sd_m = std::nextafter(v, 1.0);
    keep.add(e);
    csv.add(e);
  }
  csv.commit();
  const auto lines = linesOf(wheelchair::test::readFile(dir / "est.csv"));
  ASSERT_EQ(lines.size(), keep.v.size() + 1);
  ASSERT_GT(keep.v.size(), 1000u);
  for (std::size_t k = 0; k < keep.v.size(); ++k) {
    const EstimateSample& e = keep.v[k];
    const std::string& line = lines[k + 1];
    std::vector<double> v;
    const char* p = line.c_str();
    for (char* end = nullptr;; p = end + 1) {
      v.push_back(std::strtod(p, &end));
      ASSERT_NE(end, p) << "row " << k + 1 << ": " << line;
      if (*end != ',') {
        ASSERT_EQ(*end, '\0') << line;
        break;
      }
    }
    ASSERT_EQ(v.size(), 17u) << line;
    ASSERT_NEAR(v[0], e.t_s, 5e-7) << line;
    const double expected[16] = {
        e.x(0),  e.x(1),  e.x(2),  e.x(3),  e.x(4),  e.x(5),  e.x(6),  e.obstacle_distance_m,
        e.sd(0), e.sd(1), e.sd(2), e.sd(3), e.sd(4), e.sd(5), e.sd(6), e.obstacle_distance_sd_m};
    for (int i = 0; i < 16; ++i) {
      char digits[40];  // printf's exactly rounded 10 significant digits
      std::snprintf(digits, sizeof digits, "%.9e", expected[i]);
      const double want = std::fabs(expected[i]) < 0x1p1023 ? std::strtod(digits, nullptr)
                                                            : expected[i];  // shortest form
      ASSERT_EQ(std::memcmp(&v[1 + i], &want, sizeof(double)), 0)
          << "row " << k + 1 << " column " << i + 2 << ": " << line;
      if (std::isfinite(expected[i])) {
        ASSERT_LE(std::fabs(v[1 + i] - expected[i]), 5e-10 * std::fabs(expected[i]))
            << "row " << k + 1 << " column " << i + 2 << ": " << line;
      }
    }
  }
  // t keeps 6 decimals; the exact halfway case rounds as fmt's "{:.6f}" does.
  EXPECT_EQ(lines.back().substr(0, lines.back().find(',')), fmt::format("{:.6f}", 1e9 + 1.0 / 128));
}

TEST(EstimateStreaming, AFailingSinkStopsTheRunAndAnUncommittedWriterLeavesNothing) {
  const SynthRun sr = drive();
  wheelchair::test::TempDir dir;
  struct Failing : EstimateSink {
    EstimatesCsvWriter csv;
    std::size_t n = 0;
    explicit Failing(const std::string& p) : csv(p) {}
    void add(const EstimateSample& s) override {
      csv.add(s);
      if (++n == 50) throw std::runtime_error("disk full (simulated)");
    }
  };
  EXPECT_THROW(
      {
        Failing sink(dir / "est.csv");
        runEstimator(sr.rec, nominal(), EkfOptions{}, sink);
      },
      std::runtime_error);
  EXPECT_EQ(filesIn(dir.path()), 0u);  // neither the target nor a temporary
}

// The CLI: outputs streamed, and a write that fails part-way (file size limit: EFBIG) is one
// error line with exit 1 -- not SIGABRT from a throwing stream destructor -- and leaves no
// file and no temporary behind.
TEST(FilterCli, AFailedWriteIsOneErrorLineAndLeavesNoFileBehind) {
  wheelchair::test::TempDir dir;
  const std::string rec = dir / "drive.rawlog";
  auto r = wheelchair::test::cli("simulate --scenario three_task --duration 20 -o " + rec +
                                 " --truth " + (dir / "truth.json"));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const std::string out = dir / "out";
  std::filesystem::create_directories(out);
  r = wheelchair::test::cli("filter " + rec + " --no-progress --estimates " + out + "/e.csv" +
                            " --trajectory " + out + "/t.tum");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto rows = linesOf(wheelchair::test::readFile(out + "/e.csv")).size();
  const auto poses = linesOf(wheelchair::test::readFile(out + "/t.tum")).size();
  EXPECT_GT(rows, 1000u);
  EXPECT_EQ(poses, rows);  // one header line each, one line per estimate
  std::filesystem::remove_all(out);
  std::filesystem::create_directories(out);

  // 64 kB file size limit, SIGXFSZ ignored: writes past it fail with EFBIG.
  r = wheelchair::test::run("sh -c \"trap '' XFSZ; ulimit -f 128; " + std::string(WHEELCHAIR_CLI) +
                            " filter " + rec + " --no-progress --estimates " + out + "/e.csv\"");
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("e.csv"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("File too large"), std::string::npos) << r.out;
  EXPECT_EQ(filesIn(out), 0u) << r.out;
}
