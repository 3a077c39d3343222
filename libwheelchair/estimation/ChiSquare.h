// The chi-square functions of the estimator's gates and consistency bands live in
// libwheelchair/stats/Distributions.h (one definition for the estimator and the diagnosis);
// this header keeps their estimation:: names.
#pragma once

#include "libwheelchair/stats/Distributions.h"

namespace wheelchair::estimation {

using stats::chi2Cdf;
using stats::chi2MeanBand;
using stats::chi2Quantile;

}  // namespace wheelchair::estimation
