// SPDX-License-Identifier: Apache-2.0
// Accuracy of a tau map against ground truth (simulated sessions).
#pragma once

#include <string>

#include "thinslab/core/image.h"
#include "thinslab/core/status.h"

namespace thinslab {

struct TauAccuracy {
  int64_t pixels = 0;            // Pixels with status ok and tau_true in [min_tau, max_tau].
  double rms_relative = 0;       // sqrt(mean((tau - tau_true)^2)) / sqrt(mean(tau_true^2)).
  double mean_relative_bias = 0; // mean(tau - tau_true) / mean(tau_true); negative = reads low.
  double max_abs_error = 0;
  // Coverage (channel "sigma_tau", refined map only; -1 without it): the fraction of those
  // pixels within 1 and 2 sigma_tau of the truth, and the share of the in-view pixels with
  // tau_true in range that are status ok.
  double within_1_sigma = -1, within_2_sigma = -1;
  double ok_fraction = 0;
};

struct TauComparison {
  TauAccuracy refined;  // Channel "tau".
  TauAccuracy plain;    // Channel "tau_eq7" (Gu Eq. 7).
  double min_tau = 0, max_tau = 0;
  std::string ToJson() const;
};

// Split-half consistency (issue #24): two fits of disjoint halves of the frames against each
// other, z = (tau_a - tau_b) / sqrt(noise_a^2 + noise_b^2) over pixels status ok in both, the
// noise parts of sigma_tau (TauMaps::sigma_tau_noise). rms_z near 1 and 68 % / 95 % within 1 / 2
// say the noise part holds; it cannot see errors both halves share (model, resolution, and
// the reference when both halves use the same frames).
struct SplitHalfConsistency {
  int64_t pixels = 0;
  double rms_z = 0, within_1 = 0, within_2 = 0;
  double rms_difference = 0;  // RMS of tau_a - tau_b.
  bool shared_reference = false;
  std::string ToJson() const;
};
SplitHalfConsistency CompareSplitHalves(const Image& tau_a, const Image& noise_a, const Image& tau_b,
                                        const Image& noise_b);

// `maps` holds channels tau, tau_eq7, status; `truth` channel "tau" on the same grid.
Status CompareTauWithTruth(const Image& maps, const Image& truth, double min_tau, double max_tau,
                           TauComparison* comparison);

}  // namespace thinslab
