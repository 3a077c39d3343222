// Forward selection with backward elimination over a catalogue of candidate terms, with ONE
// multiple-testing rule (docs/diagnosis-design.md, "Model selection").
//
// Rule: a term is accepted only if its likelihood-ratio test is significant at alpha / m
// (Bonferroni over the m terms of the catalogue: under the null "no term is present" every
// false acceptance happens at the first step, where each of the m terms is tested once, so the
// family-wise false-alarm rate is <= alpha) AND its BIC drops by more than min_bic_drop, AND
// it passes the caller's own checks (plausibility, relevance, held-out validation). m is the
// size of the catalogue, fixed for the whole selection: not the number of tests run so far
// (re-testing a term after another was accepted tests the same hypothesis "this term is
// absent", and counting it again would make the level depend on the order of acceptance).
//
// Engine: at each step every candidate that is not accepted (and not skipped by the caller)
// is evaluated jointly with those accepted; among those that pass the rule and the caller's
// checks the one with the lowest delta BIC is accepted; stop when none passes. Then, if the
// caller supplies `removal`, backward elimination: while some non-forced accepted term fails
// the same tests given all the others, remove the one with the smallest likelihood ratio.
//
// Example:
//   SelectionRule rule{0.01, static_cast<int>(cands.size()), 10.0};
//   SelectionHooks h;
//   h.evaluate = [&](int c, const std::vector<int>& acc) { ... return Trial{ev}; };
//   std::vector<int> acc = selectTerms(static_cast<int>(cands.size()), rule, h);
#pragma once

#include "libwheelchair/stats/Statistics.h"

#include <functional>
#include <string>
#include <vector>

namespace wheelchair::stats {

struct SelectionRule {
  double alpha = 0.01;       ///< family-wise false-alarm level
  int family_size = 1;       ///< m: terms in the catalogue (the Bonferroni divisor)
  double min_bic_drop = 10;  ///< delta BIC must be < -min_bic_drop (10: strong evidence)
  /// The level each p-value is compared with: alpha / m.
  double level() const;
  /// Empty when the evidence passes, else why not ("not significant (p = ...)", "BIC drop too
  /// small").
  std::string reject(const Evidence& ev) const;
};

/// One candidate evaluated jointly with the accepted terms (or, for removal, the evidence of
/// an accepted term given all the others).
struct Trial {
  Evidence evidence;
  bool skip = false;   ///< not available at this step (conflict, forced term): no log line
  std::string reject;  ///< non-empty: cannot be accepted, this is why (logged)
};

struct SelectionHooks {
  /// Called once per forward step before the candidates are evaluated (optional).
  std::function<void(const std::vector<int>& accepted)> step;
  /// Candidate c added to `accepted` (required).
  std::function<Trial(int c, const std::vector<int>& accepted)> evaluate;
  /// Checks run only when c passes the rule, in order after it (optional): "" accepts.
  std::function<std::string(int c)> confirm;
  /// c has been accepted (optional).
  std::function<void(int c)> accepted;
  /// Backward elimination (optional): the term at position `pos` of `accepted`, given the
  /// others; skip = true for terms that must stay.
  std::function<Trial(int pos, const std::vector<int>& accepted)> removal;
  /// The term at position pos has been removed (optional).
  std::function<void(int pos)> removed;
};

/// Runs forward selection (then backward elimination) over candidates 0..n-1 starting from
/// `accepted` (forced terms, never removed: removal() should skip them). Returns the accepted
/// terms in order of acceptance. `log`, if given, receives the reasons of the last forward
/// step (candidate, why not) followed by the removals (candidate, "removed, redundant given
/// the other terms").
std::vector<int> selectTerms(int n, const SelectionRule& rule, const SelectionHooks& hooks,
                             std::vector<int> accepted = {},
                             std::vector<std::pair<int, std::string>>* log = nullptr);

}  // namespace wheelchair::stats
