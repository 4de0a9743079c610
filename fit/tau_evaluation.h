// SPDX-License-Identifier: Apache-2.0
// Accuracy of a tau map against ground truth (simulated sessions).
#pragma once

#include <string>

#include "core/image.h"
#include "core/status.h"

namespace thinslab {

struct TauAccuracy {
  int64_t pixels = 0;            // Pixels with status ok and tau_true in [min_tau, max_tau].
  double rms_relative = 0;       // sqrt(mean((tau - tau_true)^2)) / sqrt(mean(tau_true^2)).
  double mean_relative_bias = 0; // mean(tau - tau_true) / mean(tau_true); negative = reads low.
  double max_abs_error = 0;
};

struct TauComparison {
  TauAccuracy refined;  // Channel "tau".
  TauAccuracy plain;    // Channel "tau_plain" (Gu Eq. 7).
  double min_tau = 0, max_tau = 0;
  std::string ToJson() const;
};

// `maps` holds channels tau, tau_plain, status; `truth` channel "tau" on the same grid.
Status CompareTauWithTruth(const Image& maps, const Image& truth, double min_tau, double max_tau,
                           TauComparison* comparison);

}  // namespace thinslab
