// SPDX-License-Identifier: Apache-2.0
// The model ladder's choice (issue #8), shared by every capture kind: rungs ordered simplest
// first, each scored by its squared prediction errors on the same held-out measurements.
#pragma once

#include <vector>

namespace thinslab {

// Index of the simplest rung whose error on the held-out measurements is within noise of the
// best rung's (the one with the smallest sum): its mean per-measurement excess over the best must
// not exceed the mean measurement variance of those measurements (`noise_variances`, same order;
// empty: 0) plus `significance_sigmas` standard errors of the paired per-measurement differences
// (the noise of the held-out estimate itself). The first allowance keeps a model whose
// systematic error is below the noise of one measurement however many measurements are pooled
// (a paired test alone tells ever smaller model errors apart as the pool grows, and would always
// end on the largest model); the second keeps one whose excess the pool cannot resolve.
// `squared_errors[k]` is rung k's list (empty: rung not available); the non-empty lists must
// have the same length. -1 when no rung is available.
int SimplestRungWithinNoise(const std::vector<std::vector<double>>& squared_errors, double significance_sigmas,
                            const std::vector<double>& noise_variances = {});

}  // namespace thinslab
