// The held-out rule (libwheelchair/diagnosis/HeldOut.h, issue 16):
//  - the moving-block bootstrap says a clear positive gain is positive and a zero-mean
//    autocorrelated series is not (no asymptotic n_eff test);
//  - enforceHeldOutRule removes exactly the findings whose own held-out prediction gets worse
//    and lists them in info.rejected_heldout with the numbers;
//  - blocked cross-validation keeps a constant term and drops one whose coefficient is within
//    its block-to-block scatter (borrowed structure), one without effect, and short data.
#include "libwheelchair/diagnosis/HeldOut.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace wheelchair::diagnosis {
namespace {

std::vector<double> ar1(double mean, double phi, int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> N(0, 1);
  std::vector<double> x(n);
  double e = 0;
  for (int i = 0; i < n; ++i) {
    e = phi * e + N(rng);
    x[i] = mean + e;
  }
  return x;
}

TEST(HeldOutRule, BlockBootstrapSeesGainAndNoGain) {
  EXPECT_LT(blockBootstrapProbNotPositive(ar1(1.0, 0.5, 400, 1), 20), 0.01);
  // Strongly autocorrelated zero-mean series: not a gain (an iid test would often say so).
  int positive_calls = 0;
  for (unsigned s = 0; s < 20; ++s)
    positive_calls += blockBootstrapProbNotPositive(ar1(0.0, 0.95, 400, 100 + s), 40) < 0.05;
  EXPECT_LE(positive_calls, 3);
  EXPECT_EQ(blockBootstrapProbNotPositive({}, 5), 1.0);
}

TEST(HeldOutRule, RemovesOnlyFindingsThatPredictWorse) {
  DiagnosisReport rep;
  Finding good, worse_rms, worse_drift;
  good.effect = "gyro_bias";
  good.fit_before = {{"validation_rms_rad", 0.02}};
  good.fit_after = {{"validation_rms_rad", 0.01}};
  worse_rms.effect = "payload_mass";
  worse_rms.fit_before = {{"validation_rms_A", 0.10}};
  worse_rms.fit_after = {{"validation_rms_A", 0.11}};
  worse_drift.effect = "unmodeled";
  worse_drift.command_response = true;
  worse_drift.fit_before = {{"drift_10s_m", 0.039}, {"validation_rms_m_s", 0.013}};
  worse_drift.fit_after = {{"drift_10s_m", 0.047}, {"validation_rms_m_s", 0.012}};
  for (auto& f : {good, worse_rms, worse_drift}) rep.addFinding(f);
  EXPECT_EQ(enforceHeldOutRule(rep), 2);
  ASSERT_EQ(rep.findings.size(), 1u);
  EXPECT_EQ(rep.findings[0].effect, "gyro_bias");
  EXPECT_TRUE(rep.mismatch);
  const auto& rej = rep.info["rejected_heldout"];
  ASSERT_EQ(rej.size(), 2u);
  EXPECT_EQ(rej[0]["effect"], "payload_mass");
  EXPECT_EQ(rej[0]["worse"][0], "validation_rms_A");
  EXPECT_EQ(rej[1]["worse"][0], "drift_10s_m");
  EXPECT_DOUBLE_EQ(rej[1]["fit_after"]["drift_10s_m"].get<double>(), 0.047);
  // A term the held-out data cannot test (its stage says so) is not judged on the residual.
  DiagnosisReport untestable;
  Finding scale = worse_rms;
  scale.effect = "gyro_scale";
  scale.evidence = {{"validation_tested", false}};
  untestable.addFinding(scale);
  EXPECT_EQ(enforceHeldOutRule(untestable), 0);
  EXPECT_EQ(untestable.findings.size(), 1u);
  EXPECT_TRUE(untestable.findings[0].evidence.contains("heldout"));
  // Nothing left: no mismatch claimed by the removed findings alone.
  DiagnosisReport only_bad;
  only_bad.addFinding(worse_rms);
  enforceHeldOutRule(only_bad);
  EXPECT_TRUE(only_bad.findings.empty());
  EXPECT_FALSE(only_bad.mismatch);
}

}  // namespace
}  // namespace wheelchair::diagnosis

namespace wheelchair::diagnosis {
namespace {

// Blocked cross-validation of one regressor (blockedCvTerm): a real, constant term is kept; a
// regressor that only borrows structure whose sign changes from one stretch of the drive to
// the next (misspecification) is not, although its in-sample fit on all rows is strong; a
// regressor without effect is not; too few rows: not testable, not kept.
TEST(HeldOutRule, BlockedCvKeepsConstantTermsOnly) {
  const int n = 4000, K = 10;
  std::mt19937 rng(3);
  std::normal_distribution<double> N(0, 1);
  Eigen::MatrixXd A(n, 3);
  Eigen::VectorXd y(n);
  for (int i = 0; i < n; ++i) {
    A(i, 0) = N(rng), A(i, 1) = N(rng), A(i, 2) = N(rng);
    const int block = i * K / n;
    const double borrowed = block < 6 ? 1.0 : -1.0;  // same regressor, sign by stretch
    y(i) = 0.8 * A(i, 0) + borrowed * A(i, 1) + 0.1 * N(rng);
  }
  const BlockedCvTerm real = blockedCvTerm(A, y, 0, K, 20);
  EXPECT_TRUE(real.kept(0.01));
  EXPECT_NEAR(real.coef, 0.8, 0.05);
  EXPECT_GT(real.mean_gain, 0.3);
  const BlockedCvTerm borrowed = blockedCvTerm(A, y, 1, K, 20);
  EXPECT_NEAR(borrowed.coef, 0.2, 0.05);                         // in-sample: clearly non-zero ...
  EXPECT_GT(borrowed.coef_se, std::abs(borrowed.coef) / 2.576);  // ... within block scatter
  EXPECT_FALSE(borrowed.kept(0.01));
  const BlockedCvTerm none = blockedCvTerm(A, y, 2, K, 20);
  EXPECT_FALSE(none.kept(0.01));
  EXPECT_GT(none.p_not_positive, 0.01);
  const BlockedCvTerm short_data = blockedCvTerm(A.topRows(100), y.head(100), 0, K, 20);
  EXPECT_FALSE(short_data.testable);
  EXPECT_FALSE(short_data.kept(0.01));
}

}  // namespace
}  // namespace wheelchair::diagnosis
