// The selection engine and its one multiple-testing rule, on scripted evidence (so each
// decision is known) and on a real linear fit.
#include "libwheelchair/stats/Selection.h"

#include <gtest/gtest.h>

#include <map>
#include <random>

using namespace wheelchair::stats;

namespace {

Evidence ev(double lr, int k, double n_eff) {
  return compareNested(std::exp(lr / n_eff), 1.0, k, n_eff);  // LR = n_eff log(rss0/rss1)
}

}  // namespace

TEST(Selection, RuleIsBonferroniOverTheCatalogue) {
  const SelectionRule rule{0.01, 8, 10};
  EXPECT_DOUBLE_EQ(rule.level(), 0.01 / 8);
  EXPECT_TRUE(rule.reject(ev(40, 1, 1000)).empty());
  EXPECT_EQ(rule.reject(ev(8, 1, 1000)).rfind("not significant (p = ", 0), 0u);
  // Significant at alpha / m but the BIC drop (-LR + k log n_eff) is not strong.
  Evidence e = ev(20, 3, 1e5);
  ASSERT_LT(e.p_value, rule.level());
  EXPECT_EQ(rule.reject(e), "BIC drop too small");
}

// Three candidates. 0 is strong, 2 is accepted second with a p-value between alpha / m and
// alpha / (tests run so far): the level is the same at every step. 1 has the best BIC in
// step 2 but fails its own check: the best PASSING candidate is taken.
TEST(Selection, ForwardStepsUseOneLevelAndTakeTheBestPassingCandidate) {
  const int m = 3;
  const SelectionRule rule{0.01, m, 0};  // BIC: any drop
  const double n_eff = 1000;
  // chi2(1) upper tail 0.002: between alpha/5 (two steps, 3 + 2 tests) and alpha/3.
  const double lr2 = chi2Quantile(1 - 0.002, 1);
  ASSERT_GT(chi2Sf(lr2, 1), 0.01 / 5);
  ASSERT_LT(chi2Sf(lr2, 1), rule.level());
  SelectionHooks h;
  int steps = 0;
  h.step = [&](const std::vector<int>&) { ++steps; };
  h.evaluate = [&](int c, const std::vector<int>& acc) {
    Trial t;
    if (c == 0) t.evidence = ev(500, 1, n_eff);
    if (c == 1) t.evidence = ev(acc.empty() ? 100 : 60, 1, n_eff);
    if (c == 2) t.evidence = ev(acc.empty() ? 30 : lr2, 1, n_eff);
    return t;
  };
  h.confirm = [](int c) { return c == 1 ? std::string("physically implausible") : std::string(); };
  std::vector<int> order;
  h.accepted = [&](int c) { order.push_back(c); };
  std::vector<std::pair<int, std::string>> log;
  const auto acc = selectTerms(m, rule, h, {}, &log);
  EXPECT_EQ(acc, (std::vector<int>{0, 2}));
  EXPECT_EQ(order, acc);
  EXPECT_EQ(steps, 3);
  ASSERT_EQ(log.size(), 1u);
  EXPECT_EQ(log[0], std::make_pair(1, std::string("physically implausible")));
}

TEST(Selection, BackwardEliminationRemovesTheWeakestFailingTermButNotForcedOnes) {
  const SelectionRule rule{0.01, 4, 10};
  SelectionHooks h;
  h.evaluate = [](int c, const std::vector<int>&) {
    Trial t;
    t.evidence = ev(c == 3 ? 1 : 200 - 10 * c, 1, 1000);
    return t;
  };
  // Given all others: term 1 adds nothing (LR 2), term 2 is weak too (LR 5), 0 is forced.
  h.removal = [](int pos, const std::vector<int>& acc) {
    Trial t;
    t.skip = pos == 0;
    const std::map<int, double> lr{{0, 0.0}, {1, 2.0}, {2, acc.size() == 3 ? 5.0 : 100.0}};
    t.evidence = ev(lr.at(acc[pos]), 1, 1000);
    return t;
  };
  std::vector<int> removed;
  std::vector<int> mirror{0};
  h.accepted = [&](int c) { mirror.push_back(c); };
  h.removed = [&](int pos) { mirror.erase(mirror.begin() + pos); };
  std::vector<std::pair<int, std::string>> log;
  const auto acc = selectTerms(4, rule, h, {0}, &log);
  EXPECT_EQ(acc, (std::vector<int>{0, 2}));  // 1 removed (smallest LR); then 2 is needed
  EXPECT_EQ(mirror, acc);
  ASSERT_FALSE(log.empty());
  EXPECT_EQ(log.back(), std::make_pair(1, std::string("removed, redundant given the other terms")));
}

// Real fits: y = 2 x0 - x3 + AR(1) noise, candidates x0..x5 -> exactly {0, 3}.
TEST(Selection, LinearForwardSelectionFindsTheTrueTerms) {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> N(0, 1);
  const int n = 3000, m = 6;
  Eigen::MatrixXd X(n, m);
  Eigen::VectorXd y(n);
  double e = 0;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < m; ++j) X(i, j) = N(rng);
    e = 0.7 * e + 0.5 * N(rng);
    y(i) = 2 * X(i, 0) - X(i, 3) + e;
  }
  const Groups g = singleGroup(n);
  const int lags = 10;
  auto design = [&](std::vector<int> cols) {
    Eigen::MatrixXd D(n, cols.size());
    for (std::size_t q = 0; q < cols.size(); ++q) D.col(q) = X.col(cols[q]);
    return D;
  };
  LinearFit f0;
  SelectionHooks h;
  h.step = [&](const std::vector<int>& acc) { f0 = fitLinear(design(acc), y, g, lags); };
  h.evaluate = [&](int c, std::vector<int> acc) {
    acc.push_back(c);
    const LinearFit f1 = fitLinear(design(acc), y, g, lags);
    Trial t;
    t.evidence = compareNested(f0.rss, f1.rss, 1, effectiveSampleSize(f1.residual, g, lags));
    return t;
  };
  auto acc = selectTerms(m, SelectionRule{0.01, m, 10}, h);
  std::sort(acc.begin(), acc.end());
  EXPECT_EQ(acc, (std::vector<int>{0, 3}));
}
