#include "libwheelchair/stats/Selection.h"

#include <algorithm>
#include <cstdio>

namespace wheelchair::stats {

double SelectionRule::level() const {
  return alpha / std::max(1, family_size);
}

std::string SelectionRule::reject(const Evidence& ev) const {
  if (!(ev.p_value < level())) return "not significant (p = " + std::to_string(ev.p_value) + ")";
  if (!(ev.delta_bic < -min_bic_drop)) return "BIC drop too small";
  return {};
}

namespace {

/// One forward step: the passing candidate with the lowest delta BIC, or -1.
int bestCandidate(int n, const SelectionRule& rule, const SelectionHooks& h,
                  const std::vector<int>& accepted, std::vector<std::pair<int, std::string>>& log) {
  int best = -1;
  double best_bic = 0;
  for (int c = 0; c < n; ++c) {
    if (std::find(accepted.begin(), accepted.end(), c) != accepted.end()) continue;
    const Trial t = h.evaluate(c, accepted);
    if (t.skip) continue;
    std::string why = t.reject.empty() ? rule.reject(t.evidence) : t.reject;
    if (why.empty() && h.confirm) why = h.confirm(c);
    if (!why.empty()) {
      log.emplace_back(c, why);
      continue;
    }
    if (best < 0 || t.evidence.delta_bic < best_bic) best = c, best_bic = t.evidence.delta_bic;
  }
  return best;
}

/// Position of the accepted term to remove (the failing one with the smallest LR), or -1.
int worstAccepted(const SelectionRule& rule, const SelectionHooks& h,
                  const std::vector<int>& accepted) {
  int worst = -1;
  double worst_lr = 1e300;
  for (std::size_t a = 0; a < accepted.size(); ++a) {
    const Trial t = h.removal(static_cast<int>(a), accepted);
    if (t.skip) continue;
    const bool fails = !t.reject.empty() || !rule.reject(t.evidence).empty();
    if (fails && t.evidence.lr < worst_lr) worst_lr = t.evidence.lr, worst = static_cast<int>(a);
  }
  return worst;
}

}  // namespace

std::vector<int> selectTerms(int n, const SelectionRule& rule, const SelectionHooks& h,
                             std::vector<int> accepted,
                             std::vector<std::pair<int, std::string>>* log) {
  std::vector<std::pair<int, std::string>> round_log;
  while (true) {
    round_log.clear();
    if (h.step) h.step(accepted);
    const int best = bestCandidate(n, rule, h, accepted, round_log);
    if (best < 0) break;
    accepted.push_back(best);
    if (h.accepted) h.accepted(best);
  }
  while (h.removal) {
    const int worst = worstAccepted(rule, h, accepted);
    if (worst < 0) break;
    round_log.emplace_back(accepted[worst], "removed, redundant given the other terms");
    accepted.erase(accepted.begin() + worst);
    if (h.removed) h.removed(worst);
  }
  if (log) *log = std::move(round_log);
  return accepted;
}

}  // namespace wheelchair::stats
