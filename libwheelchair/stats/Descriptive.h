// Order statistics of a sample, one definition for the whole library.
//
// median: the sample median of the FINITE values (NaN and +-inf are dropped): the middle value
// of an odd count, the mean of the two middle values of an even count (the unbiased choice for
// a symmetric distribution, and what numpy.median and evo report); NaN when no finite value
// is left. O(n) (nth_element).
// quantile: the order statistic x_(floor(q n)) of the finite values (0-based, clamped to the
// largest), q in [0, 1]; NaN when no finite value is left.
//
// Example:
//   stats::median({3, 1, 2, 10})        // 2.5
//   1.4826 * stats::median(abs_dev)     // MAD scale of a Gaussian sample
//   stats::quantile({1, 2, 3, 4}, 0.9)  // 4
#pragma once

#include <vector>

namespace wheelchair::stats {

double median(std::vector<double> v);
double quantile(std::vector<double> v, double q);

}  // namespace wheelchair::stats
