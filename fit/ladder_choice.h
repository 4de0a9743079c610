// SPDX-License-Identifier: Apache-2.0
// The model ladder's choice (issue #8), shared by every capture kind: rungs ordered simplest
// first, each scored by its squared prediction errors on the same held-out measurements.
#pragma once

#include <vector>

namespace thinslab {

// Index of the simplest rung whose mean per-measurement excess over the best rung (smallest
// sum) is within `significance_sigmas` standard errors of the paired per-measurement
// differences: the noise of the held-out estimate itself, measurement noise included.
// `squared_errors[k]` is rung k's list (empty: rung not available); the non-empty lists must
// have the same length. -1 when no rung is available.
int SimplestRungWithinNoise(const std::vector<std::vector<double>>& squared_errors, double significance_sigmas);

}  // namespace thinslab
