// The same drive at t = 0 and stamped in UNIX time (every timestamp + 1.7e9 s, what `capture`
// and every logger on a real chair write) gives the same results through the CLI: filter
// (physics and baseline), evaluate, identify, diagnose. Before the estimators worked in time
// relative to their start, the physics filter ended 1.96e23 m away with sd 0 at this offset.
//
// Tolerance (docs/estimation.md, "Clock offset"): not to the bit, because a double holds a
// stamp near 1.7e9 s only to 2.4e-7 s, so every interval differs from the t = 0 drive by up to
// that much (1e-5 of a 20 ms encoder interval); with CVODE at rel_tol 1e-4 the estimates then
// agree within 2e-4 (m, m/s, rad, and their sd), measured 5e-5 at most. Counts agree exactly.
#include "../common/TestUtil.h"
#include "ClockOffsetUtil.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <regex>

using namespace wheelchair;
using test::cli;
using test::kUnixOffset_s;
using test::readCsv;
using test::TempDir;

namespace {

constexpr double kStateTol = 2e-4;  // m, m/s, rad (and the sd of each)

/// The sensor table of `wheelchair filter`: sensor -> "used rejected dropouts skipped".
std::map<std::string, std::string> sensorCounts(const std::string& out) {
  std::map<std::string, std::string> m;
  const std::regex row(R"((encoders|gyro|sonar|pozyx)\s+(\d+)\s+(\d+)\s+(\d+)\s+(\d+)\s)");
  for (std::sregex_iterator it(out.begin(), out.end(), row), end; it != end; ++it)
    m[(*it)[1]] =
        (*it)[2].str() + " " + (*it)[3].str() + " " + (*it)[4].str() + " " + (*it)[5].str();
  return m;
}

double angleDiff(double a, double b) {
  return std::remainder(a - b, 2 * M_PI);
}

}  // namespace

TEST(ClockOffsetCli, FilterPhysicsAndBaselineGiveTheSameEstimatesInUnixTime) {
  TempDir tmp;
  const std::string r0 = test::importShifted(tmp, "three_task_clean", 0.0);
  const std::string r1 = test::importShifted(tmp, "three_task_clean", kUnixOffset_s);
  for (const std::string filter : {"physics", "baseline"}) {
    SCOPED_TRACE(filter);
    const auto a = cli("filter " + r0 + " --no-progress --filter " + filter + " --estimates " +
                       (tmp / "a.csv") + " --trajectory " + (tmp / "a.tum"));
    const auto b = cli("filter " + r1 + " --no-progress --filter " + filter + " --estimates " +
                       (tmp / "b.csv") + " --trajectory " + (tmp / "b.tum"));
    ASSERT_EQ(a.exit_code, 0) << a.out;
    ASSERT_EQ(b.exit_code, 0) << b.out;
    EXPECT_EQ(sensorCounts(a.out), sensorCounts(b.out)) << a.out << "\n" << b.out;
    EXPECT_EQ(sensorCounts(a.out).size(), 4u) << a.out;
    const auto ea = readCsv(tmp / "a.csv"), eb = readCsv(tmp / "b.csv");
    ASSERT_EQ(ea.header, eb.header);
    ASSERT_EQ(ea.rows.size(), eb.rows.size());
    ASSERT_GT(ea.rows.size(), 1000u);
    const int phi = ea.col("phi_rad");
    double worst = 0;
    for (std::size_t i = 0; i < ea.rows.size(); ++i) {
      // Output times carry the offset (printed at 1 us: the same digits after the point).
      ASSERT_NEAR(test::num(eb.rows[i][0]) - test::num(ea.rows[i][0]), kUnixOffset_s, 1e-6)
          << "row " << i;
      for (std::size_t c = 1; c < ea.header.size(); ++c) {
        const double x = test::num(ea.rows[i][c]), y = test::num(eb.rows[i][c]);
        const double d = static_cast<int>(c) == phi ? angleDiff(y, x) : y - x;
        ASSERT_TRUE(std::isfinite(y)) << ea.header[c] << " row " << i;
        worst = std::max(worst, std::fabs(d));
        ASSERT_LE(std::fabs(d), kStateTol)
            << ea.header[c] << " row " << i << ": " << x << " vs " << y;
      }
    }
    RecordProperty(filter + "_max_difference", std::to_string(worst));
    // The TUM trajectory carries the absolute stamps too.
    const std::string tum = test::readFile(tmp / "b.tum");
    EXPECT_NE(tum.find("\n1700000042.997017 "), std::string::npos) << tum.substr(0, 200);
  }
}

TEST(ClockOffsetCli, EvaluateGivesTheSameMetricsInUnixTime) {
  TempDir tmp;
  const std::string r0 = test::importShifted(tmp, "three_task_clean", 0.0);
  const std::string r1 = test::importShifted(tmp, "three_task_clean", kUnixOffset_s);
  const auto a = cli("evaluate " + r0 + " -q -j 1 --csv " + (tmp / "a.csv"));
  const auto b = cli("evaluate " + r1 + " -q -j 1 --csv " + (tmp / "b.csv"));
  ASSERT_EQ(a.exit_code, 0) << a.out;
  ASSERT_EQ(b.exit_code, 0) << b.out;
  const auto ta = readCsv(tmp / "a.csv"), tb = readCsv(tmp / "b.csv");
  ASSERT_EQ(ta.header, tb.header);
  ASSERT_EQ(ta.rows.size(), tb.rows.size());
  ASSERT_GE(ta.rows.size(), 4u);  // ekf, encoders, encoders_gyro, baseline
  for (std::size_t i = 0; i < ta.rows.size(); ++i) {
    for (std::size_t c = 1; c < ta.header.size(); ++c) {  // column 0: the file name
      const std::string& h = ta.header[c];
      const std::string &x = ta.rows[i][c], &y = tb.rows[i][c];
      SCOPED_TRACE(h + " of " + ta.rows[i][1]);
      if (h.rfind("n_", 0) == 0 || h == "variant" || h == "ground_truth" || h == "alignment" ||
          h == "heading_drift_method" || h == "error") {
        EXPECT_EQ(x, y);  // counts and labels: exactly
      } else if (!x.empty()) {
        // Metres and degrees: d_path (20 m), ATE (0.14 m), drift (2.5 deg), alignment.
        EXPECT_NEAR(test::num(x), test::num(y), h.find("deg") != std::string::npos ? 1e-3 : 1e-4);
      }
    }
  }
}

TEST(ClockOffsetCli, IdentifyGivesTheSameParametersInUnixTime) {
  TempDir tmp;
  const std::string r0 = test::importShifted(tmp, "excite", 0.0);
  const std::string r1 = test::importShifted(tmp, "excite", kUnixOffset_s);
  ASSERT_EQ(cli("identify " + r0 + " --json " + (tmp / "a.json")).exit_code, 0);
  ASSERT_EQ(cli("identify " + r1 + " --json " + (tmp / "b.json")).exit_code, 0);
  const auto ja = nlohmann::json::parse(test::readFile(tmp / "a.json"));
  const auto jb = nlohmann::json::parse(test::readFile(tmp / "b.json"));
  EXPECT_EQ(ja["samples"], jb["samples"]);  // same grid, same samples used
  int compared = 0;
  for (const char* group : {"combinations", "ode/direct", "ode/from_theta"}) {
    const auto pa = ja.at(nlohmann::json::json_pointer(std::string("/") + group));
    const auto pb = jb.at(nlohmann::json::json_pointer(std::string("/") + group));
    for (const auto& [k, v] : pa.items()) {
      if (!v.is_object() || !v.contains("value") || !v["value"].is_number()) continue;
      SCOPED_TRACE(std::string(group) + "/" + k);
      const double x = v["value"], y = pb[k]["value"], se = v["se"];
      // Within a hundredth of a standard error (measured: 1e-4 relative, ~1e-3 se).
      EXPECT_NEAR(x, y, 0.01 * se);
      EXPECT_NEAR(se, pb[k]["se"].get<double>(), 1e-3 * se);
      ++compared;
    }
  }
  EXPECT_GE(compared, 6);
}

TEST(ClockOffsetCli, DiagnoseFindsTheSameFaultsInUnixTime) {
  TempDir tmp;
  const std::string r0 = test::importShifted(tmp, "three_task_faulty", 0.0);
  const std::string r1 = test::importShifted(tmp, "three_task_faulty", kUnixOffset_s);
  ASSERT_EQ(cli("diagnose " + r0 + " --json " + (tmp / "a.json")).exit_code, 0);
  ASSERT_EQ(cli("diagnose " + r1 + " --json " + (tmp / "b.json")).exit_code, 0);
  const auto fa = nlohmann::json::parse(test::readFile(tmp / "a.json"))["findings"];
  const auto fb = nlohmann::json::parse(test::readFile(tmp / "b.json"))["findings"];
  ASSERT_EQ(fa.size(), fb.size());
  ASSERT_GE(fa.size(), 2u);  // encoder scale and motor asymmetry at least
  for (std::size_t i = 0; i < fa.size(); ++i) {
    SCOPED_TRACE(fa[i]["effect"].dump());
    EXPECT_EQ(fa[i]["effect"], fb[i]["effect"]);
    EXPECT_EQ(fa[i]["channels"], fb[i]["channels"]);
    for (const auto& [k, v] : fa[i]["parameters"].items()) {
      if (!v.is_number()) {
        EXPECT_EQ(v, fb[i]["parameters"][k]);
        continue;
      }
      // Within a tenth of the finding's own uncertainty (measured: 3 % of it).
      const double u = fa[i]["uncertainty"].value(k, 1e-3);
      EXPECT_NEAR(v.get<double>(), fb[i]["parameters"][k].get<double>(), 0.1 * u) << k;
    }
    // Segments are reported in the recording's own (absolute) time.
    ASSERT_EQ(fa[i]["segments"].size(), fb[i]["segments"].size());
    for (std::size_t s = 0; s < fa[i]["segments"].size(); ++s)
      for (int e = 0; e < 2; ++e)
        EXPECT_NEAR(fb[i]["segments"][s][e].get<double>() - fa[i]["segments"][s][e].get<double>(),
                    kUnixOffset_s, 1e-6);
  }
}

TEST(ClockOffsetCli, FilterNamesTheSampleAndTimeOfAFailure) {
  // A clock that steps forward by 1e6 s in the middle of a drive (NTP, a dead RTC battery),
  // imported with the gap check off: CVODE cannot integrate 1e6 s of physics within its step
  // budget, and the error names the file, the sample and the time, in one line.
  TempDir tmp;
  const std::string dir = tmp / "jump";
  const double jump_at = kUnixOffset_s + 20.0;
  test::shiftRecording(test::sourcePath("datasets/three_task_clean"), dir, kUnixOffset_s,
                       [&](double t) { return t >= jump_at ? t + 1e6 : t; });
  auto r = cli("import " + dir + " -o " + (tmp / "jump.rawlog"));
  ASSERT_EQ(r.exit_code, 1) << r.out;  // refused by default: the jump exceeds max_gap_s
  EXPECT_NE(r.out.find("jumps 1000000."), std::string::npos) << r.out;
  r = cli("import " + dir + " -o " + (tmp / "jump.rawlog") + " --max-gap 0");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  r = cli("filter " + (tmp / "jump.rawlog") + " --no-progress");
  EXPECT_EQ(r.exit_code, 1) << r.out;
  // The first sample after the jump is IMU row 2002 of imu.csv (sample 2000, 0-based).
  const std::regex line(
      R"(wheelchair filter: error: .*jump\.rawlog: IMU sample 2000 \(t = 1701000020\.007752 s\): )"
      R"(CVODE failed \(CV_TOO_MUCH_WORK\) integrating from t = 1700000019\.\d+ s to )"
      R"(1701000020\.007752 s \(reached 17000\d+\.\d+ s\)\n)");
  EXPECT_TRUE(std::regex_search(r.out, line)) << r.out;
  EXPECT_EQ(r.out.find("[CVODE ERROR]"), std::string::npos) << "one line, not CVODE's print:\n"
                                                            << r.out;
  EXPECT_EQ(r.out.find("final pose"), std::string::npos) << r.out;
}
